"""What the hardware arena knows of its robots, without ROS: the roster (which robots are present and
tracked, their newest pose in the arena frame, their battery), the faults that must stop a run
(a robot that lost tracking or stopped answering), and the testbed model of a run on real robots
(FleetTestbed: the debug report's counters as model.Testbed keeps them, the poses measured).

The arena node (arena_node.py) is the I/O around these: it hands every PoseStamped, odometry and
BatteryState to the Roster as it comes, asks it for faults a hundred times a second, and steps the
FleetTestbed at the testbed's rate.
"""
import dataclasses
import math
import struct

import numpy as np

from robotarium_core import model

SETTLE = 0.005   # s: the poses of one frame of a tracking system (sent together) have all come this long after the first
FRAMES_KEPT = 64   # the tracking system's newest frames (their stamps) the roster counts a robot's missed frames in
# Reasons a pose is dropped (counted per robot, shown by status).
DROPS = ("malformed", "not_finite")


def yaw_from_quaternion(qx, qy, qz, qw):
    """The heading (rotation about z) of a quaternion, as a motion-capture body's yaw."""
    return math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))


_HEADER = struct.Struct("<iII")   # stamp sec, nanosec, frame_id length
_POSE = struct.Struct("<7d")


def parse_pose_stamped(data):
    """(stamp in s, x, y, qx, qy, qz, qw) of a serialized geometry_msgs/PoseStamped (CDR, little
    endian), read from its bytes; ValueError for bytes that are not one."""
    if len(data) < 4 + _HEADER.size or data[1] != 1:   # encapsulation: CDR little endian
        raise ValueError("not a little-endian CDR PoseStamped")
    sec, nanosec, length = _HEADER.unpack_from(data, 4)
    offset = 4 + _HEADER.size + length
    offset = 4 + ((offset - 4 + 7) // 8) * 8          # the pose's doubles align to 8 (from the encapsulation's end)
    if length > 256 or len(data) < offset + _POSE.size:
        raise ValueError("a PoseStamped of %d bytes with a frame id of %d" % (len(data), length))
    x, y, _z, qx, qy, qz, qw = _POSE.unpack_from(data, offset)
    return sec + nanosec * 1e-9, x, y, qx, qy, qz, qw


@dataclasses.dataclass
class RobotState:
    """One robot as the roster sees it now (status shows it)."""
    name: str
    tracked: bool
    answering: bool
    pose_age: float        # s since its newest pose (inf: none yet)
    battery: float         # percentage 0-100 (nan: it publishes none)
    dropped: int           # poses dropped (malformed, NaN)

    @property
    def ready(self):
        return self.tracked and self.answering

    def describe(self):
        what = "ready" if self.ready else ", ".join(
            w for w, bad in (("not tracked%s" % ("" if math.isinf(self.pose_age) else " (no pose for %.1f s)"
                                                 % self.pose_age), not self.tracked),
                             ("not answering", not self.answering)) if bad)
        battery = "" if math.isnan(self.battery) else ", battery %.0f %%" % self.battery
        return "%s %s%s" % (self.name, what, battery)


class Roster:
    """The fleet's robots: newest pose in the arena frame (calibrated), when it came and when the
    robot last answered (monotonic seconds), battery. Indices are the fleet file's order."""

    def __init__(self, fleet):
        self.fleet = fleet
        n = self.size = len(fleet.robots)
        self.poses = np.full((3, n), np.nan)
        self.stamps = np.full(n, np.nan)        # the poses' own stamps (s): latency
        self.frames = {}                        # stamp -> robots seen in that frame, for the newest FRAMES_KEPT
        self.pose_at = np.full(n, -np.inf)      # when each newest pose came
        self.answer_at = np.full(n, -np.inf)
        self.answers = np.array([bool(r.answer_topic) for r in fleet.robots])   # robots that publish a sign of life
        self.battery = np.full(n, np.nan)
        self.dropped = {reason: np.zeros(n, dtype=int) for reason in DROPS}

    def pose(self, i, x, y, theta, now, stamp=np.nan):
        """A pose of robot i in the tracking frame; False (dropped, counted) when not finite."""
        if not all(map(math.isfinite, (x, y, theta))):
            self.dropped["not_finite"][i] += 1
            return False
        ax, ay, at = self.fleet.calibration.to_arena(x, y, theta)
        self.poses[:, i] = (ax, ay, at)
        self.pose_at[i], self.stamps[i] = now, stamp
        if stamp > 0:   # (a source that stamps nothing has no frames)
            self.frames[stamp] = self.frames.get(stamp, 0) + 1
            if len(self.frames) > FRAMES_KEPT:
                del self.frames[min(self.frames)]
        return True

    def pose_message(self, i, data, now):
        """A serialized PoseStamped of robot i (parse_pose_stamped); False when dropped."""
        try:
            stamp, x, y, qx, qy, qz, qw = parse_pose_stamped(data)
        except (ValueError, struct.error):
            self.dropped["malformed"][i] += 1
            return False
        if not all(map(math.isfinite, (qx, qy, qz, qw))) or (qx * qx + qy * qy + qz * qz + qw * qw) < 1e-12:
            self.dropped["not_finite"][i] += 1
            return False
        return self.pose(i, x, y, yaw_from_quaternion(qx, qy, qz, qw), now, stamp)

    def answer(self, i, now):
        self.answer_at[i] = now

    def battery_state(self, i, percentage):
        """sensor_msgs/BatteryState.percentage (0-1, NaN unknown) of robot i."""
        if math.isfinite(percentage):
            self.battery[i] = 100.0 * percentage

    def tracked(self, now):
        """Robots with a pose that came within lost_after, and not missing from the fleet's newest frames for
        longer than lost_behind: a tracking system that stopped loses every robot after lost_after, a robot
        missing from frames that show the others after lost_behind, and a stall of this process (all poses late
        alike, stamps as they were) none."""
        fresh = now - self.pose_at <= self.fleet.lost_after
        stamped = np.isfinite(self.stamps) & (self.stamps > 0)   # (a source that stamps nothing is judged by age only)
        # The fleet's newest frame: the newest that half the robots have, by the poses that came SETTLE ago or more.
        # A frame's poses come one by one (a dozen of them take a while on a loaded machine), and a robot whose pose
        # of a frame is still on its way is not behind; a robot missing from frames that the others are in is.
        settled = stamped & (now - self.pose_at >= SETTLE)
        if not settled.any():
            return fresh
        count = np.count_nonzero(settled)
        newest = np.sort(self.stamps[settled])[count // 2]
        return fresh & ~self._behind(stamped, newest, count - count // 2)

    def _behind(self, stamped, newest, quorum):
        """Robots missing from the fleet's frames up to `newest` (frames that `quorum` robots are in) for longer
        than lost_behind, counted in frames at the frames' usual interval: a camera's frames come 26-40 ms apart
        on a loaded machine, so by their stamps alone a robot missing from two frames in a row at 30 Hz lagged
        58 ms (not lost at 60: the stop came a frame later, 0.217 s against the 0.2 s budget) and one missing
        from one late frame 55 ms (lost at 50)."""
        behind = np.zeros(self.size, dtype=bool)
        frames = np.array(sorted(stamp for stamp, seen in self.frames.items() if seen >= quorum and stamp <= newest))
        if len(frames) < 3:   # no usual interval yet: by the stamps' lag
            behind[stamped] = newest - self.stamps[stamped] > self.fleet.lost_behind
            return behind
        interval = np.median(np.diff(frames[-16:]))
        missed = len(frames) - np.searchsorted(frames, self.stamps[stamped], side="right")
        behind[stamped] = missed * interval > self.fleet.lost_behind
        return behind

    def answering(self, now):
        return ~self.answers | (now - self.answer_at <= self.fleet.answer_timeout)

    def ready(self, now):
        return self.tracked(now) & self.answering(now)

    def states(self, now):
        tracked, answering = self.tracked(now), self.answering(now)
        dropped = sum(self.dropped.values())
        return [RobotState(r.name, bool(tracked[i]), bool(answering[i]), float(now - self.pose_at[i]),
                           float(self.battery[i]), int(dropped[i])) for i, r in enumerate(self.fleet.robots)]

    def pick(self, number, now):
        """The fleet indices of the first `number` robots present and tracked; RobotariumError naming
        the robots when fewer are."""
        ready = np.flatnonzero(self.ready(now))
        if len(ready) >= number:
            return ready[:number]
        states = self.states(now)
        missing = [s.describe() for s in states if not s.ready]
        raise model.RobotariumError(
            "the experiment asks for %d robots, but only %d of fleet %s %s present and tracked (%s); not ready: %s. "
            "Switch the robots on and in view of the tracking, or ask for fewer." % (
                number, len(ready), self.fleet.name, "is" if len(ready) == 1 else "are",
                ", ".join(states[i].name for i in ready) or "none", "; ".join(missing)))

    def in_the_way(self, indices, now, arena):
        """Robots present and tracked that stand inside the arena but are not among `indices` (the run's):
        the safety layer knows nothing of them, so the run's robots could drive into them. RobotariumError
        naming them, or None."""
        inside = ~model.outside_arena(self.poses, arena) & self.tracked(now)
        inside[indices] = False
        if inside.any():
            names = [self.fleet.robots[i].name for i in np.flatnonzero(inside)]
            raise model.RobotariumError(
                "robot(s) %s of fleet %s stand in the arena but are not in this experiment of %d robots: the safety "
                "layer does not know of them, so the experiment's robots could drive into them. Park them outside "
                "the arena (or out of the tracking's view), or run an experiment with all of them." % (
                    ", ".join(names), self.fleet.name, len(indices)))

    def faults(self, indices, now):
        """Why robots `indices` cannot go on, one phrase per robot naming all it found ("robot r3 lost
        tracking", "robot r1 stopped answering", "robot r2 lost tracking and stopped answering": a stalled
        machine can delay both at once, and naming one would hide the other), in fleet order; [] when they
        all can."""
        tracked, answering = self.tracked(now)[indices], self.answering(now)[indices]
        faults = []
        for k, i in enumerate(indices):
            what = [w for w, bad in (("lost tracking", not tracked[k]), ("stopped answering", not answering[k])) if bad]
            if what:
                faults.append("robot %s %s" % (self.fleet.robots[i].name, " and ".join(what)))
        return faults

    def measured(self, indices):
        """3 x len(indices): the newest arena poses of those robots."""
        return self.poses[:, indices].copy()


class FleetTestbed(model.Testbed):
    """A run on real robots: commands and the debug report's counters exactly as model.Testbed keeps
    them (judged on the measured poses, as the real Robotarium can only judge those), the poses from
    `measure()` (the roster's newest) instead of an integration. robots: the fleet indices of the
    run's robots 0..N-1."""

    def __init__(self, poses, config, robots, measure, latency=0.0):
        super().__init__(poses, config)
        self.robots = np.asarray(robots, dtype=int)
        self.measure = measure
        # s beyond the certificate's one step (ArmSafety.latency): the fleet's declared tracking + command latency
        self.latency = float(latency)

    def _move(self):
        self.poses = self.measure()

    def commands_out(self):
        """2 x N: the (v, omega) each robot is to drive now, thresholded to the GTernal's limits along
        its arc, as the simulator applies them."""
        return model.threshold_keeping_arc(self.velocities, **self.limits)
