"""The fleet file: which robots a hardware arena moves, the topics each one offers, how they are
tracked and the calibration from the tracking system's frame to the arena's. Plain Python.

Every default of the file is written once, here (the dataclasses' defaults; the declared latencies
default to the testbed configuration's hardware-like numbers). `load(path)` reads and checks a file;
a bad one raises FleetError naming the field ("robots[2].cmd_type must be Twist or TwistStamped").
`Fleet.to_yaml()` writes one (./robotarium fleet writes the file of the fleet it serves).
The file, field by field: docs/own-robots.md#the-fleet-file.
"""
import dataclasses
import math
import re

import numpy as np
import yaml

from robotarium_core.config import DEFAULT

TRACKING = ("mocap", "camera")
COMMAND_TYPES = ("Twist", "TwistStamped")
NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")
TOPIC = re.compile(r"/?[A-Za-z~{][A-Za-z0-9_/{}~]*")
TAG_IDS = 50   # DICT_4X4_50


class FleetError(ValueError):
    """A fleet file that is missing, unreadable, or has a bad field (named in the message)."""


@dataclasses.dataclass(frozen=True)
class Calibration:
    """From the tracking system's frame to the arena's (a rigid motion of the floor, with a scale for
    a system in other units): arena = scale * R(yaw) * tracked + (x, y); heading + yaw. The mocap
    stand-in publishes in a frame of its own to prove it; a tag tracker publishes in the arena's
    frame already (its four corner tags define it), so its fleet's calibration is the identity."""
    x: float = 0.0       # m: the tracking frame's origin, in the arena frame
    y: float = 0.0
    yaw: float = 0.0     # rad: the tracking frame's x axis, from the arena's x axis
    scale: float = 1.0   # arena metres per tracking unit

    def to_arena(self, x, y, theta):
        """Arena poses (x, y, theta arrays) of poses in the tracking frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return (self.x + self.scale * (c * x - s * y), self.y + self.scale * (s * x + c * y),
                np.arctan2(np.sin(np.asarray(theta) + self.yaw), np.cos(np.asarray(theta) + self.yaw)))

    def from_arena(self, x, y, theta):
        """The inverse: tracking-frame poses of arena poses (what a tracking system would report)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = (np.asarray(x, dtype=float) - self.x) / self.scale, (np.asarray(y, dtype=float) - self.y) / self.scale
        return (c * dx + s * dy, -s * dx + c * dy,
                np.arctan2(np.sin(np.asarray(theta) - self.yaw), np.cos(np.asarray(theta) - self.yaw)))


@dataclasses.dataclass(frozen=True)
class Camera:
    """The overhead camera and its tags (tracking: camera)."""
    image_topic: str = "/camera/image_raw"   # sensor_msgs/Image, mono8 or bgr8
    corner_tags: tuple = (0, 1, 2, 3)        # ArUco ids at the arena's corners (x_min, y_min), (x_max, y_min),
                                             # (x_max, y_max), (x_min, y_max): their centres define the arena frame
    tag_size: float = 0.075                  # m, the side of a robot's tag (black border included; a white margin of
                                             # a sixth of it around: two robots' tags never touch)
    corner_tag_size: float = 0.12            # m, the side of a corner tag
    pose_prefix: str = "/tag_tracker"        # the tracker publishes each robot's PoseStamped on <prefix>/<robot>/pose


@dataclasses.dataclass(frozen=True)
class Robot:
    """One robot: a ROS 2 node taking cmd_vel, tracked by motion capture or by its tag."""
    name: str
    cmd_topic: str = ""       # default /<name>/cmd_vel
    cmd_type: str = "Twist"   # Twist or TwistStamped (geometry_msgs)
    pose_topic: str = ""      # default /vrpn_mocap/<name>/pose (mocap) or <camera.pose_prefix>/<name>/pose (camera)
    tag: int = -1             # its ArUco id (camera tracking)
    battery_topic: str = ""   # sensor_msgs/BatteryState, if the robot publishes one
    answer_topic: str = ""    # nav_msgs/Odometry it publishes while alive (its odometry): silent for
                              # answer_timeout, it counts as gone; "" for a robot that publishes none


@dataclasses.dataclass(frozen=True)
class Fleet:
    robots: tuple
    name: str = "fleet"
    tracking: str = "mocap"
    lost_after: float = 0.06       # s without a pose before a robot counts as not tracked: 7 frames of a
                                   # 120 Hz motion capture (a camera's fleet: 0.15, 4.5 frames at 30 Hz)
    lost_behind: float = 0.05      # s a robot may be missing from frames the others are in, counted in frames
                                   # at their usual interval: at 30 Hz 2 frames in a row (1 is forgiven)
    answer_timeout: float = 0.1    # s: 5 messages of a 50 Hz odometry
    drive_on_position_error: float = 0.03   # m: the drive-on phase ends when every robot is this close to its
    drive_on_rotation_error: float = 0.05   # rad ... and its heading this close: tighter than the simulator's 2.x
                                            # drive-on (5 cm, 0.2 rad), so the experiment starts where the script says
    command_latency: float = DEFAULT.command_latency    # s, declared: the arena to the wheels
    tracking_latency: float = DEFAULT.tracking_latency  # s, declared: the robots to a pose
    calibration: Calibration = Calibration()
    camera: Camera = Camera()

    @property
    def names(self):
        return [r.name for r in self.robots]

    def pose_topic(self, robot):
        if robot.pose_topic:
            return robot.pose_topic
        if self.tracking == "camera":
            return "%s/%s/pose" % (self.camera.pose_prefix.rstrip("/"), robot.name)
        return "/vrpn_mocap/%s/pose" % robot.name

    def cmd_topic(self, robot):
        return robot.cmd_topic or "/%s/cmd_vel" % robot.name

    def to_dict(self):
        document = dataclasses.asdict(self)
        document["robots"] = [{k: v for k, v in dataclasses.asdict(r).items()
                               if k == "name" or v != getattr(Robot("x"), k)} for r in self.robots]
        document["camera"]["corner_tags"] = list(self.camera.corner_tags)
        return document

    def to_yaml(self):
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


def _number(where, value, low=None, high=None, integer=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FleetError("%s must be a finite number; received %r." % (where, value))
    if integer and value != int(value):
        raise FleetError("%s must be a whole number; received %r." % (where, value))
    if (low is not None and value < low) or (high is not None and value > high):
        raise FleetError("%s must be in [%s, %s]; received %r." % (where, low, high, value))
    return int(value) if integer else float(value)


def _topic(where, value):
    if not isinstance(value, str) or (value and not TOPIC.fullmatch(value)):
        raise FleetError("%s must be a ROS topic name such as /r0/cmd_vel; received %r." % (where, value))
    return value


def _mapping(where, value, cls):
    if not isinstance(value, dict):
        raise FleetError("%s must be a mapping of %s; received %r." % (
            where, ", ".join(f.name for f in dataclasses.fields(cls)), value))
    unknown = sorted(set(value) - {f.name for f in dataclasses.fields(cls)})
    if unknown:
        raise FleetError("%s has unknown field(s) %s; known: %s." % (
            where, ", ".join(map(str, unknown)), ", ".join(f.name for f in dataclasses.fields(cls))))
    return value


def _robot(i, value, tracking):
    where = "robots[%d]" % i
    if isinstance(value, str):
        value = {"name": value}
    value = dict(_mapping(where, value, Robot))
    if "name" not in value:
        raise FleetError("%s has no name." % where)
    if not isinstance(value["name"], str) or not NAME.fullmatch(value["name"]):
        raise FleetError("%s.name must be a letter then letters, digits or '_' (a ROS name); received %r."
                         % (where, value["name"]))
    for field in ("cmd_topic", "pose_topic", "battery_topic", "answer_topic"):
        if field in value:
            value[field] = _topic("%s.%s" % (where, field), value[field])
    if value.get("cmd_type", "Twist") not in COMMAND_TYPES:
        raise FleetError("%s.cmd_type must be Twist or TwistStamped; received %r." % (where, value["cmd_type"]))
    if "tag" in value:
        value["tag"] = _number("%s.tag" % where, value["tag"], -1, TAG_IDS - 1, integer=True)
    if tracking == "camera" and value.get("tag", -1) < 0:
        raise FleetError("%s (%s) needs a tag (its ArUco id, 0-%d) for camera tracking." % (
            where, value["name"], TAG_IDS - 1))
    return Robot(**value)


def from_dict(document):
    """A checked Fleet from a fleet file's mapping; FleetError names the first bad field."""
    document = dict(_mapping("the fleet file", document, Fleet))
    if "robots" not in document or not isinstance(document["robots"], list) or not document["robots"]:
        raise FleetError("the fleet file needs robots: a list of at least one robot (- name: r0).")
    tracking = document.get("tracking", "mocap")
    if tracking not in TRACKING:
        raise FleetError("tracking must be mocap or camera; received %r." % (tracking,))
    if "name" in document and (not isinstance(document["name"], str) or not NAME.fullmatch(document["name"])):
        raise FleetError("name must be a letter then letters, digits or '_'; received %r." % (document["name"],))
    for field in ("drive_on_position_error", "drive_on_rotation_error"):
        if field in document:
            document[field] = _number(field, document[field], 0.005, 1.0)
    for field in ("lost_after", "lost_behind", "answer_timeout", "command_latency", "tracking_latency"):
        if field in document:
            document[field] = _number(field, document[field], 0.0, 10.0)
    if "calibration" in document:
        c = _mapping("calibration", document["calibration"], Calibration)
        document["calibration"] = Calibration(**{k: _number("calibration.%s" % k, v) for k, v in c.items()})
        if document["calibration"].scale <= 0:
            raise FleetError("calibration.scale must be positive; received %r." % document["calibration"].scale)
    camera = dict(_mapping("camera", document.get("camera", {}), Camera))
    if "image_topic" in camera:
        _topic("camera.image_topic", camera["image_topic"])
    if "pose_prefix" in camera:
        _topic("camera.pose_prefix", camera["pose_prefix"])
    if "corner_tags" in camera:
        tags = camera["corner_tags"]
        if not isinstance(tags, list) or len(tags) != 4:
            raise FleetError("camera.corner_tags must be 4 ArUco ids (corners x_min y_min, x_max y_min, x_max y_max, "
                             "x_min y_max); received %r." % (tags,))
        camera["corner_tags"] = tuple(_number("camera.corner_tags", t, 0, TAG_IDS - 1, integer=True) for t in tags)
    for field in ("tag_size", "corner_tag_size"):
        if field in camera:
            camera[field] = _number("camera.%s" % field, camera[field], 0.001, 1.0)
    document["camera"] = Camera(**camera)
    document["robots"] = tuple(_robot(i, r, tracking) for i, r in enumerate(document["robots"]))
    names = [r.name for r in document["robots"]]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise FleetError("robots: each name once; %s appear(s) more than once." % ", ".join(twice))
    tags = [r.tag for r in document["robots"] if r.tag >= 0]
    clash = sorted({t for t in tags if tags.count(t) > 1 or t in document["camera"].corner_tags})
    if tracking == "camera" and clash:
        raise FleetError("robots: tag(s) %s used twice (or also a corner tag %s): each robot needs a tag of its own."
                         % (clash, list(document["camera"].corner_tags)))
    return Fleet(**document)


def load(path):
    """The fleet of a fleet file (YAML); FleetError says what is wrong with it."""
    try:
        with open(path) as f:
            document = yaml.safe_load(f)
    except OSError as error:
        raise FleetError("cannot read the fleet file %s: %s." % (path, error.strerror)) from None
    except yaml.YAMLError as error:
        raise FleetError("the fleet file %s is not YAML: %s" % (path, error)) from None
    try:
        return from_dict(document)
    except FleetError as error:
        raise FleetError("%s: %s" % (path, error)) from None
