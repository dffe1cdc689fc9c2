"""Two robots drive at each other until their centres are 0.10 m apart (closer than a robot
diameter: a collision, as the Robotarium counts it) and stay there, 400 iterations. The safety
layer holds them 0.115 m apart on the testbed; the Robotarium's simulator counts each iteration
they sit 0.10 m apart: ./robotarium run must give that verdict, not a guess."""
import numpy as np

import rps.robotarium as robotarium

N = 2
initial_conditions = np.array([[-0.3, 0.3], [0.0, 0.0], [0.0, np.pi]])
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
for _ in range(400):
    x = r.get_poses()
    gap = x[0, 1] - x[0, 0] - 0.10   # how far each robot still is from standing 0.10 m from the other
    v = np.clip(2.0 * gap, 0.0, 0.1)
    r.set_velocities(np.arange(N), np.array([[v, v], [0.0, 0.0]]))
    r.step()
r.call_at_scripts_end()
