"""End to end: the Robotarium simulator 2.1.0's own examples (examples/rps2/, copied unchanged) run
through ./robotarium run against one testbed, recognised as 2.x scripts, with the drive-on phase.

Three of them run in CI (lockstep, numpy seeded as devtools/run_seeded.py does; scripts with an
`iterations = N` line run for a few steps); all of them when ROBOTARIUM_SLOW_TESTS=1 is set
(README: "The Robotarium simulator 2.x API"): each drives its robots on first, which takes a few
hundred steps, and CI's time is short.
"""
import glob
import os

import pytest

from devtools.rosutil import REPO
from tests.test_examples import check_bag, run, run_folder, testbed  # noqa: F401 (testbed: the module's fixture)

EXAMPLES = os.path.join(REPO, "examples", "rps2")
# What CI runs (about 90 s of its time): the examples that use the most of 2.x between them.
# dead_reckoning: the drive-on phase, encoders and IMU; distance_sensor_avoidance: obstacles,
# distance sensors and their endpoints, skip_initialization, 2.x's _solve_qp, r._axes_handle;
# leader_follower_with_plotting: the 2.x figure, 2.x's graph and barrier utilities.
IN_CI = ["state_estimation/dead_reckoning/dead_reckoning.py", "sensors/distance_sensor_avoidance.py",
         "plotting/leader_follower_with_plotting.py"]
ALL = sorted(os.path.relpath(p, EXAMPLES) for p in glob.glob(os.path.join(EXAMPLES, "**", "*.py"), recursive=True)
             if not p.endswith("uni_ekf.py"))   # uni_ekf.py is a module ekf_experiment.py imports
SHORT_ITERATIONS = 120
# Scripts whose loop has no iteration count and no end of their own within a test's time.
SCRIPT_ARGS = {"state_estimation/extended_kalman_filter/ekf_experiment.py": ["--cycles", "1"]}


def run_example(env, name):
    script = os.path.join(EXAMPLES, name)
    with open(script) as f:
        shorten = ["--iterations", str(SHORT_ITERATIONS)] if "\niterations = " in f.read() else []
    completed = run(env, os.path.join(REPO, "devtools", "run_seeded.py"), "--lockstep", "--no-video", "--",
                    *shorten, "1", script, *SCRIPT_ARGS.get(name, []), timeout=300)
    out = completed.stdout + completed.stderr
    assert completed.returncode == 0, out
    assert "Robotarium simulator 2.x API" in out, out          # recognised as a 2.x script
    assert "Your simulation took approximately" in out, out    # debug()'s report, 2.x's text
    assert "Errors detected" not in out, out
    return out


@pytest.mark.parametrize("name", IN_CI)
def test_2x_examples_run_unchanged(testbed, name):  # noqa: F811 (the fixture)
    env, bags = testbed
    out = run_example(env, name)
    folder = run_folder(bags, out)
    counts = check_bag(folder)   # an independent reader (rosbags) opens it
    assert counts["/robotarium/sensors"] == counts["/robotarium/poses"], counts   # one reading per step
    assert counts["/robotarium/experiment"] == 1, counts
    if "skip_initialization=True" not in open(os.path.join(EXAMPLES, name)).read():
        assert "Initializing" in out and "At initial conditions... Starting Experiment" in out, out


@pytest.mark.skipif(not os.environ.get("ROBOTARIUM_SLOW_TESTS"), reason="the other 2.x examples: set "
                    "ROBOTARIUM_SLOW_TESTS=1 (CI runs one of each kind)")
@pytest.mark.parametrize("name", sorted(set(ALL) - set(IN_CI)))
def test_every_other_2x_example_runs_unchanged(testbed, name):  # noqa: F811 (the fixture)
    env, bags = testbed
    run_example(env, name)
