"""A script that never ends (as a goal loop that never converges): real time, two robots turning
in circles. Prints RUNNING after five steps. Used by tests/test_testbed_lifetime.py and
bench/bench_testbed_lifetime.py to stop `./robotarium run` from outside."""
import numpy as np

import rps.robotarium as robotarium

r = robotarium.Robotarium(number_of_robots=2, show_figure=False, sim_in_real_time=True)
steps = 0
while True:
    r.get_poses()
    r.set_velocities(np.arange(2), np.array([[0.05, 0.05], [0.5, -0.5]]))
    r.step()
    steps += 1
    if steps == 5:
        print("RUNNING", flush=True)
