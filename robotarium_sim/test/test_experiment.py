"""robotarium_sim.experiment in process: what a start may ask for, run ids, and one experiment's
bookkeeping (the simulator node's tests check that it is wired to the topics and services)."""
import types

import numpy as np
import pytest

from robotarium_core import model, rps2
from robotarium_core.config import DEFAULT
from robotarium_sim.experiment import Experiment, RunIds, build_testbed
from robotarium_sim.hardware import HardwareTestbed


def request(n=3, poses=None, name="test", seed=1, api="", hardware=False):
    x, y, theta = ([], [], []) if poses is None else (list(map(float, row)) for row in poses)
    return types.SimpleNamespace(name=name, number_of_robots=n, x=x, y=y, theta=theta, seed=seed, api=api,
                                 hardware=hardware, obstacles=[], drive_on_x=[], drive_on_y=[], drive_on_theta=[],
                                 use_distance_sensors=False, sensor_seed=0)


@pytest.mark.parametrize("kwargs, words", [
    (dict(n=0), "number_of_robots"),
    (dict(n=DEFAULT.max_robots + 1), "number_of_robots"),
    (dict(n=2, poses=[[0.0, 0.05], [0.0, 0.0], [0.0, 0.0]]), "collision"),
    (dict(n=2, poses=[[0.0, 2.0], [0.0, 0.0], [0.0, 0.0]]), "outside the arena"),
    (dict(n=3, poses=[[0.0, 0.5], [0.0, 0.0], [0.0, 0.0]]), "length 3"),
    (dict(name="two words"), "letters, digits"),
    (dict(name="x" * 65), "letters, digits"),
    (dict(api="3"), "api must be"),
    (dict(api=rps2.API, hardware=True), "hardware-like mode models the guide's API only"),
])
def test_a_start_that_cannot_be_run_is_refused_saying_why(kwargs, words):
    with pytest.raises(model.RobotariumError, match=words):
        build_testbed(request(**kwargs), DEFAULT)


def test_a_start_gets_the_model_it_asks_for_with_seeded_random_poses():
    name, first = build_testbed(request(n=20, seed=42, name=""), DEFAULT)
    _, second = build_testbed(request(n=20, seed=42), DEFAULT)
    assert name == "experiment" and type(first) is model.Testbed
    assert first.poses.shape == (3, 20) and np.array_equal(first.poses, second.poses)
    assert np.all(np.abs(first.poses[0]) < 1.6) and np.all(np.abs(first.poses[1]) < 1.0)
    _, other = build_testbed(request(n=20, seed=43), DEFAULT)
    assert not np.array_equal(first.poses, other.poses)
    line = [[-0.5, 0.0, 0.5], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    assert np.array_equal(build_testbed(request(poses=line), DEFAULT)[1].poses, line)
    assert isinstance(build_testbed(request(poses=line, hardware=True), DEFAULT)[1], HardwareTestbed)
    assert isinstance(build_testbed(request(poses=line, api=rps2.API), DEFAULT)[1], rps2.Testbed2)


def test_runs_of_one_name_in_one_second_get_their_own_ids():
    ids = RunIds()
    now = 1_790_000_000.0
    got = [ids.new("quick", now) for _ in range(3)] + [ids.new("quick", now + 1), ids.new("other", now)]
    assert len(set(got)) == 5
    assert got[1] == got[0] + "_2" and got[2] == got[0] + "_3" and got[3].startswith("quick_")


def test_each_experiment_starts_afresh_with_its_own_secrets_and_counts():
    first = Experiment.started("a_1", "a", real_time=False, holder="ann@host pid 1 a.py", now=5.0)
    secrets = (first.token, first.safety_key, first.poses_key)
    assert len(set(secrets)) == 3 and all(len(s) == 32 for s in secrets)
    assert not first.real_time and first.last_tick == 5.0 and first.started_at
    assert first.gate.admit(1, 0, stop=False) is None   # lockstep: the array for the next step
    assert first.count_drop("stale") and not first.count_drop("stale") and first.dropped["stale"] == 2
    first.safe_arrays_heard = 3
    first.count_safety_report(True, 0.2)
    first.count_safety_report(False, 0.0, stale_stop=True)
    first.count_safety_report(False, 0.0, of_an_array=False, dropped="counts")   # drop counts only
    assert (first.reports_heard, first.reports_missing, first.safety_interventions, first.stale_pose_stops) == (2, 1, 1, 1)
    assert first.tally.largest_change == 0.2 and first.dropped_requested == "counts"
    second = Experiment.started("a_2", "a", real_time=True)
    assert (second.token, second.safety_key, second.poses_key) != secrets
    assert second.dropped["stale"] == 0 and second.safety_interventions == 0 and second.tally.largest_change == 0
    idle = Experiment()   # before the first run: nothing to say
    assert idle.run_id == "" and idle.real_time and idle.outcome == 0 and idle.dropped_requested is None
