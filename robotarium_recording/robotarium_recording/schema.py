"""ROS interface schemas as rosbag2 stores them, found without ROS (no rclpy) and without mcap.

A bag keeps, per message type, a `ros2msg` schema: the type's whole concatenated .msg text (its own
.msg, then every nested type once as an 'MSG: pkg/Name' block after a line of '='), and per topic
its RIHS01 type hash and the QoS profiles its publishers offer (metadata version 9: policies
written as names). The .msg and .json files come from the ament share folders (AMENT_PREFIX_PATH),
falling back to this repository's robotarium_msgs. Also here: the leading stamp of a CDR message,
which the recorder takes as a message's publish time.
"""
import json
import os
import re
import struct

SEPARATOR = "=" * 80          # between the concatenated .msg texts of a ros2msg schema

_PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
               "uint32", "int64", "uint64", "string", "wstring"}
_STAMP_FIRST = {"std_msgs/Header", "Header", "std_msgs/msg/Header", "builtin_interfaces/Time",
                "builtin_interfaces/msg/Time"}
_INFINITE = {"sec": 9223372036, "nsec": 854775807}   # RMW_DURATION_INFINITE as rosbag2 writes it


def _repo_root():
    here = os.path.dirname(os.path.abspath(__file__))
    for root in (os.environ.get("ROBOTARIUM_ROOT", ""), os.path.dirname(os.path.dirname(here))):
        if root and os.path.isdir(os.path.join(root, "robotarium_msgs", "msg")):
            return root
    return None


def interface_file(type_name, ext="msg"):
    """Path of `pkg/msg/Name.<ext>` in an ament share folder (AMENT_PREFIX_PATH), falling back to
    this repository's source of robotarium_msgs; None if not found."""
    pkg, _, name = split_type(type_name)
    candidates = [os.path.join(prefix, "share", pkg, "msg", "%s.%s" % (name, ext))
                  for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if prefix]
    root = _repo_root()
    if root:
        candidates.append(os.path.join(root, pkg, "msg", "%s.%s" % (name, ext)))
    return next((c for c in candidates if os.path.isfile(c)), None)


def split_type(type_name):
    """'pkg/msg/Name' or 'pkg/Name' -> (pkg, 'msg', Name)."""
    parts = type_name.split("/")
    if len(parts) == 2:
        return parts[0], "msg", parts[1]
    if len(parts) == 3:
        return tuple(parts)
    raise ValueError("not a message type name: %r" % type_name)


def _fields(text):
    """(type, name) of each field of a .msg text, constants left out."""
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        words = line.split()
        if len(words) < 2 or "=" in words[1] or "=" in words[0]:
            continue
        yield words[0], words[1]


def _base_type(field_type, package):
    """Full 'pkg/msg/Name' of a field's type, or None for a primitive."""
    base = re.sub(r"\[[^\]]*\]$", "", field_type).split("<=")[0]
    if base in _PRIMITIVES:
        return None
    if base == "Header":
        return "std_msgs/msg/Header"
    if "/" in base:
        pkg, _, name = split_type(base)
        return "%s/msg/%s" % (pkg, name)
    return "%s/msg/%s" % (package, base)


def message_definition(type_name):
    """The ros2msg schema text of a type: its .msg text, then every nested type once (depth first)
    as 'MSG: pkg/Name' blocks, the way rosbag2 stores them."""
    blocks, seen = [], set()

    def visit(full, top):
        if full in seen:
            return
        seen.add(full)
        path = interface_file(full)
        if path is None:
            raise FileNotFoundError("no .msg file for %s (is AMENT_PREFIX_PATH set?)" % full)
        with open(path, encoding="utf-8") as f:
            text = f.read()
        pkg, _, name = split_type(full)
        blocks.append(text if top else "%s\nMSG: %s/%s\n%s" % (SEPARATOR, pkg, name, text))
        for field_type, _ in _fields(text):
            nested = _base_type(field_type, pkg)
            if nested:
                visit(nested, False)

    pkg, _, name = split_type(type_name)
    visit("%s/msg/%s" % (pkg, name), True)
    return "\n".join(block.rstrip("\n") for block in blocks) + "\n"


def type_hash(type_name):
    """RIHS01 hash of a type from the .json that rosidl installs beside the .msg, or ''."""
    path = interface_file(type_name, "json")
    if not path:
        return ""
    with open(path, encoding="utf-8") as f:
        hashes = json.load(f).get("type_hashes", [])
    pkg, _, name = split_type(type_name)
    full = "%s/msg/%s" % (pkg, name)
    return next((h["hash_string"] for h in hashes if h.get("type_name") == full), "")


def has_leading_stamp(definition):
    """True when the first field is a std_msgs/Header or a builtin_interfaces/Time, so that the
    CDR bytes 4..12 are its stamp (rcl_interfaces/Log too)."""
    first = next(_fields(definition.split(SEPARATOR)[0]), None)
    return first is not None and first[0] in _STAMP_FIRST


def stamp_from_cdr(data):
    """Nanoseconds of a leading stamp in a CDR message (after the 4-byte encapsulation header), or
    None when the stamp is zero (publisher left it unset) or the data is too short."""
    if len(data) < 12:
        return None
    sec, nanosec = struct.unpack_from("<iI" if data[1] & 1 else ">iI", data, 4)
    if sec == 0 and nanosec == 0:
        return None
    return sec * 1_000_000_000 + nanosec


def qos_profile(history="keep_last", depth=10, reliability="reliable", durability="volatile",
                deadline_ns=None, lifespan_ns=None, liveliness="automatic", lease_ns=None,
                avoid_ros_namespace_conventions=False):
    """One offered QoS profile as rosbag2 (metadata version 9) writes it; None durations = infinite."""
    def duration(ns):
        if ns is None or ns >= 9223372036854775807 or ns < 0:
            return dict(_INFINITE)
        return {"sec": int(ns // 1_000_000_000), "nsec": int(ns % 1_000_000_000)}
    return {"history": history, "depth": int(depth), "reliability": reliability, "durability": durability,
            "deadline": duration(deadline_ns), "lifespan": duration(lifespan_ns), "liveliness": liveliness,
            "liveliness_lease_duration": duration(lease_ns),
            "avoid_ros_namespace_conventions": bool(avoid_ros_namespace_conventions)}
