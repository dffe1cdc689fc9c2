"""Run a Robotarium script with numpy's global generator seeded:
`run_seeded.py [--iterations K] SEED SCRIPT [ARGS]`.

The guide's scripts draw random goals without a seed; seeding from outside keeps them unchanged
while making a test run reproducible (lockstep then gives the same run every time).
--iterations K runs the script with its top-level `iterations = N` line read as `iterations = K`
(the rest of the script as it is): tests run long examples for a few steps.
"""
import os
import re
import runpy
import sys
import types

import numpy as np

try:
    from robotarium_client import session
except ImportError:   # the Robotarium's own simulator (bench_guide_scripts runs it with this too)
    session = None

args = sys.argv[1:]
iterations = None
if args[:1] == ["--iterations"]:
    iterations, args = int(args[1]), args[2:]
seed, script = int(args[0]), os.path.abspath(args[1])
sys.argv = [script] + args[2:]
if session is not None:
    session.options.experiment_name = session.experiment_name_of(script)
sys.path.insert(0, os.path.dirname(script))
np.random.seed(seed)
if iterations is None:
    runpy.run_path(script, run_name="__main__")
else:
    with open(script) as f:
        source, count = re.subn(r"(?m)^iterations\s*=\s*\d+", "iterations = %d" % iterations, f.read())
    if count != 1:
        sys.exit("%s has no single top-level 'iterations = N' line to shorten" % script)
    main = types.ModuleType("__main__")
    main.__file__ = script
    saved, sys.modules["__main__"] = sys.modules["__main__"], main   # as runpy does: the script is __main__
    try:
        exec(compile(source, script, "exec"), main.__dict__)
    finally:
        sys.modules["__main__"] = saved
