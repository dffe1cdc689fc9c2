"""A script that never calls r.call_at_scripts_end()."""
import numpy as np

import rps.robotarium as robotarium

r = robotarium.Robotarium(number_of_robots=1, show_figure=False, sim_in_real_time=False)
for _k in range(10):
    r.get_poses()
    r.set_velocities(np.arange(1), np.array([[0.05], [0.0]]))
    r.step()
