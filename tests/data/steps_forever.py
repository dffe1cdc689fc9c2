"""A script that never ends, saying where it is: real time (or lockstep with the argument
"lockstep"), three robots turning in circles, printing its run id, then "step k" after each step. Used by
tests/test_faults.py and bench/bench_faults.py to kill or interrupt a client mid-run."""
import sys

import numpy as np

import rps.robotarium as robotarium

r = robotarium.Robotarium(number_of_robots=3, show_figure=False, sim_in_real_time="lockstep" not in sys.argv[1:],
                          initial_conditions=np.array([[-0.8, 0.0, 0.8], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
print("run %s" % r._link.run_id, flush=True)   # which experiment is this script's (for the tests)
step = 0
while True:
    r.get_poses()
    r.set_velocities(np.arange(3), np.array([[0.05, 0.05, 0.05], [0.5, -0.5, 0.5]]))
    r.step()
    step += 1
    print("step %d" % step, flush=True)
