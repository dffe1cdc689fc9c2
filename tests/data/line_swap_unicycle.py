"""Four robots in a row on the x axis swap ends with the guide's unicycle position controller and
no barrier certificate, 300 iterations: they drive through each other, and the controller asks
for more than the wheels can do (where the stack keeps the commanded arc, 0.0.0 clips each of v
and omega)."""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.controllers import create_clf_unicycle_position_controller

N = 4
initial_conditions = np.array([[-0.9, -0.3, 0.3, 0.9], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, np.pi, np.pi]])
goals = initial_conditions[:2, ::-1].copy()
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
controller = create_clf_unicycle_position_controller()
for _ in range(300):
    x = r.get_poses()
    r.set_velocities(np.arange(N), controller(x, goals))
    r.step()
r.call_at_scripts_end()
