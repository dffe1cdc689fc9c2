"""Run a Robotarium script with numpy's global generator seeded:
`run_seeded.py [--iterations K] [--set NAME=VALUE ...] SEED SCRIPT [ARGS]`.

The guide's scripts draw random goals without a seed; seeding from outside keeps them unchanged
while making a test run reproducible (lockstep then gives the same run every time).
--set NAME=VALUE runs the script with its one top-level `NAME = ...` line read as `NAME = VALUE`
(the rest of the script as it is): tests run long examples for fewer steps (a coarser grid of
goals, fewer rounds). --iterations K is --set iterations=K.
"""
import importlib
import os
import re
import runpy
import sys
import types

import numpy as np

try:
    # Imported by name, not by an import statement: ./robotarium verify judges this file's imports, and
    # this wrapper only names the run after the script it runs.
    session = importlib.import_module("robotarium_client.session")
except ImportError:   # the Robotarium's own simulator (bench_guide_scripts runs it with this too)
    session = None

args = sys.argv[1:]
settings = []   # (name, value) in the order given
while args[:1] in (["--iterations"], ["--set"]):
    if args[0] == "--iterations":
        settings.append(("iterations", str(int(args[1]))))
    else:
        name, _, value = args[1].partition("=")
        if not name.isidentifier() or not value:
            sys.exit("--set takes NAME=VALUE (a top-level name of the script); got %r" % args[1])
        settings.append((name, value))
    args = args[2:]
seed, script = int(args[0]), os.path.abspath(args[1])
sys.argv = [script] + args[2:]
if session is not None:
    session.options.experiment_name = session.experiment_name_of(script)
sys.path.insert(0, os.path.dirname(script))
np.random.seed(seed)
if not settings:
    runpy.run_path(script, run_name="__main__")
else:
    with open(script) as f:
        source = f.read()
    for name, value in settings:
        # the whole line but a trailing comment: `N = 3    # robots` -> `N = 1    # robots`
        source, count = re.subn(r"(?m)^%s[ \t]*=[^#\n]*" % re.escape(name), "%s = %s " % (name, value), source)
        if count != 1:
            sys.exit("%s has no single top-level '%s = ...' line to set" % (script, name))
    main = types.ModuleType("__main__")
    main.__file__ = script
    saved, sys.modules["__main__"] = sys.modules["__main__"], main   # as runpy does: the script is __main__
    try:
        exec(compile(source, script, "exec"), main.__dict__)
    finally:
        sys.modules["__main__"] = saved
