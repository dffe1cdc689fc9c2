"""A safe script behaves on the testbed as on the Robotarium (issue 36).

Every guide listing and every bundled example runs end to end through ./robotarium run (lockstep,
the always-on safety layer, numpy seeded) on one testbed, and the same script runs in this process
on the Robotarium's own simulator 0.0.0 (devtools.safe_scripts: its robotarium.py from
.venv-reference, the script's own rps utilities being ours on both sides, and the guide's
thresholding in its step: scripts beyond the wheel limits drive the commanded arc there too). Where
0.0.0 counts no collision and no robot outside, the safety layer must change no command array, the
run must take as many iterations, and every robot must stand where 0.0.0 puts it at every step
(within 1e-9 m; bit for bit in practice); neither report may mention a collision or a robot outside.

Listings with a fixed loop of thousands of steps run a shorter loop (--set), the same on both sides.
"""
import glob
import json
import os

import numpy as np
import pytest

from devtools.e2e import module_testbed, run, run_folder
from devtools.reference import reference_available
from devtools.rosutil import REPO

pytestmark = [pytest.mark.e2e, pytest.mark.skipif(not reference_available(),
                                                  reason="the Robotarium simulator 0.0.0 (.venv-reference) is missing: "
                                                         "./robotarium setup makes it")]

GUIDE = sorted(glob.glob(os.path.join(REPO, "examples", "guide", "*.py")))
OURS = sorted(glob.glob(os.path.join(REPO, "examples", "*.py")))
RUN_SEEDED = os.path.join(REPO, "devtools", "run_seeded.py")
SEED = 1
# Fixed loops of thousands of steps, shortened (the same on both sides); the rest run as printed.
SHORTER = {"3_3_1_leader_follower_formation_control.py": [("iterations", "1200")],
           "3_4_1_rectangle_formation_control.py": [("iterations", "1000")],
           "3_5_2_unreachable_goals_single_integrator.py": [("iterations", "1200")],
           "3_5_3_unreachable_goals_unicycle.py": [("iterations", "1200")],
           "3_6_1_leader_follower_data_saving.py": [("iterations", "1200")],
           "3_8_2_leader_follower_with_plotting.py": [("iterations", "1200")]}


@pytest.fixture(scope="module")
def testbed(tmp_path_factory):
    with module_testbed(tmp_path_factory) as bed:
        yield bed


def reference_trace(script, settings):
    from devtools import safe_scripts
    return safe_scripts.run_script(script, safe_scripts.reference_robotarium(guide_thresholding=True), SEED, settings)


@pytest.mark.parametrize("script", GUIDE + OURS, ids=lambda p: os.path.basename(p))
def test_a_safe_script_runs_step_for_step_as_on_the_robotarium(testbed, script):
    from robotarium_recording.bag import Bag
    env, bags = testbed
    settings = SHORTER.get(os.path.basename(script), [])
    sets = [arg for name, value in settings for arg in ("--set", "%s=%s" % (name, value))]
    completed = run(env, RUN_SEEDED, "--lockstep", "--no-video", "--", *sets, str(SEED), script)
    out = completed.stdout + completed.stderr
    assert completed.returncode == 0, out
    folder = run_folder(bags, out)
    with open(os.path.join(folder, "run.json")) as f:
        info = json.load(f)

    reference = reference_trace(script, settings)
    assert (reference.collisions, reference.boundary) == (0, 0), "0.0.0 itself counts errors: not a safe script"
    assert info["safety_interventions"] == 0, out
    assert "The safety layer changed" not in out and info.get("verdict") is None, out
    assert info["steps"] == reference.iterations, (info["steps"], reference.iterations)
    poses = Bag(folder).poses()
    assert list(poses.steps) == list(range(info["steps"] + 1))
    ours = np.stack([poses.x, poses.y], axis=1)                       # steps x 2 x N
    theirs = np.array(reference.poses)[:, :2]
    difference = float(np.hypot(*(ours - theirs).transpose(1, 0, 2)).max())
    assert difference < 1e-9, "robots stand up to %.3g m from where 0.0.0 puts them" % difference
    # the debug report as 0.0.0 counts (actuator-limit iterations too: the same steps, the same order)
    assert "Simulation had" not in out or "where the actuator limits were exceeded" in out
    if reference.actuator:
        assert "Simulation had %d iteration(s) where the actuator limits were exceeded" % reference.actuator in out, out
    else:
        assert "Acceptance of your experiment is likely!" in out, out
    with open(os.path.join(folder, "report.txt")) as f:
        report = f.read()
    for words in ("robots collided", "outside the boundaries", "safety layer"):
        assert words not in out and words not in report.split("##### RUN")[0], words
    assert os.path.exists(os.path.join(folder, "log.txt"))
    if script in OURS:   # each of our examples says when it reached its goal
        assert "goal reached" in out, out
