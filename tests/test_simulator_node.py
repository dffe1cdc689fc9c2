"""The simulator node, started for real in a subprocess on its own DDS domain."""
import os
import subprocess
import sys

import numpy as np
import pytest
from geometry_msgs.msg import Twist

from robotarium_msgs.msg import RobotPoses, TestbedStatus, TwistArray
from robotarium_msgs.srv import EndExperiment, StartExperiment
from devtools.rosutil import REPO, NodeProcess, RosProbe, node_env, unique_domain_id
from robotarium_core.topics import TESTBED_QOS

NS = "/robotarium"


@pytest.fixture
def testbed(tmp_path):
    domain = unique_domain_id()
    sim = NodeProcess("robotarium_sim.simulator_node", domain, log_path=tmp_path / "simulator.log")
    probe = RosProbe(domain)
    try:
        yield sim, probe
    finally:
        probe.close()
        sim.close()


def start(probe, n=3, real_time=False, poses=None, name="test", seed=1):
    request = StartExperiment.Request(name=name, number_of_robots=n, real_time=real_time, seed=seed)
    if poses is not None:
        request.x, request.y, request.theta = (list(map(float, row)) for row in poses)
    return probe.call(StartExperiment, NS + "/start_experiment", request)


def command(ids, v, w, step=0):
    msg = TwistArray(step=step)
    msg.header.frame_id = "arena"
    msg.ids = [int(i) for i in ids]
    for vi, wi in zip(v, w):
        t = Twist()
        t.linear.x, t.angular.z = float(vi), float(wi)
        msg.twists.append(t)
    return msg


def as_array(msg):
    return np.array([msg.x, msg.y, msg.theta])


LINE = np.array([[-0.5, 0.0, 0.5], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])


def test_start_and_end_round_trip(testbed):
    _, probe = testbed
    response = start(probe, n=3, poses=LINE, name="roundtrip")
    assert response.success, response.message
    assert response.run_id.startswith("roundtrip_")
    assert np.array_equal(np.array([response.x, response.y, response.theta]), LINE)

    second = start(probe, n=2, name="other")
    assert not second.success and "still running" in second.message

    end = probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request())
    assert end.success and end.run_id == response.run_id and end.steps == 0
    assert "No errors in your simulation!" in end.report

    again = probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request())
    assert not again.success and "no experiment" in again.message
    assert start(probe, n=2, name="after").success  # a new one may start once the old one ended


@pytest.mark.parametrize("n, poses, words", [
    (0, None, "number_of_robots"),
    (51, None, "number_of_robots"),
    (2, np.array([[0.0, 0.05], [0.0, 0.0], [0.0, 0.0]]), "collision"),
    (2, np.array([[0.0, 2.0], [0.0, 0.0], [0.0, 0.0]]), "outside the arena"),
    (3, np.array([[0.0, 0.5], [0.0, 0.0], [0.0, 0.0]]), "length 3"),
])
def test_invalid_start_is_refused_with_reason(testbed, n, poses, words):
    _, probe = testbed
    response = start(probe, n=n, poses=poses)
    assert not response.success
    assert words in response.message


def test_random_initial_conditions_are_valid_and_seeded(testbed):
    _, probe = testbed
    first = start(probe, n=20, seed=42)
    probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request())
    second = start(probe, n=20, seed=42)
    a = np.array([first.x, first.y, first.theta])
    assert a.shape == (3, 20)
    assert np.array_equal(a, np.array([second.x, second.y, second.theta]))
    assert np.all(np.abs(a[0]) < 1.6) and np.all(np.abs(a[1]) < 1.0)


def lockstep(probe, publisher, msg, poses_topic, timeout=10.0):
    """Publish lockstep command `msg` (msg.step = k), wait for the poses of step k, return them."""
    k = msg.step
    publisher.publish(msg)
    if not probe.spin_until(lambda: poses_topic and poses_topic[-1].step >= k, timeout):
        raise AssertionError("no poses for step %d within %.0f s" % (k, timeout))
    assert poses_topic[-1].step == k, "step %d produced poses of step %d" % (k, poses_topic[-1].step)
    return poses_topic[-1]


def run_lockstep(probe, commands, poses_topic):
    """Send each command array, wait for the step it produces; return the poses seen."""
    publisher = probe.node.create_publisher(TwistArray, NS + "/cmd_safe", TESTBED_QOS)
    assert probe.spin_until(lambda: publisher.get_subscription_count() > 0, 10)
    trace = []
    for k, (v, w) in enumerate(commands, start=1):
        trace.append(as_array(lockstep(probe, publisher, command(range(len(v)), v, w, step=k), poses_topic)))
    probe.node.destroy_publisher(publisher)
    return np.array(trace)


def test_lockstep_is_deterministic(testbed):
    _, probe = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    probe.wait_for_publishers()
    rng = np.random.default_rng(0)
    commands = [(rng.uniform(-0.1, 0.1, 3), rng.uniform(-1, 1, 3)) for _ in range(60)]
    runs = []
    for _ in range(2):
        assert start(probe, n=3, poses=LINE).success
        runs.append(run_lockstep(probe, commands, poses))
        end = probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request())
        assert end.steps == 60
        poses.clear()
    assert np.array_equal(runs[0], runs[1])
    # and it is the model's trajectory: the robots did move
    assert np.abs(runs[0][-1] - LINE).max() > 0.05


def test_bad_commands_are_dropped_counted_and_never_move_robots(testbed):
    _, probe = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    status = probe.collect(TestbedStatus, NS + "/status")
    probe.wait_for_publishers()
    assert start(probe, n=3, poses=LINE).success
    publisher = probe.node.create_publisher(TwistArray, NS + "/cmd_safe", TESTBED_QOS)
    assert probe.spin_until(lambda: publisher.get_subscription_count() > 0, 10)
    bad = [
        command([0, 1, 2], [0.1, float("nan"), 0.1], [0, 0, 0]),     # nonfinite
        command([0, 1, 2], [0.1, 0.1, 0.1], [0, float("inf"), 0]),   # nonfinite
        command([0, 1, 2], [0.1, 0.1], [0, 0]),                      # length mismatch
        command([0, 0, 1], [0.1, 0.1, 0.1], [0, 0, 0]),              # duplicate id
        command([0, 1, 7], [0.1, 0.1, 0.1], [0, 0, 0]),              # unknown id
    ]
    for msg in bad:
        publisher.publish(msg)

    def counted():
        return status and (status[-1].dropped_nonfinite, status[-1].dropped_length_mismatch,
                           status[-1].dropped_unknown_id) == (2, 2, 1)
    assert probe.spin_until(counted, 10), status[-1] if status else "no status"
    assert status[-1].step == 0 and status[-1].commands_accepted == 0
    assert all(p.step == 0 for p in poses) and np.array_equal(as_array(poses[-1]), LINE)

    lockstep(probe, publisher, command([0, 1, 2], [0.1, 0.1, 0.1], [0, 0, 0], step=1), poses)  # good ones work
    assert as_array(poses[-1])[0, 0] == pytest.approx(-0.5 + 0.033 * 0.1)


def test_real_time_tick_rate_is_30_hz(testbed):
    _, probe = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    probe.wait_for_publishers()
    assert start(probe, n=5, real_time=True).success
    probe.spin_for(3.5)
    stamps = np.array([p.header.stamp.sec + p.header.stamp.nanosec * 1e-9 for p in poses if p.step > 0])
    steps = np.array([p.step for p in poses if p.step > 0])
    assert np.all(np.diff(steps) == 1), "lost or reordered poses"
    assert stamps[-1] - stamps[0] > 2.9
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    assert rate == pytest.approx(30.0, rel=0.02)


def test_command_held_for_half_a_second_then_robot_stops(testbed):
    _, probe = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    status = probe.collect(TestbedStatus, NS + "/status")
    probe.wait_for_publishers()
    assert start(probe, n=1, real_time=True, poses=np.array([[0.0], [0.0], [0.0]])).success
    publisher = probe.node.create_publisher(TwistArray, NS + "/cmd_safe", TESTBED_QOS)
    assert probe.spin_until(lambda: publisher.get_subscription_count() > 0, 10)
    publisher.publish(command([0], [0.1], [0.0]))
    probe.spin_for(1.5)
    x = np.array([p.x[0] for p in poses])
    moving_steps = np.count_nonzero(np.diff(x) > 0)
    # 0.5 s at 30 Hz is 15 ticks (one either way for where the command lands between ticks)
    assert 14 <= moving_steps <= 16
    assert x[-1] == pytest.approx(moving_steps * 0.033 * 0.1)
    assert x[-1] == x[-20]  # and it stays stopped
    assert status[-1].command_timeouts == 1


def test_safety_interventions_are_counted(testbed):
    from robotarium_msgs.msg import SafetyReport
    _, probe = testbed
    status = probe.collect(TestbedStatus, NS + "/status")
    probe.wait_for_publishers()
    assert start(probe, n=2, poses=LINE[:, :2]).success
    publisher = probe.node.create_publisher(SafetyReport, NS + "/safety_report", TESTBED_QOS)
    assert probe.spin_until(lambda: publisher.get_subscription_count() > 0, 10)
    for state in (SafetyReport.STATUS_PASSTHROUGH, SafetyReport.STATUS_SOLVED, SafetyReport.STATUS_STOP_NO_POSES,
                  SafetyReport.STATUS_PASSTHROUGH):
        publisher.publish(SafetyReport(status=state))
    assert probe.spin_until(lambda: status and status[-1].safety_interventions == 2, 5)


def test_invalid_parameter_stops_the_node_with_a_clear_error(tmp_path):
    completed = subprocess.run(
        [sys.executable, "-m", "robotarium_sim.simulator_node", "--ros-args", "-p", "rate:=-5.0"],
        env=node_env(unique_domain_id()), capture_output=True, text=True, timeout=30, cwd=REPO)
    assert completed.returncode == 2
    assert "rate" in completed.stderr and "must be" in completed.stderr


def test_installed_for_ros2_run():
    """`ros2 run robotarium_sim simulator` finds lib/robotarium_sim/simulator in the install tree."""
    script = os.path.join(REPO, "install", "lib", "robotarium_sim", "simulator")
    assert os.access(script, os.X_OK)
    config = os.path.join(REPO, "install", "share", "robotarium_core", "config", "testbed.yaml")
    assert os.path.exists(config)
