"""Two robots drive straight east at full speed and leave the arena after about 60 of 300
iterations: the Robotarium counts every robot outside the boundaries each iteration."""
import numpy as np

import rps.robotarium as robotarium

N = 2
initial_conditions = np.array([[1.2, 1.2], [-0.3, 0.3], [0.0, 0.0]])
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
for _ in range(300):
    r.get_poses()
    r.set_velocities(np.arange(N), np.array([[0.2, 0.2], [0.0, 0.0]]))
    r.step()
r.call_at_scripts_end()
