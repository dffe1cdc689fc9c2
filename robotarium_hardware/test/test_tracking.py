"""The roster: poses in (calibrated, NaN dropped and counted), who is tracked and answering, the
refusal that names the robots, the faults that stop a run; the pose bytes; the arena's testbed."""
import math

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.serialization import serialize_message

from robotarium_core import model
from robotarium_core.config import DEFAULT
from robotarium_hardware import fleet as fleets
from robotarium_hardware.templates import Template
from robotarium_hardware.tracking import FleetTestbed, Roster, parse_pose_stamped, yaw_from_quaternion

FLEET = fleets.from_dict({"robots": [{"name": "r0", "answer_topic": "/r0/odom"}, "r1", "r2"], "lost_after": 0.08,
                          "lost_behind": 0.05, "answer_timeout": 0.1, "calibration": {"x": 1.0, "yaw": math.pi / 2}})


def pose_bytes(x, y, yaw, frame="world"):
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 500_000_000
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return serialize_message(msg)


@pytest.mark.parametrize("frame", ["", "w", "world", "a_longer_frame_name"])
def test_pose_bytes_are_read_whatever_the_frame_ids_length(frame):
    stamp, x, y, qx, qy, qz, qw = parse_pose_stamped(pose_bytes(0.25, -0.5, 1.0, frame))
    assert (stamp, x, y) == (12.5, 0.25, -0.5) and math.isclose(yaw_from_quaternion(qx, qy, qz, qw), 1.0)


def test_a_template_patches_only_the_fields_it_names():
    msg = PoseStamped()
    msg.header.frame_id = "world"
    template = Template(msg, ("header.stamp.sec", "header.stamp.nanosec", "pose.position.x", "pose.position.y",
                              "pose.orientation.z", "pose.orientation.w"))
    stamp, x, y, _, _, qz, qw = parse_pose_stamped(template.build(3, 250_000_000, 0.1, 0.2, 0.0, 1.0))
    assert (stamp, x, y, qz, qw) == (3.25, 0.1, 0.2, 0.0, 1.0)


def test_poses_are_calibrated_and_bad_ones_dropped_and_counted():
    roster = Roster(FLEET)
    assert roster.pose_message(1, pose_bytes(0.5, 0.0, 0.0), now=10.0)
    assert np.allclose(roster.poses[:, 1], [1.0, 0.5, math.pi / 2])   # turned a quarter, shifted 1 m in x
    assert not roster.pose_message(1, pose_bytes(float("nan"), 0.0, 0.0), now=10.0)
    assert not roster.pose_message(1, b"\x00\x01\x00\x00garbage", now=10.0)
    assert roster.dropped["not_finite"][1] == 1 and roster.dropped["malformed"][1] == 1
    assert np.allclose(roster.poses[:, 1], [1.0, 0.5, math.pi / 2])   # the good pose stays


def test_an_experiment_for_more_robots_than_are_ready_is_refused_naming_them():
    roster = Roster(FLEET)
    for i in range(3):
        roster.pose(i, 0.1 * i, 0.0, 0.0, now=5.0)
    roster.answer(0, now=5.0)
    assert list(roster.pick(3, now=5.05)) == [0, 1, 2]
    roster.pose(1, 0.1, 0.0, 0.0, now=5.1)
    roster.pose(2, 0.2, 0.0, 0.0, now=5.1)
    with pytest.raises(model.RobotariumError) as error:   # r0: no pose for 0.11 s and its odometry silent
        roster.pick(3, now=5.11)
    message = str(error.value)
    assert "asks for 3 robots, but only 2" in message and "(r1, r2)" in message
    assert "r0 not tracked (no pose for 0.1 s), not answering" in message
    assert list(roster.pick(2, now=5.11)) == [1, 2]


def test_faults_name_the_robot_that_lost_tracking_or_stopped_answering():
    roster = Roster(FLEET)
    for i in range(3):
        roster.pose(i, 0.0, 0.1 * i, 0.0, now=1.0)
    roster.answer(0, now=1.0)
    run = np.array([0, 1, 2])
    assert roster.faults(run, now=1.05) == []
    # the others seen again, r2 not: lost once its newest pose's stamp lags theirs by more than lost_behind
    for i in range(3):
        roster.pose(i, 0.0, 0.1 * i, 0.0, now=1.0, stamp=100.0)
    for t in (1.03, 1.06):
        roster.pose(0, 0.0, 0.0, 0.0, now=t, stamp=99.0 + t)
        assert roster.faults(run, now=t) == []   # the frame's other poses may still be on their way
        roster.pose(1, 0.0, 0.1, 0.0, now=t, stamp=99.0 + t)
        roster.answer(0, now=t)
        assert roster.faults(run, now=t + 0.006) == ([] if t < 1.05 else ["robot r2 lost tracking"])
    # this process stalled: the poses that came late carry their own stamps, so nobody is behind
    roster.pose(2, 0.0, 0.2, 0.0, now=1.065, stamp=100.06)
    assert roster.faults(run, now=1.07) == []
    # a tracking system that stops loses every robot after lost_after; a robot that stops answering says so
    assert roster.faults(run[:2], now=1.15) == ["robot r0 lost tracking", "robot r1 lost tracking"]
    assert roster.faults(run[:2], now=1.17) == ["robot r0 lost tracking and stopped answering",
                                                 "robot r1 lost tracking"]
    roster.pose(0, 0.0, 0.0, 0.0, now=1.17, stamp=100.17)
    roster.pose(1, 0.0, 0.1, 0.0, now=1.17, stamp=100.17)
    assert roster.faults(run[:2], now=1.18) == ["robot r0 stopped answering"]


def test_the_arenas_testbed_counts_on_measured_poses_and_thresholds_its_commands():
    measured = np.array([[-0.5, 0.5], [0.0, 0.0], [0.0, 0.0]])
    tb = FleetTestbed(measured, DEFAULT, [0, 1], lambda: np.array([[-0.5, -0.45], [0.0, 0.0], [0.0, 0.0]]), 0.025)
    assert tb.latency == 0.025   # what the safety node widens its margins by (ArmSafety.latency)
    tb.set_commands([0, 1], [1.0, 0.1], [0.0, 0.0], now=0.0)
    assert np.allclose(tb.commands_out()[0], [DEFAULT.max_linear_velocity, 0.1])
    tb.step()
    tb.step()
    assert tb.collisions == 1 and tb.steps == 2   # the second step counted on the measured poses, 5 cm apart
    assert tb.expire_commands(now=1.0, timeout=0.5).all() and not tb.commands_out().any()


def test_a_robot_of_the_fleet_in_the_arena_but_not_in_the_experiment_is_in_the_way():
    roster = Roster(fleets.from_dict({"robots": ["r0", "r1", "r2"]}))
    roster.pose(0, 0.0, 0.0, 0.0, now=1.0)
    roster.pose(1, 0.5, 0.0, 0.0, now=1.0)
    roster.pose(2, 2.5, 0.0, 0.0, now=1.0)   # parked beyond the arena's edge
    assert roster.in_the_way(np.array([0, 1]), 1.0, DEFAULT.arena) is None
    with pytest.raises(model.RobotariumError, match="robot.s. r1 of fleet fleet stand in the arena but are not in"):
        roster.in_the_way(np.array([0]), 1.0, DEFAULT.arena)


def test_a_frame_still_arriving_puts_nobody_behind():
    """Twelve robots, one frame's poses arriving one by one (a loaded machine): while fewer than half have the
    new frame, the others are not behind; a robot missing from the frames the others are in is."""
    fleet = fleets.from_dict({"robots": ["r%d" % k for k in range(12)], "lost_after": 0.5, "lost_behind": 0.05})
    roster = Roster(fleet)
    for k in range(12):
        roster.pose(k, 0.3 * k - 1.5, 0.0, 0.0, now=1.0, stamp=10.0)
    for k in range(5):   # 5 of 12 have a frame 60 ms newer
        roster.pose(k, 0.3 * k - 1.5, 0.0, 0.0, now=1.06, stamp=10.06)
    assert roster.faults(np.arange(12), now=1.07) == []
    for k in range(5, 11):   # all but r11 have it
        roster.pose(k, 0.3 * k - 1.5, 0.0, 0.0, now=1.07, stamp=10.06)
    assert roster.faults(np.arange(12), now=1.08) == ["robot r11 lost tracking"]


def test_a_robot_missing_from_frames_is_judged_by_the_frames_it_missed_not_by_their_jitter():
    """A camera at 30 Hz on a loaded machine takes its frames 26-40 ms apart. A robot missing from two frames in a
    row is lost even where they came 55 ms after its last (by the lag alone it would wait for a third: the stop
    came a frame late); one missing from a single frame that came 65 ms after the one before is not."""
    fleet = fleets.from_dict({"robots": ["r0", "r1", "r2", "r3"], "lost_after": 0.15, "lost_behind": 0.06})
    run = np.arange(4)

    def frame(stamp, robots):
        for k in robots:
            roster.pose(k, 0.3 * k - 0.5, 0.0, 0.0, now=stamp + 0.02, stamp=stamp)
        return roster.faults(run, now=stamp + 0.03)

    roster = Roster(fleet)
    for n in range(10):   # the usual interval: 1/30 s
        assert frame(10.0 + n / 30, run) == []
    last = 10.0 + 9 / 30
    assert frame(last + 0.030, [0, 2, 3]) == []                              # r1 missed one frame: forgiven
    assert frame(last + 0.055, [0, 2, 3]) == ["robot r1 lost tracking"]      # two in a row: lost, 55 ms behind
    roster = Roster(fleet)
    for n in range(10):
        frame(10.0 + n / 30, run)
    assert frame(last + 0.065, [0, 2, 3]) == []                              # one late frame missed: forgiven
    assert frame(last + 0.095, run) == []                                    # and seen again
