"""Run a Robotarium script with numpy's global generator seeded: `run_seeded.py SEED SCRIPT [ARGS]`.

The guide's scripts draw random goals without a seed; seeding from outside keeps them unchanged
while making a test run reproducible (lockstep then gives the same run every time).
"""
import os
import runpy
import sys

import numpy as np

try:
    from robotarium_client import session
except ImportError:   # the Robotarium's own simulator (bench_guide_scripts runs it with this too)
    session = None

seed, script = int(sys.argv[1]), os.path.abspath(sys.argv[2])
sys.argv = [script] + sys.argv[3:]
if session is not None:
    session.options.experiment_name = session.experiment_name_of(script)
sys.path.insert(0, os.path.dirname(script))
np.random.seed(seed)
runpy.run_path(script, run_name="__main__")
