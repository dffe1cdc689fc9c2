"""Four robots drive small circles where they stand (a simulated fleet of four, 0.4 m apart), for
the fault tests of tests/test_own_robots.py: long enough to be stopped mid-run."""
import numpy as np

import rps.robotarium as robotarium

N = 4
iterations = 900
initial_conditions = np.array([[-0.6, -0.2, 0.2, 0.6], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)   # a hardware arena runs it in real time all the same
for _ in range(iterations):
    r.get_poses()
    r.set_velocities(np.arange(N), np.array([[0.08] * N, [0.8] * N]))
    r.step()
r.call_at_scripts_end()
