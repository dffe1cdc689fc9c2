"""A feedback script: robot 0 chases robot 1 (a unicycle position controller on its pose) while
robot 1 drives slowly away and stops; robot 0 is told to stop only 5 cm from robot 1's centre.
The safety layer holds robot 0 back from the first approach on, so every later command of the
script (computed from poses the safety layer already changed) differs from what the Robotarium's
simulator sees: a replay of the commands could not tell how often the robots collide there; the
script judged as the Robotarium does can."""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.controllers import create_clf_unicycle_position_controller

N = 2
initial_conditions = np.array([[-0.8, 0.0], [0.1, 0.0], [0.5, 0.0]])
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
chase = create_clf_unicycle_position_controller(linear_velocity_gain=0.8, angular_velocity_gain=3)
for k in range(360):
    x = r.get_poses()
    dxu = np.zeros((2, N))
    target = x[:2, [1]]
    if np.linalg.norm(target - x[:2, [0]]) > 0.05:
        dxu[:, [0]] = chase(x[:, [0]], target)
    dxu[0, 1] = 0.05 if k < 120 else 0.0   # robot 1 drives away slowly, then stops
    r.set_velocities(np.arange(N), dxu)
    r.step()
r.call_at_scripts_end()
