"""The safety node between client and simulator, all real nodes on a private DDS domain."""
import time

import numpy as np
import pytest
from test_simulator_node import as_array, command, lockstep

from devtools.rosutil import NodeProcess, RosProbe, unique_domain_id
from robotarium_core import model
from robotarium_core.dds_settings import init_context
from robotarium_core.topics import TESTBED_QOS, readers_matched
from robotarium_msgs.msg import RobotPoses, SafetyReport, TestbedStatus, TwistArray
from robotarium_msgs.srv import ArmSafety, EndExperiment, StartExperiment

pytestmark = pytest.mark.node   # real testbed nodes in subprocesses

NS = "/robotarium"


@pytest.fixture
def stack(tmp_path):
    domain = unique_domain_id()
    nodes = {
        "sim": NodeProcess("robotarium_sim.simulator_node", domain, log_path=tmp_path / "sim.log"),
        "safety": NodeProcess("robotarium_safety.safety_node", domain, log_path=tmp_path / "safety.log"),
    }
    probe = RosProbe(domain)
    try:
        yield nodes, probe
    finally:
        probe.close()
        for node in nodes.values():
            node.close()


@pytest.fixture
def lone_safety(tmp_path):
    """A safety node alone on a domain of its own, the probe playing the simulator: (node, probe, the cmd_safe
    arrays, the safety reports) it receives."""
    domain = unique_domain_id()
    safety = NodeProcess("robotarium_safety.safety_node", domain, log_path=tmp_path / "safety.log")
    probe = RosProbe(domain)
    try:
        yield safety, probe, probe.collect(TwistArray, NS + "/cmd_safe"), probe.collect(SafetyReport, NS + "/safety_report")
    finally:
        probe.close()
        safety.close()


def start(probe, poses, real_time=False):
    request = StartExperiment.Request(name="safety", number_of_robots=poses.shape[1], real_time=real_time)
    request.x, request.y, request.theta = (list(map(float, row)) for row in poses)
    response = probe.start_experiment(request, NS)
    assert response.success, response.message
    return response


def with_token(msg, started):
    """A command array as the experiment's client sends it: with its token."""
    msg.token = started.token
    return msg


def connected(probe, publisher, count=1):
    assert probe.spin_until(lambda: publisher.get_subscription_count() >= count, 15), "nobody listens"


HEAD_ON = np.array([[-0.4, 0.4], [0.0, 0.0], [0.0, np.pi]])


def test_head_on_command_comes_out_changed_and_safe(stack):
    _, probe = stack
    poses = probe.collect(RobotPoses, NS + "/poses")
    reports = probe.collect(SafetyReport, NS + "/safety_report")
    safe = probe.collect(TwistArray, NS + "/cmd_safe")
    probe.wait_for_publishers()
    started = start(probe, HEAD_ON)
    requests = probe.node.create_publisher(TwistArray, NS + "/cmd_requested", TESTBED_QOS)
    connected(probe, requests)
    assert probe.spin_until(lambda: poses, 10)
    closest = np.inf
    for k in range(1, 151):  # both drive straight at each other at 0.15 m/s: they would meet at step ~81
        msg = with_token(command([0, 1], [0.15, 0.15], [0.0, 0.0], step=k), started)
        p = as_array(lockstep(probe, requests, msg, poses))
        closest = min(closest, np.hypot(*(p[:2, 0] - p[:2, 1])))
    end = probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request(token=started.token))
    assert end.collisions == 0 and end.boundary_violations == 0
    assert closest > model.ROBOT_DIAMETER
    assert any(r.status == SafetyReport.STATUS_SOLVED and r.max_change > 0.05 for r in reports)
    changed = [s for s in safe if abs(s.twists[0].linear.x - 0.15) > 1e-3]
    assert changed, "the safety node never changed the head-on command"
    # and without it they would have collided: the same commands straight into the model
    tb = model.Testbed(HEAD_ON)
    for _ in range(150):
        tb.set_commands([0, 1], [0.15, 0.15], [0.0, 0.0])
        tb.step()
    assert tb.collisions > 0


def test_safe_command_passes_unchanged(stack):
    _, probe = stack
    poses = probe.collect(RobotPoses, NS + "/poses")
    safe = probe.collect(TwistArray, NS + "/cmd_safe")
    reports = probe.collect(SafetyReport, NS + "/safety_report")
    probe.wait_for_publishers()
    started = start(probe, np.array([[-1.0, 1.0], [0.0, 0.0], [np.pi / 2, -np.pi / 2]]))
    requests = probe.node.create_publisher(TwistArray, NS + "/cmd_requested", TESTBED_QOS)
    connected(probe, requests)
    lockstep(probe, requests, with_token(command([0, 1], [0.05, 0.05], [0.3, -0.2], step=1), started), poses)
    # the safe command and the poses it produced come from two nodes: either may arrive first
    assert probe.spin_until(lambda: safe and reports, 10)
    assert [t.linear.x for t in safe[-1].twists] == [0.05, 0.05]
    assert [t.angular.z for t in safe[-1].twists] == [0.3, -0.2]
    assert reports[-1].status == SafetyReport.STATUS_PASSTHROUGH and reports[-1].max_change == 0.0
    assert safe[-1].requested_exceeds_limits is False   # 0.05 m/s, 0.3 rad/s: far within the wheel limits


def test_bad_request_becomes_a_stop(stack):
    _, probe = stack
    poses = probe.collect(RobotPoses, NS + "/poses")
    safe = probe.collect(TwistArray, NS + "/cmd_safe")
    reports = probe.collect(SafetyReport, NS + "/safety_report")
    probe.wait_for_publishers()
    started = start(probe, np.array([[-1.0, 1.0], [0.0, 0.0], [0.0, 0.0]]))
    requests = probe.node.create_publisher(TwistArray, NS + "/cmd_requested", TESTBED_QOS)
    connected(probe, requests)
    lockstep(probe, requests, with_token(command([0, 1], [0.1, 0.1], [0.0, 0.0], step=1), started), poses)
    lockstep(probe, requests, with_token(command([0, 1], [0.1, float("nan")], [0.0, 0.0], step=2), started), poses)
    assert probe.spin_until(lambda: reports and reports[-1].step == 2 and safe and safe[-1].step == 2, 10)
    assert reports[-1].status == SafetyReport.STATUS_STOP_BAD_INPUT
    assert [t.linear.x for t in safe[-1].twists] == [0.0, 0.0]
    # the stop held the robots where they were
    assert np.array_equal(as_array(poses[-1])[:2], as_array(poses[-2])[:2])


def test_no_poses_means_stop(lone_safety):
    _, probe, safe, reports = lone_safety
    probe.wait_for_publishers()
    # the probe plays the simulator: it arms the safety node with an experiment of three robots
    arm = ArmSafety.Request(run_id="alone", number_of_robots=3, token="t" * 32, safety_key="s" * 32,
                            poses_key="p" * 32)
    assert probe.call(ArmSafety, NS + "/safety/arm", arm, resend=1.0).success
    requests = probe.node.create_publisher(TwistArray, NS + "/cmd_requested", TESTBED_QOS)
    connected(probe, requests)
    msg = command([0, 1, 2], [0.2, 0.2, 0.2], [1.0, 0.0, -1.0])
    msg.token = arm.token
    requests.publish(msg)
    assert probe.spin_until(lambda: safe and reports, 10)
    assert reports[-1].status == SafetyReport.STATUS_STOP_NO_POSES
    assert list(safe[-1].ids) == [0, 1, 2] and safe[-1].token == arm.safety_key
    assert all(t.linear.x == 0.0 and t.angular.z == 0.0 for t in safe[-1].twists)


def test_robots_stop_when_the_safety_node_dies(stack):
    nodes, probe = stack
    poses = probe.collect(RobotPoses, NS + "/poses")
    status = probe.collect(TestbedStatus, NS + "/status")
    reports = probe.collect(SafetyReport, NS + "/safety_report")
    probe.wait_for_publishers()
    started = start(probe, np.array([[-1.0, 0.0], [-0.5, 0.5], [0.0, 0.0]]), real_time=True)
    requests = probe.node.create_publisher(TwistArray, NS + "/cmd_requested", TESTBED_QOS)
    connected(probe, requests)

    def drive(seconds):
        for _ in range(int(seconds * 30)):
            requests.publish(with_token(command([0, 1], [0.1, 0.1], [0.0, 0.0]), started))
            probe.spin_for(1 / 30)

    # The safety node sends stops until the simulator's poses reach it (discovery between the two can
    # take seconds on a loaded machine): drive until it passes commands.
    deadline = time.monotonic() + 20
    while not any(r.status == SafetyReport.STATUS_PASSTHROUGH for r in reports) and time.monotonic() < deadline:
        drive(0.1)
    x_before = as_array(poses[-1])[0]
    drive(1.0)
    moved = as_array(poses[-1])[0] - x_before
    assert np.all(moved > 0.05), "robots did not move through the safety node"
    nodes["safety"].kill()  # SIGKILL: no goodbye
    drive(1.5)  # the client keeps asking; nothing passes any more
    x_late = as_array(poses[-1])[0]
    drive(0.5)
    assert np.array_equal(as_array(poses[-1])[0], x_late), "robots kept moving without the safety node"
    assert status[-1].state == TestbedStatus.STATE_RUNNING   # stopped, not ended: its client decides


def test_first_commands_of_quick_starts_are_never_lost(stack):
    # cmd_requested is volatile (ros2 topic pub's default QoS drives the testbed), so nothing published
    # before the writer matched the safety node's reader is delivered, ever. Each run starts the way a
    # new client does: a new DDS participant (discovered afresh), a publisher, the client's wait
    # (readers_matched), then at once the run's first command. In lockstep a lost first command never
    # produces step 1. (Without the wait most runs lose it, so 10 runs catch a missing wait.)
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    _, probe = stack
    poses = probe.collect(RobotPoses, NS + "/poses")
    probe.wait_for_publishers()
    for run in range(10):
        started = start(probe, np.array([[-0.5, 0.5], [0.0, 0.0], [0.0, np.pi]]))
        context = Context()
        init_context(context=context, domain_id=probe.context.get_domain_id(), node=False)
        try:
            client = Node("quick_start_%d" % run, namespace=NS, context=context)
            requests = client.create_publisher(TwistArray, "cmd_requested", TESTBED_QOS)
            deadline = time.monotonic() + 15
            while not readers_matched(client, requests, "safety") and time.monotonic() < deadline:
                time.sleep(0.01)   # the graph and the match count need no spinning
            requests.publish(with_token(command([0, 1], [0.1, 0.1], [0.0, 0.0], step=1), started))
            first = probe.spin_until(lambda: poses and poses[-1].run_id == started.run_id and poses[-1].step == 1, 10)
        finally:
            client.destroy_node()
            rclpy.try_shutdown(context=context)
        probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request(token=started.token))
        assert first, "run %d: the first command of the run was lost" % run
        assert as_array(poses[-1])[0, 0] > -0.5, "run %d: the first step did not move robot 0" % run


def test_late_poses_stop_robots_only_past_the_bound(stack):
    """Poses late under load (here: the simulator frozen with SIGSTOP) do not stop the robots until
    they are older than pose_timeout; then each command becomes a stop, counted and logged."""
    import signal
    import time

    from robotarium_core.config import DEFAULT

    nodes, probe = stack
    status = probe.collect(TestbedStatus, NS + "/status")
    reports = probe.collect(SafetyReport, NS + "/safety_report")
    probe.wait_for_publishers()
    started = start(probe, np.array([[-1.0, 0.0], [-0.5, 0.5], [0.0, 0.0]]), real_time=True)
    requests = probe.node.create_publisher(TwistArray, NS + "/cmd_requested", TESTBED_QOS)
    connected(probe, requests)

    def ask():
        """One command; the safety node's report on it (not on a re-filter of the commands in force)."""
        count = len(reports)
        requests.publish(with_token(command([0, 1], [0.05, 0.05], [0.0, 0.0]), started))
        assert probe.spin_until(lambda: any(not r.refreshed for r in reports[count:]), 10), "no safety report"
        return [r for r in reports[count:] if not r.refreshed][0]

    def ask_while_frozen(seconds):
        """Freeze the simulator (no poses), ask after `seconds`, thaw after the report came."""
        assert probe.spin_until(lambda: ask().status == SafetyReport.STATUS_PASSTHROUGH, 10)   # fresh poses now
        nodes["sim"].kill(signal.SIGSTOP)
        try:
            time.sleep(seconds)
            return ask()
        finally:
            nodes["sim"].kill(signal.SIGCONT)

    late = ask_while_frozen(0.5 * DEFAULT.pose_timeout)
    # the poses were late (several periods: the last ones may have been on their way as the simulator
    # froze, and reached the safety node up to a moment after it: 0.247 s for a freeze of 0.25 s) ...
    assert late.pose_age >= 0.25 * DEFAULT.pose_timeout
    assert late.status == SafetyReport.STATUS_PASSTHROUGH                   # ... but not too late: no stop
    assert probe.spin_until(lambda: status and status[-1].step > 0, 10)
    before, first = status[-1].stale_pose_stops, len(reports)

    stale = ask_while_frozen(1.5 * DEFAULT.pose_timeout)
    assert stale.status == SafetyReport.STATUS_STOP_NO_POSES and stale.pose_age > DEFAULT.pose_timeout
    assert probe.spin_until(lambda: ask().status == SafetyReport.STATUS_PASSTHROUGH, 10)   # passing again
    stops = sum(r.status == SafetyReport.STATUS_STOP_NO_POSES for r in reports[first:])
    assert probe.spin_until(lambda: status[-1].stale_pose_stops - before == stops, 5), \
        (status[-1].stale_pose_stops, before, stops)
    log = nodes["safety"].output()
    assert "more than pose_timeout" in log and "fresh poses again" in log, log


def test_a_safety_node_armed_mid_run_filters_at_the_poses_it_was_handed_and_a_second_arm_changes_nothing(lone_safety):
    """A safety node restarted mid-run (docs/faults.md) is armed with where the run stands: the client's next
    array goes out at once, filtered at the poses of the request (no poses message comes in lockstep until the
    testbed steps); arming it again for the same run resets nothing; poses that are not the run's robots' are
    refused; asked again before any array went through (its answer lost), it is armed again. Unarmed, it reports no drop
    counts (a restarted node's would count the client's arrays into the run)."""
    safety, probe, safe, reports = lone_safety
    requests = probe.node.create_publisher(TwistArray, NS + "/cmd_requested", TESTBED_QOS)
    connected(probe, requests)
    requests.publish(command([0, 1], [0.1, 0.1], [0.0, 0.0], step=3))   # no run armed: dropped, not reported
    arm = ArmSafety.Request(run_id="run_1", number_of_robots=2, real_time=False, token="tok", safety_key="key",
                            poses_key="poses", step=5, x=[-0.5, 0.5], y=[0.0, 0.0], theta=[0.0, np.pi])
    wrong = ArmSafety.Request(run_id="run_1", number_of_robots=2, token="tok", step=5, x=[0.0], y=[0.0], theta=[0.0])
    refused = probe.call(ArmSafety, NS + "/safety/arm", wrong, resend=1.0)
    assert not refused.success and "needs the poses of all 2 robots" in refused.message, refused.message
    probe.spin_for(1.5)   # (a report of drop counts goes out at most once a second)
    assert not reports, reports
    step_6 = command([0, 1], [0.1, 0.1], [0.0, 0.0], step=6)
    step_6.token = "tok"
    armed = probe.call(ArmSafety, NS + "/safety/arm", arm, resend=1.0)
    assert armed.success and not armed.already_armed and "from step 5 on" in armed.message, armed.message
    # asked again before any array went through (the simulator's resend: it never heard the first answer): armed
    again = probe.call(ArmSafety, NS + "/safety/arm", arm, resend=1.0)
    assert again.success and not again.already_armed and "from step 5 on" in again.message, again.message
    requests.publish(step_6)
    # (no simulator here: the node sends once lockstep_wait ran out waiting for its reader)
    assert probe.spin_until(lambda: safe, 10), safety.output()
    assert safe[-1].step == 6 and safe[-1].token == "key" and [t.linear.x for t in safe[-1].twists] == [0.1, 0.1]
    again = probe.call(ArmSafety, NS + "/safety/arm", arm, resend=1.0)
    assert again.success and again.already_armed, again.message
    requests.publish(step_6)
    probe.spin_for(1.0)
    assert len(safe) == 1   # step 6 was forwarded already: the second arm reset nothing
