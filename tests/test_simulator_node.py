"""The simulator node, started for real in a subprocess on its own DDS domain."""
import os
import re
import subprocess
import sys
import time

import numpy as np
import pytest
from geometry_msgs.msg import Twist

from devtools.rosutil import REPO, NodeProcess, RosProbe, SafetyStandIn, node_env, unique_domain_id
from robotarium_core import model
from robotarium_core.config import DEFAULT
from robotarium_core.topics import TESTBED_QOS
from robotarium_msgs.msg import RobotPoses, TestbedStatus, TwistArray
from robotarium_msgs.srv import EndExperiment, StartExperiment

pytestmark = pytest.mark.node   # real testbed nodes in subprocesses

NS = "/robotarium"
LISTENERS_WAIT_HERE = 2.0   # s (the simulator's listeners_wait): what a start waits for a reader that never comes


@pytest.fixture
def testbed(tmp_path):
    domain = unique_domain_id()
    sim = NodeProcess("robotarium_sim.simulator_node", domain, log_path=tmp_path / "simulator.log",
                      ros_args=["-p", "listeners_wait:=%r" % LISTENERS_WAIT_HERE])
    probe = RosProbe(domain)
    try:
        safety = SafetyStandIn(probe)   # the test plays the safety node: arms, and publishes on cmd_safe
        yield sim, probe, safety
    finally:
        probe.close()
        sim.close()


def start(probe, n=3, real_time=False, poses=None, name="test", seed=1):
    request = StartExperiment.Request(name=name, number_of_robots=n, real_time=real_time, seed=seed)
    if poses is not None:
        request.x, request.y, request.theta = (list(map(float, row)) for row in poses)
    return probe.start_experiment(request, NS)


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


def end(probe, response):
    """End the experiment `response` (its StartExperiment response) started, as its client."""
    return probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request(token=response.token))


def test_start_and_end_round_trip(testbed):
    _, probe, safety = testbed
    response = start(probe, n=3, poses=LINE, name="roundtrip")
    assert response.success, response.message
    assert response.run_id.startswith("roundtrip_")
    assert np.array_equal(np.array([response.x, response.y, response.theta]), LINE)
    # the safety node was armed with this experiment, the client's token and fresh keys
    assert safety.armed.run_id == response.run_id and safety.armed.token == response.token
    assert len({response.token, safety.armed.safety_key, response.poses_key}) == 3 and len(response.token) == 32

    second = start(probe, n=2, name="other")
    assert not second.success and "still running" in second.message

    ended = end(probe, response)
    assert ended.success and ended.run_id == response.run_id and ended.steps == 0
    assert "No errors in your simulation!" in ended.report
    assert ended.end_reason == "ended by its client at step 0"
    assert probe.spin_until(lambda: safety.armed.run_id == "", 10)   # disarmed (the simulator does not wait for it)

    again = end(probe, response)
    assert not again.success and "no experiment" in again.message
    assert start(probe, n=2, name="after").success  # a new one may start once the old one ended


def test_only_its_client_or_an_operator_ends_an_experiment(testbed):
    _, probe, _ = testbed
    response = start(probe, n=2, poses=LINE[:, :2])
    assert response.success, response.message
    for stranger in (EndExperiment.Request(), EndExperiment.Request(token="0" * 32)):
        refused = probe.call(EndExperiment, NS + "/end_experiment", stranger)
        assert not refused.success and "belongs to the client that started it" in refused.message
        assert "--force" in refused.message
    forced = probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request(force=True))
    assert forced.success and forced.end_reason == "ended by an operator (end --force) at step 0"
    assert "did not complete" in forced.report   # an operator's end interrupts the run


def test_how_a_run_ended_is_in_the_closing_status_and_only_a_completed_run_is_estimated(testbed):
    _, probe, _ = testbed
    status = probe.collect(TestbedStatus, NS + "/status")
    for outcome, detail in ((TestbedStatus.OUTCOME_SCRIPT_ERROR, "the script raised KeyError: 'goal' at step 0"),
                            (TestbedStatus.OUTCOME_NONE, "")):
        started = start(probe, n=2, poses=LINE[:, :2], name="ending")
        assert started.success
        ended = probe.call(EndExperiment, NS + "/end_experiment",
                           EndExperiment.Request(token=started.token, outcome=outcome, detail=detail))
        assert ended.success
        completed = outcome == TestbedStatus.OUTCOME_NONE   # an empty request: call_at_scripts_end
        assert ("Acceptance of your experiment is likely" in ended.report) == completed
        assert ("did not complete" in ended.report) != completed
        assert probe.spin_until(lambda: status and status[-1].state == TestbedStatus.STATE_IDLE
                                and status[-1].run_id == ended.run_id, 5)
        closing = status[-1]
        want = TestbedStatus.OUTCOME_COMPLETED if completed else outcome
        assert (closing.outcome, closing.outcome_detail) == (want, detail)
        # a new experiment clears it until it ends
        following = start(probe, n=2, poses=LINE[:, :2], name="next")
        assert probe.spin_until(lambda: status[-1].state == TestbedStatus.STATE_RUNNING, 5)
        assert status[-1].outcome == TestbedStatus.OUTCOME_NONE
        end(probe, following)


def test_a_late_joiner_gets_only_the_newest_status_and_the_stream_every_one(testbed):
    """<ns>/status is the testbed's state (issue 23): a subscriber that joins after two runs (as
    `ros2 topic echo --once` does) gets the newest status first, never one from before the last run
    (it got the oldest of a history of 50). The hidden stream, subscribed throughout, got every status
    of both runs, as the recorder needs: the first RUNNING, the final RUNNING and the closing IDLE."""
    from robotarium_core.topics import STATUS_STREAM
    _, probe, _ = testbed
    stream = probe.collect(TestbedStatus, "%s/%s" % (NS, STATUS_STREAM))
    runs = []
    for name in ("first", "second"):
        started = start(probe, n=2, poses=LINE[:, :2], name=name)
        assert started.success, started.message
        assert end(probe, started).success
        runs.append(started.run_id)
    idle, running = TestbedStatus.STATE_IDLE, TestbedStatus.STATE_RUNNING
    assert probe.spin_until(lambda: any(s.run_id == runs[1] and s.state == idle for s in stream), 10)
    for run_id in runs:
        states = [s.state for s in stream if s.run_id == run_id]
        closing = states.index(idle)
        assert states[0] == running and closing >= 2 and states[closing - 1] == running, (run_id, states)
    # as a late joiner asks for a latched topic (transient local; a volatile reader would only see the
    # next heartbeat): the newest status comes from the writer's history at once
    from robotarium_core.topics import STATUS_QOS
    late = probe.collect(TestbedStatus, NS + "/status", STATUS_QOS)
    assert probe.spin_until(lambda: late, 10), "the late joiner got no status"
    assert (late[0].run_id, late[0].state) == (runs[1], idle), [(s.run_id, s.state) for s in late]


def test_a_runs_first_poses_wait_for_the_client_readers_it_names(testbed):
    """The streams are volatile (issue 23): the run's first poses go out once the simulator's writer
    matched the reader of the client that StartExperiment.client_node names, so a reader made just
    before the start gets step 0; a client that never shows is waited for listeners_wait s (set low
    here), and the log names whose reader was missing."""
    sim, probe, _ = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")   # made now, the start follows at once
    started = start(probe, n=2, poses=LINE[:, :2], name="fresh")
    assert started.success, started.message
    assert probe.spin_until(lambda: any(p.run_id == started.run_id and p.step == 0 for p in poses), 5)
    assert end(probe, started).success
    request = StartExperiment.Request(name="nobody", number_of_robots=2, real_time=False, seed=1,
                                      client_node=NS + "/nobody")
    request.x, request.y, request.theta = (list(map(float, row)) for row in LINE[:, :2])
    began = time.monotonic()
    started = probe.start_experiment(request, NS)
    assert started.success and time.monotonic() - began >= LISTENERS_WAIT_HERE, started.message
    assert end(probe, started).success
    said = "starting without %s/nobody's reader of %s/poses" % (NS, NS)
    # (the node's log is its own process's file: read it until the line is there)
    assert probe.spin_until(lambda: said in sim.output(), 5), sim.output()


def test_an_invalid_start_is_refused_with_its_reason(testbed):
    """Every reason is tested in process (robotarium_sim/test/test_experiment.py); here that one reaches the client."""
    _, probe, _ = testbed
    response = start(probe, n=3, poses=np.array([[0.0, 0.5], [0.0, 0.0], [0.0, 0.0]]))
    assert not response.success and "length 3" in response.message
    assert start(probe, n=2, poses=LINE[:, :2]).success   # and the testbed is free for the next


def lockstep(probe, publisher, msg, poses_topic, timeout=10.0):
    """Publish lockstep command `msg` (msg.step = k), wait for the poses of step k, return them."""
    k = msg.step
    publisher.publish(msg)
    if not probe.spin_until(lambda: poses_topic and poses_topic[-1].step >= k, timeout):
        raise AssertionError("no poses for step %d within %.0f s" % (k, timeout))
    assert poses_topic[-1].step == k, "step %d produced poses of step %d" % (k, poses_topic[-1].step)
    return poses_topic[-1]


def run_lockstep(probe, safety, commands, poses_topic):
    """Send each command array, wait for the step it produces; return the poses seen."""
    safety.wait_for_simulator()
    trace = []
    for k, (v, w) in enumerate(commands, start=1):
        trace.append(as_array(lockstep(probe, safety, command(range(len(v)), v, w, step=k), poses_topic)))
    return np.array(trace)


def test_lockstep_is_deterministic(testbed):
    _, probe, safety = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    probe.wait_for_publishers()
    rng = np.random.default_rng(0)
    commands = [(rng.uniform(-0.1, 0.1, 3), rng.uniform(-1, 1, 3)) for _ in range(60)]
    runs = []
    for _ in range(2):
        started = start(probe, n=3, poses=LINE)
        assert started.success
        runs.append(run_lockstep(probe, safety, commands, poses))
        assert end(probe, started).steps == 60
        poses.clear()
    assert np.array_equal(runs[0], runs[1])
    # and it is the model's trajectory: the robots did move
    assert np.abs(runs[0][-1] - LINE).max() > 0.05


def test_a_client_whose_arrays_keep_coming_is_not_lost_when_its_liveliness_lapses(testbed):
    """A starved machine can hold back a client's liveliness assertions for seconds while its arrays
    keep coming (a lockstep client was ended as lost at step 1520 of a run it was driving): the testbed
    ends an experiment for a lost client only once its arrays have stopped for the lease too."""
    _, probe, safety = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    status = probe.collect(TestbedStatus, NS + "/status")
    probe.wait_for_publishers()
    started = start(probe, n=3, poses=LINE)
    assert started.success, started.message
    safety.wait_for_simulator()
    lockstep(probe, safety, command(range(3), [0.0] * 3, [0.0] * 3, step=1), poses)
    probe.drop_client_presences()   # its liveliness ends ("left"), its arrays go on for twice the lease
    k, until = 1, time.monotonic() + 2 * DEFAULT.client_lease
    while time.monotonic() < until:
        k += 1
        lockstep(probe, safety, command(range(3), [0.0] * 3, [0.0] * 3, step=k), poses)
        probe.spin_for(0.05)
    stopped = time.monotonic()
    assert probe.spin_until(lambda: any(m.run_id == started.run_id and m.state == TestbedStatus.STATE_IDLE
                                        for m in status), DEFAULT.client_lease + 10)
    assert time.monotonic() - stopped >= DEFAULT.client_lease - 0.3   # not before the arrays had stopped that long
    ended = [m for m in status if m.run_id == started.run_id and m.state == TestbedStatus.STATE_IDLE][-1]
    assert ended.end_reason == "client lost at step %d" % k, ended.end_reason


def test_hardware_like_lockstep_is_the_same_for_a_seed(tmp_path):
    """`./robotarium up --hardware`: every experiment runs the hardware-like model; in lockstep a
    seed gives the same run bit for bit, another seed another run, and neither is the ideal one."""
    domain = unique_domain_id()
    sim = NodeProcess("robotarium_sim.simulator_node", domain, ros_args=["-p", "hardware:=true"],
                      log_path=tmp_path / "simulator.log")
    probe = RosProbe(domain)
    try:
        safety = SafetyStandIn(probe)
        poses = probe.collect(RobotPoses, NS + "/poses")
        probe.wait_for_publishers()
        rng = np.random.default_rng(0)
        commands = [(rng.uniform(0.05, 0.15, 3), rng.uniform(-1, 1, 3)) for _ in range(60)]
        runs = []
        for seed in (7, 7, 8):
            started = start(probe, n=3, poses=LINE, seed=seed)
            assert started.success and "hardware-like (seed %d)" % seed in started.message, started.message
            runs.append(run_lockstep(probe, safety, commands, poses))
            ended = end(probe, started)
            assert ended.hardware and ended.hardware_seed == seed and ended.steps == 60
            assert "simulated the real testbed's hardware" in ended.report
            poses.clear()
        assert np.array_equal(runs[0], runs[1])
        assert not np.array_equal(runs[0], runs[2])
        ideal = model.Testbed(LINE)
        for v, w in commands:
            ideal.set_commands(range(3), v, w)
            ideal.step()
        assert np.abs(runs[0][-1, :2] - ideal.poses[:2]).max() > 0.005
    finally:
        probe.close()
        sim.close()


def test_bad_commands_are_dropped_counted_and_never_move_robots(testbed):
    _, probe, safety = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    status = probe.collect(TestbedStatus, NS + "/status")
    probe.wait_for_publishers()
    assert start(probe, n=3, poses=LINE).success
    safety.wait_for_simulator()
    bad = [
        command([0, 1, 2], [0.1, float("nan"), 0.1], [0, 0, 0]),     # nonfinite
        command([0, 1, 2], [0.1, 0.1, 0.1], [0, float("inf"), 0]),   # nonfinite
        command([0, 1, 2], [0.1, 0.1], [0, 0]),                      # length mismatch
        command([0, 0, 1], [0.1, 0.1, 0.1], [0, 0, 0]),              # duplicate id
        command([0, 1, 7], [0.1, 0.1, 0.1], [0, 0, 0]),              # unknown id
    ]
    for msg in bad:
        safety.publish(msg)

    def counted():
        dropped = status and status[-1].dropped_cmd_safe
        return dropped and (dropped.nonfinite, dropped.length_mismatch, dropped.unknown_id) == (2, 2, 1)
    assert probe.spin_until(counted, 10), status[-1] if status else "no status"
    assert status[-1].step == 0 and status[-1].commands_accepted == 0
    assert all(p.step == 0 for p in poses) and np.array_equal(as_array(poses[-1]), LINE)

    lockstep(probe, safety, command([0, 1, 2], [0.1, 0.1, 0.1], [0, 0, 0], step=1), poses)  # good ones work
    assert as_array(poses[-1])[0, 0] == pytest.approx(-0.5 + 0.033 * 0.1)


def test_real_time_tick_rate_is_30_hz(testbed):
    _, probe, _ = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    probe.wait_for_publishers()
    assert start(probe, n=5, real_time=True).success
    probe.spin_for(3.5)
    stamps = np.array([p.header.stamp.sec + p.header.stamp.nanosec * 1e-9 for p in poses if p.step > 0])
    steps = np.array([p.step for p in poses if p.step > 0])
    assert np.all(np.diff(steps) == 1), "lost or reordered poses"
    assert stamps[-1] - stamps[0] > 2.9
    # The tick's period, not the throughput: a starved process may miss a tick (rcl skips a period
    # it is late for rather than bursting), which lowers the mean rate but not the period kept.
    assert float(np.median(np.diff(stamps))) == pytest.approx(1 / 30.0, rel=0.02)
    assert (len(stamps) - 1) / (stamps[-1] - stamps[0]) <= 30.0 * 1.02   # never faster than real time


@pytest.mark.realtime   # 15 ticks in the command's 0.5 s of wall time: a starved simulator skips ticks (13 under load 17)
def test_command_held_for_half_a_second_then_robot_stops(testbed):
    sim, probe, safety = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    status = probe.collect(TestbedStatus, NS + "/status")
    probe.wait_for_publishers()
    assert start(probe, n=1, real_time=True, poses=np.array([[0.0], [0.0], [0.0]])).success
    safety.wait_for_simulator()
    safety.publish(command([0], [0.1], [0.0]))
    probe.spin_for(1.5)
    x = np.array([p.x[0] for p in poses])
    moving_steps = np.count_nonzero(np.diff(x) > 0)
    # 0.5 s at 30 Hz is 15 ticks (one either way for where the command lands between ticks)
    assert 14 <= moving_steps <= 16
    assert x[-1] == pytest.approx(moving_steps * 0.033 * 0.1)
    assert x[-1] == x[-20]  # and it stays stopped
    assert status[-1].command_timeouts == 1
    # the log says which robot stopped, when, and how late its command was
    said = re.findall(r"robots 0 stopped at step (\d+): no command for (\d\.\d\d) s \(the command timeout is 0.50 s\)",
                      sim.output())
    assert len(said) == 1 and 0.5 < float(said[0][1]) < 0.6 and int(said[0][0]) >= 14, sim.output()


def test_safety_interventions_are_counted(testbed):
    from robotarium_msgs.msg import SafetyReport
    _, probe, _ = testbed
    status = probe.collect(TestbedStatus, NS + "/status")
    probe.wait_for_publishers()
    assert start(probe, n=2, poses=LINE[:, :2]).success
    publisher = probe.node.create_publisher(SafetyReport, NS + "/safety_report", TESTBED_QOS)
    assert probe.spin_until(lambda: publisher.get_subscription_count() > 0, 10)
    # An intervention: a stop or a solved QP that changed a command beyond intervention_tolerance (1e-3);
    # not a stop of a request at rest (counted, it made "658 interventions, largest change 0").
    tolerance = DEFAULT.intervention_tolerance
    for state, change in ((SafetyReport.STATUS_PASSTHROUGH, 0.0), (SafetyReport.STATUS_SOLVED, 0.5 * tolerance),
                          (SafetyReport.STATUS_SOLVED, 0.2), (SafetyReport.STATUS_STOP_NO_POSES, 0.0),
                          (SafetyReport.STATUS_STOP_BAD_INPUT, 0.1), (SafetyReport.STATUS_PASSTHROUGH, 0.0)):
        publisher.publish(SafetyReport(status=state, max_change=change))
    assert probe.spin_until(lambda: status and status[-1].safety_interventions == 2, 5)
    probe.spin_for(0.3)
    assert status[-1].safety_interventions == 2


def test_an_end_counts_the_safety_reports_still_on_their_way(testbed):
    """The safety node's reports travel apart from its arrays and may come after the client's end
    (a lost packet is repaired seconds later on a loaded machine: the console once said 172 of 243
    interventions): the end waits for the report of every array applied before it answers."""
    from robotarium_msgs.msg import SafetyReport
    _, probe, safety = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    probe.wait_for_publishers()
    started = start(probe, n=3, poses=LINE)
    assert started.success
    safety.wait_for_simulator()
    for k in range(1, 6):   # five steps, the reports held back
        safety.publish(command(range(3), [0.1] * 3, [0.0] * 3, step=k), report=False)
        assert probe.spin_until(lambda: poses and poses[-1].step == k, 10)
    client = probe.node.create_client(EndExperiment, NS + "/end_experiment")
    assert client.wait_for_service(timeout_sec=10)
    ending = client.call_async(EndExperiment.Request(token=started.token))
    probe.spin_for(0.5)
    assert not ending.done()   # waiting for the reports
    for k in range(1, 6):
        safety.publish_report(k, SafetyReport.STATUS_SOLVED, max_change=0.2)
    assert probe.spin_until(ending.done, 10)
    ended = ending.result()
    assert ended.success and ended.steps == 5 and ended.safety_interventions == 5, ended


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


def test_viewers_get_the_scene_at_the_viewer_rate_not_every_step(testbed):
    from visualization_msgs.msg import Marker, MarkerArray

    from robotarium_core.config import DEFAULT
    from robotarium_core.topics import VIEWER_QOS
    _, probe, safety = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    scenes = probe.collect(MarkerArray, NS + "/markers", VIEWER_QOS)   # what RViz asks for by default
    probe.wait_for_publishers()
    started = start(probe, n=3, poses=LINE)
    safety.wait_for_simulator()
    steps = 120
    began, before = time.monotonic(), len(scenes)
    for k in range(1, steps + 1):
        lockstep(probe, safety, command(range(3), [0.1, 0.1, 0.1], [0.5, 0.0, -0.5], step=k), poses)
    probe.spin_for(3.0 / DEFAULT.viewer_rate)   # a scene or more after the last step
    # At most one scene per viewer period of the time it took, however many steps that was (a scene
    # per step would be 120): a loaded machine makes the timer fire less often, never more.
    periods = (time.monotonic() - began) * DEFAULT.viewer_rate
    assert 0 < len(scenes) - before <= periods + 2, (
        "%d scenes for %d lockstep steps in %.1f viewer periods" % (len(scenes) - before, steps, periods))
    latest = scenes[-1].markers
    assert latest[0].action == Marker.DELETEALL and all(m.header.frame_id == "arena" for m in latest)
    bodies = sorted((m for m in latest if m.ns == "robots"), key=lambda m: m.id)
    assert np.allclose([(m.pose.position.x, m.pose.position.y) for m in bodies], as_array(poses[-1])[:2].T)
    trail = next(m for m in latest if m.ns == "trails")
    assert len(trail.points) > 3 * 2                    # each robot's recent path, not just where it is
    end(probe, started)
    count = len(scenes)
    assert probe.spin_until(lambda: len(scenes) > count and {m.ns for m in scenes[-1].markers[1:]} == {"arena"}, 5)


def test_a_huge_finite_command_is_full_speed_on_its_arc_never_a_stop(testbed):
    """1e308 on cmd_safe (from the safety node's key holder) once overflowed the thresholding into
    a stop; it drives at the limits like any command beyond them."""
    _, probe, safety = testbed
    poses = probe.collect(RobotPoses, NS + "/poses")
    probe.wait_for_publishers()
    assert start(probe, n=2, poses=LINE[:, :2]).success
    safety.wait_for_simulator()
    p = as_array(lockstep(probe, safety, command([0, 1], [1e308, 1e308], [0.0, 1e308], step=1), poses))
    assert p[0, 0] == -0.5 + 0.033 * 0.2                # straight on at 0.2 m/s
    reach = model.threshold_keeping_arc(np.array([[1.0], [1.0]]))[0, 0]   # v = omega at the wheel limit
    assert p[0, 1] == pytest.approx(0.033 * reach) and p[2, 1] == pytest.approx(0.033 * reach)
