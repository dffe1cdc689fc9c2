"""A script that imports a module the Robotarium does not provide (rclpy), beside allowed ones."""
import numpy as np
import rclpy  # noqa: F401 - the point of the script

import rps.robotarium as robotarium

r = robotarium.Robotarium(number_of_robots=1, show_figure=False, sim_in_real_time=False)
r.get_poses()
r.set_velocities(np.arange(1), np.zeros((2, 1)))
r.step()
r.call_at_scripts_end()
