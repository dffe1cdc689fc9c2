"""robotarium_core.cdr against rclpy's own serialization: the bytes we publish are the bytes rclpy
would publish, and what we read from rclpy's bytes is what rclpy reads."""
import math

import numpy as np
import pytest
from geometry_msgs.msg import Pose, PoseArray, Twist
from rclpy.serialization import deserialize_message, serialize_message

from robotarium_core import cdr
from robotarium_msgs.msg import DropCounts, RobotPoses, SafetyReport, TestbedStatus, TwistArray

RNG = np.random.default_rng(13)
SIZES = [0, 1, 3, 20, 50]


def same_bytes(ours, layout, values, theirs):
    """Ours equal rclpy's byte for byte, except in the alignment padding (rclpy leaves whatever
    was in its buffer there; we write zeros) and after the end (rclpy's serialize_message returns
    its size estimate, which can be a few bytes longer than the message)."""
    theirs = bytearray(theirs[:len(ours)])
    for offset, size in layout._writer(values).padding:
        theirs[4 + offset:4 + offset + size] = bytes(size)
    return bytes(theirs) == ours


def twist_array_message(n, step, v, w, exceeds, frame="arena", sec=17, nanosec=999):
    msg = TwistArray(step=step, requested_exceeds_limits=exceeds)
    msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id = sec, nanosec, frame
    msg.ids = list(range(n))
    for vi, wi in zip(v.tolist(), w.tolist()):
        twist = Twist()
        twist.linear.x, twist.angular.z = vi, wi
        msg.twists.append(twist)
    return msg


@pytest.mark.parametrize("n", SIZES)
def test_twist_array_is_rclpys_message_byte_for_byte(n):
    v, w = RNG.normal(size=(2, n))
    exceeds = bool(n % 2)
    msg = twist_array_message(n, 2**40 + n, v, w, exceeds)
    values = dict(sec=17, nanosec=999, frame_id="arena", step=2**40 + n, ids=np.arange(n),
                  twists=cdr.twists(v, w), requested_exceeds_limits=exceeds)
    ours = cdr.TWIST_ARRAY.build(**values)
    assert same_bytes(ours, cdr.TWIST_ARRAY, values, serialize_message(msg))
    assert deserialize_message(ours, TwistArray) == msg

    parsed = cdr.TWIST_ARRAY.parse(serialize_message(msg))
    assert (parsed.sec, parsed.nanosec, parsed.frame_id, parsed.step) == (17, 999, "arena", 2**40 + n)
    assert parsed.ids.tolist() == list(range(n))
    assert np.array_equal(parsed.twists[:, 0], v) and np.array_equal(parsed.twists[:, 5], w)
    assert not parsed.twists[:, 1:5].any()
    assert parsed.requested_exceeds_limits is exceeds


def test_every_twist_component_and_odd_strings():
    """All six components land where rclpy puts them, whatever the string lengths before them."""
    for frame in ["", "a", "ab", "abc", "abcd", "arena_5"]:
        msg = TwistArray(step=3)
        msg.header.frame_id = frame
        msg.ids = [4, 2]
        rows = RNG.normal(size=(2, 6))
        for row in rows:
            twist = Twist()
            (twist.linear.x, twist.linear.y, twist.linear.z,
             twist.angular.x, twist.angular.y, twist.angular.z) = row.tolist()
            msg.twists.append(twist)
        parsed = cdr.TWIST_ARRAY.parse(serialize_message(msg))
        assert parsed.frame_id == frame and parsed.ids.tolist() == [4, 2]
        assert np.array_equal(parsed.twists, rows)
        ours = cdr.TWIST_ARRAY.build(frame_id=frame, step=3, ids=[4, 2], twists=rows)
        assert deserialize_message(ours, TwistArray) == msg


@pytest.mark.parametrize("n", SIZES)
def test_robot_poses_and_pose_array_are_rclpys_messages(n):
    x, y, theta = RNG.uniform(-1.5, 1.5, size=(3, n))
    msg = RobotPoses(run_id="consensus_20261123-101500", step=n * 1000 + 7, sim_time=0.033 * 7)
    msg.header.stamp.sec, msg.header.frame_id = 1_800_000_000, "arena"
    msg.ids, msg.x, msg.y, msg.theta = list(range(n)), x.tolist(), y.tolist(), theta.tolist()
    values = dict(sec=1_800_000_000, frame_id="arena", run_id=msg.run_id, step=msg.step, sim_time=msg.sim_time,
                  ids=np.arange(n), x=x, y=y, theta=theta)
    ours = cdr.ROBOT_POSES.build(**values)
    assert same_bytes(ours, cdr.ROBOT_POSES, values, serialize_message(msg))
    assert deserialize_message(ours, RobotPoses) == msg
    parsed = cdr.ROBOT_POSES.parse(serialize_message(msg))
    assert (parsed.run_id, parsed.step, parsed.sim_time) == (msg.run_id, msg.step, msg.sim_time)
    assert np.array_equal(np.array([parsed.x, parsed.y, parsed.theta]), np.array([x, y, theta]))

    # the viewers' PoseArray, as the simulator built it with Pose objects
    poses = PoseArray()
    poses.header.frame_id = "arena"
    for xi, yi, ti in zip(x.tolist(), y.tolist(), theta.tolist()):
        pose = Pose()
        pose.position.x, pose.position.y = xi, yi
        pose.orientation.z, pose.orientation.w = math.sin(ti / 2), math.cos(ti / 2)
        poses.poses.append(pose)
    values = dict(frame_id="arena", poses=cdr.planar_poses(x, y, theta))
    ours = cdr.POSE_ARRAY.build(**values)
    assert same_bytes(ours, cdr.POSE_ARRAY, values, serialize_message(poses))
    assert deserialize_message(ours, PoseArray) == poses


@pytest.mark.parametrize("layout, message", [(cdr.TWIST_ARRAY, TwistArray), (cdr.ROBOT_POSES, RobotPoses),
                                             (cdr.POSE_ARRAY, PoseArray), (cdr.SAFETY_REPORT, SafetyReport)])
def test_layouts_follow_the_message_definitions(layout, message):
    """A field added to a .msg file must be added to its layout too (or every parse is off)."""
    fields = []
    for name, kind in message.get_fields_and_field_types().items():
        if kind == "robotarium_msgs/DropCounts":
            fields += list(DropCounts.get_fields_and_field_types())
            continue
        fields += ["sec", "nanosec", "frame_id"] if kind == "std_msgs/Header" else [name]
    assert list(layout.Message._fields) == fields
    assert layout.type_name == "%s/msg/%s" % (message.__module__.split(".")[0], message.__name__)


@pytest.mark.parametrize("solver_status", ["", "solved", "primal infeasible"])
def test_safety_report_is_rclpys_message_byte_for_byte(solver_status):
    drops = {name: int(k) * 3 + 1 for k, name in enumerate(DropCounts.get_fields_and_field_types())}
    values = dict(sec=5, nanosec=7, frame_id="arena", step=2**33, status=SafetyReport.STATUS_SATURATED,
                  number_of_robots=20, max_change=0.125, robots_changed=3, solve_time=1.5e-4,
                  solver_status=solver_status, pose_age=-1.0, audit=True, **drops)
    msg = SafetyReport(step=2**33, status=SafetyReport.STATUS_SATURATED, number_of_robots=20, max_change=0.125,
                       robots_changed=3, solve_time=1.5e-4, solver_status=solver_status, pose_age=-1.0, audit=True,
                       dropped=DropCounts(**drops))
    msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id = 5, 7, "arena"
    ours = cdr.SAFETY_REPORT.build(**values)
    assert same_bytes(ours, cdr.SAFETY_REPORT, values, serialize_message(msg))
    assert deserialize_message(ours, SafetyReport) == msg


@pytest.mark.parametrize("run_id", ["", "run_20261129_1", "é" * 30])
@pytest.mark.parametrize("experiment", ["x" * 7, "a long name " * 500])
def test_testbed_status_head_reads_rclpys_message(run_id, experiment):
    """The client reads a status's head (TESTBED_STATUS_HEAD) and deserialises the rest only for
    its run's IDLE status: the head's fields are those of the message's first fields, in order."""
    head = list(TestbedStatus.get_fields_and_field_types())[:9]
    assert head == ["header", "state", "experiment", "run_id", "started", "safety_rearms", "mode", "number_of_robots",
                    "step"]
    assert list(cdr.TESTBED_STATUS_HEAD.Message._fields) == (["sec", "nanosec", "frame_id"] + head[1:4]
                                                             + ["started_sec", "started_nanosec"] + head[5:])
    msg = TestbedStatus(state=TestbedStatus.STATE_IDLE, experiment=experiment, run_id=run_id, mode="lockstep",
                        number_of_robots=5, step=2 ** 40 + 3, end_reason="ended", waiting=["a", "b"],
                        dropped_cmd_safe=DropCounts(stale=3))
    msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id = 12, 34, "arena"
    msg.started.sec, msg.started.nanosec = 1_800_000_000, 999_999_999
    msg.safety_rearms = 2
    data = serialize_message(msg)
    parsed = cdr.TESTBED_STATUS_HEAD.parse(data, max_string=len(data))   # as the client and the recorder read it
    assert parsed == (12, 34, "arena", TestbedStatus.STATE_IDLE, experiment, run_id, 1_800_000_000, 999_999_999, 2,
                      "lockstep", 5, 2 ** 40 + 3)


@pytest.mark.parametrize("waiting", [[], ["alice@lab pid 7 a.py"], ["", "é" * 3, "x" * 5000]])
def test_a_whole_testbed_status_reads_and_writes_as_rclpys(waiting):
    """TESTBED_STATUS (a bag's statuses, robotarium_recording.bag): every field, each set to a value of its own,
    read from rclpy's bytes as rclpy reads it; its bytes are rclpy's message."""
    names = list(TestbedStatus.get_fields_and_field_types())
    flat = ["sec", "nanosec", "frame_id"]
    for name in names[1:]:
        if name == "started":
            flat += ["started_sec", "started_nanosec"]
        elif name.startswith("dropped_"):
            flat += ["%s_%s" % (name, reason) for reason in cdr.DROP_COUNTS]
        else:
            flat.append(name)
    assert list(cdr.TESTBED_STATUS.Message._fields) == flat
    assert list(DropCounts.get_fields_and_field_types()) == list(cdr.DROP_COUNTS)
    msg = TestbedStatus(state=1, experiment="swap", run_id="swap_1", safety_rearms=2, mode="real-time",
                        number_of_robots=7, step=2 ** 40 + 3, sim_time=12.5, collisions=4, boundary_violations=5,
                        actuator_limit_iterations=6, first_collision_step=7, first_boundary_step=8, command_timeouts=9,
                        commands_accepted=10, dropped_cmd_safe=DropCounts(**{r: 11 + k for k, r in enumerate(cdr.DROP_COUNTS)}),
                        dropped_cmd_requested=DropCounts(**{r: 21 + k for k, r in enumerate(cdr.DROP_COUNTS)}),
                        safety_interventions=31, ideal_interventions=32, poses_key_sha256="p" * 64,
                        safety_key_sha256="s" * 64, end_reason="completed", outcome=TestbedStatus.OUTCOME_TIME_LIMIT,
                        outcome_detail="Stopped at the time limit", stale_pose_stops=33, hardware=True,
                        hardware_seed=2 ** 32 - 1, holder="ada@lab pid 9 swap.py", waiting=waiting, audit=True,
                        intervention_max_change=0.25, intervention_change_sum=1.5)
    msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id = 12, 34, "arena"
    msg.started.sec, msg.started.nanosec = 1_800_000_000, 999_999_999
    data = serialize_message(msg)
    parsed = cdr.TESTBED_STATUS.parse(data, max_string=len(data))._asdict()
    for name in names:
        value = getattr(msg, name)
        if name == "header":
            assert (parsed["sec"], parsed["nanosec"], parsed["frame_id"]) == (12, 34, "arena")
        elif name == "started":
            assert (parsed["started_sec"], parsed["started_nanosec"]) == (1_800_000_000, 999_999_999)
        elif name.startswith("dropped_"):
            assert [parsed["%s_%s" % (name, r)] for r in cdr.DROP_COUNTS] == [getattr(value, r) for r in cdr.DROP_COUNTS]
        else:
            assert parsed[name] == (tuple(value) if name == "waiting" else value), name
    assert deserialize_message(cdr.TESTBED_STATUS.build(**parsed), TestbedStatus) == msg
    with pytest.raises(cdr.CdrError):   # a count of strings the bytes cannot hold: refused before any is read
        cdr.TESTBED_STATUS.parse(data[:len(data) - 30])


def test_bad_bytes_are_a_cdr_error_never_a_crash():
    good = serialize_message(twist_array_message(5, 9, np.ones(5), np.ones(5), False))
    for cut in range(len(good) - 1):   # every truncation (the last byte is the bool)
        with pytest.raises(cdr.CdrError):
            cdr.TWIST_ARRAY.parse(good[:cut])
    with pytest.raises(cdr.CdrError, match="encapsulation"):
        cdr.TWIST_ARRAY.parse(b"\x00\x00\x00\x00" + good[4:])   # big-endian CDR
    with pytest.raises(cdr.CdrError, match="at most 4 accepted"):
        cdr.TWIST_ARRAY.parse(good, max_elements=4)
    assert cdr.TWIST_ARRAY.parse(good, max_elements=5).ids.tolist() == [0, 1, 2, 3, 4]
    # a count of 2**32 - 1 twists in a short message: refused from its length, nothing allocated
    offset = good.rindex(b"\x05\x00\x00\x00", 0, len(good) - 1 - 5 * 48)   # the twists' count
    assert good[offset - 20:offset] == np.arange(5, dtype="<u4").tobytes()     # right after the ids
    huge = good[:offset] + b"\xff\xff\xff\xff" + good[offset + 4:]
    with pytest.raises(cdr.CdrError, match="truncated"):
        cdr.TWIST_ARRAY.parse(huge)
    with pytest.raises(cdr.CdrError, match="string"):
        cdr.TWIST_ARRAY.parse(good[:12] + b"\xff\xff\xff\x7f" + good[16:], max_string=1024)


def test_build_refuses_unknown_fields_and_wrong_shapes():
    with pytest.raises(TypeError, match="no field speed"):
        cdr.TWIST_ARRAY.build(speed=1.0)
    with pytest.raises(ValueError, match="shape"):
        cdr.TWIST_ARRAY.build(ids=[0], twists=np.zeros((1, 2)))


# -- the command inputs: parse_commands ---------------------------------------------------------

def array(n, token="secret", step=7, frame="arena", flag=True, seed=0):
    rng = np.random.default_rng(seed)
    msg = TwistArray(step=step, token=token, requested_exceeds_limits=flag, ids=list(range(n)))
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = -5, 123
    for _ in range(n):
        t = Twist()
        t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z = rng.normal(size=6)
        msg.twists.append(t)
    return msg


@pytest.mark.parametrize("n, token, frame", [(0, "", ""), (1, "a", "arena"), (3, "secret", "ab"),
                                             (50, "x" * 32, "arena_frame"), (7, "tok", "abc")])
def test_every_field_as_rclpy_serializes_it(n, token, frame):
    msg = array(n, token=token, frame=frame)
    parsed = cdr.parse_commands(serialize_message(msg), max_robots=50)
    assert parsed.token == token and parsed.step == 7 and parsed.requested_exceeds_limits is True
    assert (parsed.sec, parsed.nanosec) == (-5, 123)
    assert parsed.ids.tolist() == list(range(n))
    assert parsed.v.tolist() == [t.linear.x for t in msg.twists]
    assert parsed.omega.tolist() == [t.angular.z for t in msg.twists]


def test_ids_and_twists_of_different_lengths_come_through_for_check_commands():
    msg = array(3)
    msg.ids = [0, 1]
    parsed = cdr.parse_commands(serialize_message(msg), max_robots=5)
    assert len(parsed.ids) == 2 and len(parsed.v) == 3


def test_an_array_without_the_token_is_foreign():
    data = serialize_message(array(3, token="someone-else"))
    with pytest.raises(cdr.CdrError) as error:
        cdr.parse_commands(data, max_robots=5, token="secret")
    assert error.value.reason == cdr.FOREIGN
    for other in ("", "secre", "secret2"):
        with pytest.raises(cdr.CdrError):
            cdr.parse_commands(serialize_message(array(3, token=other)), max_robots=5, token="secret")
    assert cdr.parse_commands(serialize_message(array(3)), max_robots=5, token="secret").step == 7


def test_more_robots_than_the_experiment_has_is_oversized_before_reading_them():
    data = serialize_message(array(9))
    with pytest.raises(cdr.CdrError) as error:
        cdr.parse_commands(data, max_robots=8)
    assert error.value.reason == cdr.OVERSIZED
    # a count field claiming 2**32 - 1 entries in a short message: refused from the count alone
    head = serialize_message(array(0))
    offset = len(head) - 1 - 4 - 4   # bool, twists count, ids count (0 entries each)
    lying = head[:offset] + (2 ** 32 - 1).to_bytes(4, "little") + head[offset + 4:]
    with pytest.raises(cdr.CdrError) as error:
        cdr.parse_commands(lying, max_robots=50)
    assert error.value.reason == cdr.OVERSIZED


def test_every_truncation_is_malformed_never_an_exception_of_another_kind():
    data = serialize_message(array(4))
    for cut in range(len(data)):
        with pytest.raises(cdr.CdrError) as error:
            cdr.parse_commands(data[:cut], max_robots=50)
        assert error.value.reason == cdr.MALFORMED
    with pytest.raises(cdr.CdrError) as error:
        cdr.parse_commands(b"\x07\x07\x00\x00" + data[4:], max_robots=50)   # not a CDR encapsulation
    assert error.value.reason == cdr.MALFORMED
    with pytest.raises(cdr.CdrError) as error:   # a token that is not what it claims: malformed, not foreign
        cdr.parse_commands(data[:4 + 20] + b"\xff\xff\xff\x7f" + data[4 + 24:], max_robots=50, token="secret")
    assert error.value.reason == cdr.MALFORMED


def test_random_bytes_never_raise_anything_but_cdr_error():
    rng = np.random.default_rng(1)
    good = serialize_message(array(5))
    for _ in range(2000):
        data = bytearray(good)
        for i in rng.integers(0, len(data), size=rng.integers(1, 6)):
            data[i] = rng.integers(0, 256)
        try:
            parsed = cdr.parse_commands(bytes(data), max_robots=50)
        except cdr.CdrError as error:
            assert error.reason in (cdr.FOREIGN, cdr.OVERSIZED, cdr.MALFORMED)
        else:
            assert len(parsed.ids) <= 50 and len(parsed.v) <= 50


@pytest.mark.parametrize("layout", [cdr.TWIST_ARRAY, cdr.ROBOT_POSES, cdr.SAFETY_REPORT, cdr.POSE_ARRAY, cdr.MARKER,
                                    cdr.TESTBED_STATUS_HEAD])
def test_build_and_parse_of_scalar_runs_equal_the_field_by_field_path(layout):
    """build and parse pack consecutive scalars with one struct per alignment phase (cdr._steps):
    the same bytes as writing field by field (_write), and the same values read back, for strings
    of every length modulo 8 before each run (every phase) and random values."""
    rng = np.random.default_rng(3)
    for trial in range(64):
        values = {}
        for name, kind in layout.fields:
            if isinstance(kind, cdr._String):
                values[name] = "s" * int(rng.integers(0, 17))
            elif isinstance(kind, cdr._Sequence):
                count = int(rng.integers(0, 4))
                shape = (count, kind.width) if kind.width else (count,)
                values[name] = (rng.integers(0, 200, shape) if kind.dtype.kind in "ui" else rng.normal(size=shape)
                                ).astype(kind.dtype)
            elif kind.fmt == "?":
                values[name] = bool(rng.integers(0, 2))
            elif kind.fmt in "dfe":
                values[name] = float(np.float32(rng.normal())) if kind.fmt == "f" else float(rng.normal())
            else:
                values[name] = int(rng.integers(0, 2 ** (8 * kind.size - 1)))
        ours = layout.build(**values)
        assert ours == b"".join(layout._writer(values).parts)
        parsed = layout.parse(ours)
        for name, _ in layout.fields:
            assert np.array_equal(getattr(parsed, name), values[name]), (trial, name)
    with pytest.raises(TypeError, match="no field"):
        layout.build(nonsense=1)
