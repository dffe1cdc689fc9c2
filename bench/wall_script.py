"""The script of the wall-to-prompt benchmark (bench_wall_to_prompt.py, issue 26): 3 robots,
300 lockstep steps, no figure, no barrier certificate; each robot drives a circle. It runs
unchanged on the Robotarium simulator and through this stack, and prints one line,
`TIMES constructor loop` (seconds, measured inside the script).
"""
import time

import numpy as np

import rps.robotarium as robotarium

N = 3
STEPS = 300

started = time.perf_counter()
initial_conditions = np.array([[-0.8, 0.0, 0.8], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
constructed = time.perf_counter()
velocities = np.array([[0.1] * N, [0.5] * N])
for _ in range(STEPS):
    x = r.get_poses()
    r.set_velocities(np.arange(N), velocities)
    r.step()
looped = time.perf_counter()
print("TIMES %.3f %.3f" % (constructed - started, looped - constructed))
r.call_at_scripts_end()
