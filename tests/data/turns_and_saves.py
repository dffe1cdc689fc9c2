"""Robots turning on the spot for STEPS steps (argv[1], default 30; argv[2] robots, default 2, at most
10), 0.6 m apart on a grid, then call_at_scripts_end(); first writes the data files named in argv[3:]
as NAME:KILOBYTES in the working folder. Nothing comes near anything, so the safety layer never steps
in: a completed run whose report says "Acceptance likely". Used by tests/test_testbed_faults.py
(a full disk, capped data files)."""
import os
import sys

import numpy as np

import rps.robotarium as robotarium

steps = int(sys.argv[1]) if len(sys.argv) > 1 else 30
n = int(sys.argv[2]) if len(sys.argv) > 2 else 2
for spec in sys.argv[3:]:
    name, kilobytes = spec.split(":")
    with open(name, "wb") as f:
        f.write(os.urandom(int(kilobytes) * 1000))

grid = np.array([[-1.2 + 0.6 * (i % 5), -0.3 + 0.6 * (i // 5), 0.0] for i in range(n)]).T
r = robotarium.Robotarium(number_of_robots=n, show_figure=False, sim_in_real_time=False, initial_conditions=grid)
for _ in range(steps):
    r.get_poses()
    r.set_velocities(np.arange(n), np.vstack((np.zeros(n), np.full(n, 0.5))))
    r.step()
r.call_at_scripts_end()
