"""Four robots drive head-on through the centre of the arena with no barrier certificate (the
guide's single-integrator position controller, mapped to unicycle commands), 300 iterations.
The Robotarium's simulator (robotarium-python-simulator 0.0.0) counts 168 collision iterations:
./robotarium verify must reject it, and ./robotarium run must not call it likely to be accepted."""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.controllers import create_si_position_controller
from rps.utilities.transformations import create_si_to_uni_dynamics

N = 4
initial_conditions = np.array([[-0.6, 0.6, 0.0, 0.0], [0.0, 0.0, -0.6, 0.6], [0.0, np.pi, np.pi / 2, -np.pi / 2]])
goals = -initial_conditions[:2]   # each robot to the opposite side, all through the centre
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
si_to_uni = create_si_to_uni_dynamics()
si_controller = create_si_position_controller()
for _ in range(300):
    x = r.get_poses()
    r.set_velocities(np.arange(N), si_to_uni(si_controller(x[:2], goals), x))
    r.step()
r.call_at_scripts_end()
