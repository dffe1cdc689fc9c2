"""Two robots drive apart to their goals, 150 iterations (5 s): a clean script, accepted unless the
declared robot count or duration says otherwise."""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.controllers import create_clf_unicycle_position_controller

N = 2
initial_conditions = np.array([[-0.2, 0.2], [0.0, 0.0], [np.pi, 0.0]])
goals = np.array([[-0.6, 0.6], [0.0, 0.0]])
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
controller = create_clf_unicycle_position_controller()
for _ in range(150):
    x = r.get_poses()
    r.set_velocities(np.arange(N), controller(x, goals))
    r.step()
r.call_at_scripts_end()
