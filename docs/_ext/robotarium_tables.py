"""Sphinx extension: the ROS interface's tables, written from the code when the build starts.

- `_generated/topics.md` and `_generated/services.md`: every topic and service name comes from
  robotarium_core/topics.py (and robotarium_sim/rps2_io.py for the per-robot sensor topics) and
  every QoS from the profile the nodes use; the message types and the words are kept here, beside
  the names. A topic name in topics.py that this table does not describe fails the build (a
  warning, and the build runs with -W), so a new topic cannot go undocumented.
- `_generated/parameters.md`: every field of the one testbed configuration
  (robotarium_core/config.py FIELDS), its default from testbed.yaml (config.DEFAULT), its unit and
  meaning, its valid range and which parts read it.

The modules are imported from the source tree, not from install/, so the tables show the code
as it is now. topics.py and rps2_io.py need rclpy and the built robotarium_msgs: build the docs in
the project's environment (./robotarium shell).
"""
import math
import os
import sys

from sphinx.util import logging

LOG = logging.getLogger(__name__)
REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SOURCE_PACKAGES = ("robotarium_core", "robotarium_sim")

# (where the name is: "module:ATTRIBUTE", the message type, [(role, "module:QOS_ATTRIBUTE"), ...], what)
# The QoS is the publisher's unless the role says otherwise; the two command inputs are described by
# their subscriptions, since that is what a sender has to match.
TOPICS = [
    ("topics:CMD_REQUESTED", "robotarium_msgs/msg/TwistArray", [("subscription", "topics:COMMAND_INPUT_QOS")],
     "commands to the safety node; only arrays with the experiment's token count"),
    ("topics:CMD_SAFE", "robotarium_msgs/msg/TwistArray",
     [("subscription", "topics:COMMAND_INPUT_QOS"), ("published", "topics:OUTPUT_QOS")],
     "the safety node's commands to the simulator (with the safety key)"),
    ("topics:POSES", "robotarium_msgs/msg/RobotPoses", [("", "topics:OUTPUT_QOS")],
     "every robot's x, y, θ at each step"),
    ("topics:STATUS", "robotarium_msgs/msg/TestbedStatus", [("", "topics:STATUS_QOS")],
     "step, counters, state, how the last run ended; latched, the newest only: a late joiner gets the state now"),
    ("topics:STATUS_STREAM", "robotarium_msgs/msg/TestbedStatus", [("", "topics:STATUS_STREAM_QOS")],
     "hidden: every status, for the recorder, which records it as `status`"),
    ("topics:SAFETY_REPORT", "robotarium_msgs/msg/SafetyReport", [("", "topics:SAFETY_REPORT_QOS")],
     "what the safety node changed"),
    ("topics:SENSORS", "robotarium_msgs/msg/SensorReadings", [("", "topics:OUTPUT_QOS")],
     "the 2.x API's sensors, each step of a 2.x experiment"),
    ("rps2_io:IMU", "sensor_msgs/msg/Imu", [("", "rps2_io:IMU_QOS")],
     "robot i's accelerometer (m/s², specific force: +9.81 on z at rest), gyroscope (rad/s), fused yaw as a "
     "quaternion, covariances from the noise model; frame `robot_<i>`; at `standard_sensor_rate` Hz of simulated "
     "time (10 Hz; 0: off), 2.x experiments"),
    ("rps2_io:MAG", "sensor_msgs/msg/MagneticField", [("", "rps2_io:MAG_QOS")],
     "robot i's magnetometer in tesla; same rate and stamps"),
    ("rps2_io:RANGE", "sensor_msgs/msg/Range", [("", "rps2_io:RANGE_QOS")],
     "robot i's 7 distance sensors, one message each (frame `robot_<i>/distance_<k>`, 2.x's order), -1 as +inf "
     "(REP 117); same rate and stamps; only with `use_distance_sensors`"),
    ("topics:POSE_ARRAY", "geometry_msgs/msg/PoseArray", [("", "topics:POSE_ARRAY_QOS")],
     "the poses for viewers (only while subscribed)"),
    ("topics:MARKERS", "visualization_msgs/msg/MarkerArray", [("", "topics:VIEWER_QOS")],
     "arena, robots (footprint, heading, id), trails in frame `arena`, at `viewer_rate` (10 Hz; only while "
     "subscribed)"),
    ("topics:OBSTACLES", "visualization_msgs/msg/Marker", [("", "topics:LATCHED")],
     "a 2.x experiment's obstacles"),
    ("topics:DRAWING", "std_msgs/msg/String", [("", "topics:DRAWING_QOS")],
     "what the script drew on `r.axes` (JSON)"),
    ("topics:CONFIG", "std_msgs/msg/String", [("", "topics:LATCHED")],
     "the run's configuration (YAML)"),
    ("topics:EXPERIMENT", "std_msgs/msg/String", [("", "topics:LATCHED")],
     "the run's settings (YAML: api, obstacles, drive-on goals)"),
    ("topics:RECORDING", "std_msgs/msg/String", [("", "topics:LATCHED")],
     "where the run is recorded (recorder to simulator and client)"),
    ("topics:RECORDED_RUNS", "std_msgs/msg/String", [("", "topics:RECORDED_RUNS_QOS")],
     "hidden: the last runs' folders as their recordings opened (JSON: run_id, path), so `./robotarium run` "
     "finds the recording of a script killed before it heard `recording`"),
    ("topics:RECORDING_ERROR", "std_msgs/msg/String", [("", "topics:LATCHED")],
     "a run whose recording stopped (JSON: run_id, path, why, e.g. disk full; recorder to client)"),
]

# (where the name is, the service type, who serves it, what)
SERVICES = [
    ("topics:START_EXPERIMENT", "robotarium_msgs/srv/StartExperiment", "simulator",
     "starts an experiment; returns its token, poses key and the client's presence topic"),
    ("topics:END_EXPERIMENT", "robotarium_msgs/srv/EndExperiment", "simulator",
     "ends it (the token, or `force` for an operator); returns the debug report and the recording"),
    ("topics:SAFETY_ARM", "robotarium_msgs/srv/ArmSafety", "safety node",
     "the simulator tells the safety node which experiment to guard, and its secrets"),
]

# Names in topics.py that are neither a topic nor a service.
NOT_TOPICS = {"DEFAULT_NAMESPACE"}


def _modules():
    for package in SOURCE_PACKAGES:
        path = os.path.join(REPO, package)
        if path not in sys.path:
            sys.path.insert(0, path)
    try:
        from robotarium_core import config, topics
        from robotarium_sim import rps2_io
    except ImportError as error:
        raise RuntimeError("the docs' tables import the project's modules (%s); build the docs in the project's "
                           "environment: ./robotarium shell -c \"sphinx-build -W -b html docs docs/_build/html\""
                           % error) from error
    return {"topics": topics, "rps2_io": rps2_io, "config": config}


def _resolve(modules, where):
    module, attribute = where.split(":")
    return getattr(modules[module], attribute)


def _cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def _topic_name(value):
    return value.replace("%d", "<i>")


def describe_qos(profile):
    """'reliable, transient local, keep last 50' for an rclpy QoSProfile."""
    history = ("keep last %d" % profile.depth if profile.history.name == "KEEP_LAST" else "keep all")
    return "%s, %s, %s" % (profile.reliability.name.lower().replace("_", " "),
                           profile.durability.name.lower().replace("_", " "), history)


def topics_table(modules):
    lines = ["| topic | type | QoS | what |", "|---|---|---|---|"]
    for where, type_name, qos, what in TOPICS:
        name = _topic_name(_resolve(modules, where))
        qos_text = "; ".join(("%s: %s" % (role, describe_qos(_resolve(modules, q))) if role
                              else describe_qos(_resolve(modules, q))) for role, q in qos)
        lines.append("| `%s` | `%s` | %s | %s |" % (name, type_name, _cell(qos_text), _cell(what)))
    return "\n".join(lines) + "\n"


def services_table(modules):
    lines = ["| service | type | served by | what |", "|---|---|---|---|"]
    for where, type_name, server, what in SERVICES:
        lines.append("| `%s` | `%s` | %s | %s |" % (_resolve(modules, where), type_name, server, _cell(what)))
    return "\n".join(lines) + "\n"


def undocumented_names(modules):
    """Names of topics.py's topic and service constants that no table row describes."""
    described = {where.split(":")[1] for where, *_ in TOPICS + SERVICES if where.startswith("topics:")}
    topics = modules["topics"]
    return sorted(name for name, value in vars(topics).items()
                  if name.isupper() and isinstance(value, str) and name not in NOT_TOPICS and name not in described)


def _number(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[%s]" % ", ".join(_number(v) for v in value)
    if isinstance(value, float):
        return "%.10g" % value
    return str(value)


def _bound(value):
    if value == math.inf:
        return "∞"
    if value == -math.inf:
        return "-∞"
    return _number(value)


def valid_range(name, field):
    """What config.py accepts for a field, in words and interval notation."""
    if name == "arena":
        return "x_min < x_max, y_min < y_max"
    if getattr(field, "boolean", False):
        return "true or false"
    if getattr(field, "names", False):
        return "a list of names"
    low, high = getattr(field, "low", -math.inf), getattr(field, "high", math.inf)
    low_open = getattr(field, "low_open", True)
    interval = "%s%s, %s%s" % ("(" if low_open or low == -math.inf else "[", _bound(low), _bound(high),
                               ")" if high == math.inf else "]")
    if getattr(field, "integer", False):
        interval = "whole number in " + interval
    length = getattr(field, "length", 0)
    if length:
        interval = "%d numbers, each in %s" % (length, interval)
    return interval


def parameters_table(modules):
    config = modules["config"]
    lines = ["| parameter | default | what | valid | read by |", "|---|---|---|---|---|"]
    for name, field in config.FIELDS.items():
        used_by = ", ".join(getattr(field, "used_by", ()))
        lines.append("| `%s` | `%s` | %s | %s | %s |" % (name, _number(getattr(config.DEFAULT, name)),
                                                         _cell(field.description), _cell(valid_range(name, field)),
                                                         used_by))
    return "\n".join(lines) + "\n"


def _write(path, text):
    """Write only what changed, so an unchanged table does not rebuild its pages; through a
    temporary file, so a build running beside this one never reads half a table."""
    if os.path.exists(path):
        with open(path) as f:
            if f.read() == text:
                return
    temporary = "%s.%d.tmp" % (path, os.getpid())
    with open(temporary, "w") as f:
        f.write(text)
    os.replace(temporary, path)


def write_tables(app):
    modules = _modules()
    out = os.path.join(app.srcdir, "_generated")
    os.makedirs(out, exist_ok=True)
    header = "<!-- written by docs/_ext/robotarium_tables.py from the code; do not edit -->\n\n"
    _write(os.path.join(out, "topics.md"), header + topics_table(modules))
    _write(os.path.join(out, "services.md"), header + services_table(modules))
    _write(os.path.join(out, "parameters.md"), header + parameters_table(modules))
    for name in undocumented_names(modules):
        LOG.warning("robotarium_core/topics.py names %s, which the docs' topic table does not describe: add it "
                    "to TOPICS, SERVICES or NOT_TOPICS in docs/_ext/robotarium_tables.py", name)


def setup(app):
    app.connect("builder-inited", write_tables)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
