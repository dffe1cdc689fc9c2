"""One robot drives east out of the arena and back in: its centre is outside the boundary for
EXIT_STEPS iterations (the Robotarium allows 100), 300 iterations in all. The safety layer keeps it
inside on the testbed; the verdict counts the iterations the script's own commands spend outside."""
import numpy as np

import rps.robotarium as robotarium

EXIT_STEPS = 60   # iterations outside the arena

N = 1
initial_conditions = np.array([[1.3], [0.0], [0.0]])
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
# 0.1 m/s: 3.3 mm a step; 1.3 -> 1.6 takes 91 steps. Out for EXIT_STEPS / 2 steps, back as many.
out_steps = 91 + EXIT_STEPS // 2
for k in range(300):
    r.get_poses()
    v = 0.1 if k < out_steps else (-0.1 if k < 2 * out_steps else 0.0)
    r.set_velocities(np.arange(N), np.array([[v], [0.0]]))
    r.step()
r.call_at_scripts_end()
