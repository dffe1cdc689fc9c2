"""Recorded runs: rosbag2 folders with MCAP storage, written and read without ROS (no rclpy).

A run folder, as `ros2 bag record -s mcap` makes it and `ros2 bag info/play`, rosbags and Foxglove
read it:
    <run_id>/metadata.yaml       rosbag2 metadata, version 9 (Jazzy)
    <run_id>/<run_id>_0.mcap     MCAP, profile "ros2": one `ros2msg` schema per type holding the whole
                                 concatenated .msg text, `cdr` messages, zstd-compressed chunks

Writing (BagWriter) is built to survive a SIGKILL: chunks are closed at least every
`chunk_seconds`, and every flush writes the new chunks *and* a provisional end of file (DataEnd,
a Footer without summary, the closing magic) in one system call, overwritten by the next flush.
So at any moment the file on disk is a complete MCAP file without a summary, which the mcap
library and rosbags open by scanning; metadata.yaml is replaced atomically after each flush.
`close()` writes the real summary (indexes, statistics) and the final metadata.yaml.

Reading (Bag) scans the records in file order and stops cleanly at a torn tail, so even a file cut
in the middle of a write gives back every complete chunk; `recover_bag()` rewrites such a file's
tail and metadata.yaml so that other readers open it too (like `ros2 bag reindex`).
Messages decode with a rosbags typestore: Jazzy's standard types plus the schemas stored in the
bag itself (so an old bag still decodes after our .msg files change).
"""
import errno
import functools
import glob
import hashlib
import os
import re
import struct
import time
from collections import namedtuple

import numpy as np
import yaml
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

ROS_DISTRO = "jazzy"
METADATA_VERSION = 9          # rosbag2 of Jazzy: QoS policies written as names
SEPARATOR = "=" * 80          # between the concatenated .msg texts of a ros2msg schema
MAGIC = b"\x89MCAP0\r\n"
LIBRARY = "robotarium recorder (mcap-python)"

# A DataEnd record (crc 0 = not computed), a Footer with no summary, the magic.
_PROVISIONAL_TAIL = (struct.pack("<BQI", 0x0F, 4, 0) + struct.pack("<BQQQI", 0x02, 20, 0, 0, 0) + MAGIC)

_PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
               "uint32", "int64", "uint64", "string", "wstring"}
_STAMP_FIRST = {"std_msgs/Header", "Header", "std_msgs/msg/Header", "builtin_interfaces/Time",
                "builtin_interfaces/msg/Time"}
_INFINITE = {"sec": 9223372036, "nsec": 854775807}   # RMW_DURATION_INFINITE as rosbag2 writes it
# libyaml's emitter when PyYAML has it: the pure-Python one costs the recorder ~5 % of a core.
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
# A bag of up to this many bytes keeps its messages in memory from the scan that opens it, so the
# report, the plot and the video read the file once, not once per topic they need.
KEEP_IN_MEMORY = 64 * 1024 * 1024


def _repo_root():
    here = os.path.dirname(os.path.abspath(__file__))
    for root in (os.environ.get("ROBOTARIUM_ROOT", ""), os.path.dirname(os.path.dirname(here))):
        if root and os.path.isdir(os.path.join(root, "robotarium_msgs", "msg")):
            return root
    return None


# -- interface definitions ---------------------------------------------------------------------

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
    import json
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


def _dump_qos(profiles):
    return yaml.dump(list(profiles), Dumper=_DUMPER, sort_keys=False, default_flow_style=False).strip() if profiles else ""


# -- writing -----------------------------------------------------------------------------------

class _TailGuardedFile:
    """The output stream of mcap.Writer. Writes are kept in memory; flush() puts them on disk
    followed by a provisional end of file in one pwrite, which the next flush overwrites, so the
    file is always a readable MCAP file (barring a kill inside that one system call)."""

    def __init__(self, path):
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self._pos = 0
        self._pending = bytearray()

    def write(self, data):
        self._pending += data
        return len(data)

    def tell(self):
        return self._pos + len(self._pending)

    def flush(self, tail=True):
        data = bytes(self._pending) + (_PROVISIONAL_TAIL if tail else b"")
        written = 0
        while written < len(data):
            written += os.pwrite(self._fd, data[written:], self._pos + written)
        self._pos += len(self._pending)
        self._pending.clear()

    def close(self):
        self.flush(tail=False)
        os.ftruncate(self._fd, self._pos)   # the last provisional tail may be longer than the summary
        os.close(self._fd)

    def abandon(self):
        """Stop writing (a write failed: a full disk): close the file as it is on disk."""
        self._pending.clear()
        try:
            os.close(self._fd)
        except OSError:
            pass


TopicRecord = namedtuple("TopicRecord", "name type channel_id offered_qos type_hash count")


class BagWriter:
    """A rosbag2 folder with one MCAP file, written so that a killed writer leaves it readable.

    `chunk_seconds`: a chunk is closed and flushed at the latest this long after the previous flush
    (call `maybe_flush()` often, e.g. from a timer, and on every message); `chunk_size` bounds a
    chunk's uncompressed size. `custom_data` goes to metadata.yaml (strings only).
    """

    def __init__(self, path, chunk_seconds=1.0, chunk_size=4 * 1024 * 1024, custom_data=None,
                 compression="zstd"):
        os.makedirs(path)   # raises if it exists: a run is never overwritten
        self.path = os.path.abspath(path)
        self.name = os.path.basename(self.path)
        self.file_name = "%s_0.mcap" % self.name
        self.chunk_seconds = chunk_seconds
        self.custom_data = dict(custom_data or {})
        self.topics = {}
        self.message_count = 0
        self.start_ns = None
        self.end_ns = None
        self.closed = False
        self._schemas = {}
        self._file = _TailGuardedFile(os.path.join(self.path, self.file_name))
        self._writer = Writer(self._file, chunk_size=chunk_size, compression={
            "zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}[compression])
        self._writer.start(profile="ros2", library=LIBRARY)
        self._last_flush = time.monotonic()
        self._dirty = False
        self._file.flush()
        self.write_metadata()

    def add_topic(self, topic, type_name, offered_qos=(), definition=None, hash_string=None):
        """Register a topic (once) with its type's schema and the QoS profiles its publishers offer."""
        if topic in self.topics:
            return self.topics[topic]
        if type_name not in self._schemas:
            text = definition if definition is not None else message_definition(type_name)
            self._schemas[type_name] = self._writer.register_schema(type_name, "ros2msg", text.encode())
        hash_string = type_hash(type_name) if hash_string is None else hash_string
        offered_qos = list(offered_qos)
        channel_metadata = {"offered_qos_profiles": _dump_qos(offered_qos)}
        if hash_string:
            channel_metadata["topic_type_hash"] = hash_string
        channel_id = self._writer.register_channel(topic, "cdr", self._schemas[type_name], channel_metadata)
        record = TopicRecord(topic, type_name, channel_id, offered_qos, hash_string, [0])
        self.topics[topic] = record
        return record

    def write(self, topic, data, log_time, publish_time=None):
        """Write one serialized message of a registered topic (times in ns since the epoch)."""
        record = self.topics[topic]
        self._writer.add_message(record.channel_id, log_time=int(log_time), data=bytes(data),
                                 publish_time=int(log_time if publish_time is None else publish_time),
                                 sequence=record.count[0])
        record.count[0] += 1
        self.message_count += 1
        self.start_ns = log_time if self.start_ns is None else min(self.start_ns, log_time)
        self.end_ns = log_time if self.end_ns is None else max(self.end_ns, log_time)
        self._dirty = True

    def maybe_flush(self, now=None):
        if self._dirty and (now or time.monotonic()) - self._last_flush >= self.chunk_seconds:
            self.flush()

    def flush(self):
        """Close the chunk in progress, put it on disk with a provisional end, refresh metadata.yaml."""
        self._writer.flush()
        self._file.flush()
        self._last_flush = time.monotonic()
        self._dirty = False
        self.write_metadata()

    def close(self):
        if self.closed:
            return
        self.closed = True
        self._writer.flush()
        self.custom_data["complete"] = "true"
        self._writer.add_metadata("rosbag2", {"serialized_metadata": yaml.dump(
            self.metadata()["rosbag2_bagfile_information"], Dumper=_DUMPER, sort_keys=False), "ROS_DISTRO": ROS_DISTRO})
        self._writer.finish()
        self._file.close()
        self.write_metadata()

    def abandon(self):
        """After a write failed (a full disk): write nothing more. What is on disk stays readable up
        to its last complete chunk; recover_bag() makes the file and metadata.yaml agree."""
        self.closed = True
        self._file.abandon()

    def metadata(self):
        start = self.start_ns or 0
        duration = (self.end_ns - self.start_ns) if self.start_ns is not None else 0
        custom = dict(self.custom_data)
        custom.setdefault("complete", "false")
        return {"rosbag2_bagfile_information": {
            "version": METADATA_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": int(duration)},
            "starting_time": {"nanoseconds_since_epoch": int(start)},
            "message_count": self.message_count,
            "topics_with_message_count": [
                {"topic_metadata": {"name": t.name, "type": t.type, "serialization_format": "cdr",
                                    "offered_qos_profiles": list(t.offered_qos),
                                    "type_description_hash": t.type_hash},
                 "message_count": t.count[0]} for t in self.topics.values()],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [self.file_name],
            "files": [{"path": self.file_name, "starting_time": {"nanoseconds_since_epoch": int(start)},
                       "duration": {"nanoseconds": int(duration)}, "message_count": self.message_count}],
            "custom_data": custom,
            "ros_distro": ROS_DISTRO,
        }}

    def write_metadata(self):
        write_metadata_file(self.path, self.metadata())


def write_metadata_file(bag_dir, metadata):
    """Replace metadata.yaml atomically (a reader never sees half of it)."""
    tmp = os.path.join(bag_dir, ".metadata.yaml.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            yaml.dump(metadata, f, Dumper=_DUMPER, sort_keys=False, default_flow_style=False)
        os.replace(tmp, os.path.join(bag_dir, "metadata.yaml"))
    except OSError:
        if os.path.exists(tmp):   # a full disk: the old metadata.yaml stays, no half-written copy beside it
            os.remove(tmp)
        raise


# -- reading -----------------------------------------------------------------------------------

@functools.lru_cache(maxsize=64)
def _sha256(text):
    return hashlib.sha256(text.encode()).hexdigest()


BagMessage = namedtuple("BagMessage", "topic type log_time publish_time data")
TopicInfo = namedtuple("TopicInfo", "type count offered_qos")


def _once(method):
    """A Bag method that reads the same whatever the call: computed once per Bag (a copy of a list)."""
    def once(self):
        memo = self.__dict__.setdefault("_memo", {})
        if method.__name__ not in memo:
            memo[method.__name__] = method(self)
        value = memo[method.__name__]
        return list(value) if isinstance(value, list) else value
    once.__name__, once.__doc__ = method.__name__, method.__doc__
    return once


class Bag:
    """A recorded run (a rosbag2 folder, its metadata.yaml or an .mcap file), read record by record.

    bag.topics: {topic: TopicInfo(type, count, offered_qos)} from a scan of the file(s);
    bag.complete: False when a file has no summary (recording killed, or still going);
    bag.truncated: True when a file ends in a torn record (everything before it is still read);
    bag.namespace: the testbed namespace ('/robotarium'), from the status topic's name.
    """

    def __init__(self, path):
        path = os.path.abspath(path)
        if os.path.isfile(path) and path.endswith(".yaml"):
            path = os.path.dirname(path)
        self.metadata = None
        if os.path.isdir(path):
            self.path = path
            meta = os.path.join(path, "metadata.yaml")
            if os.path.isfile(meta):
                with open(meta, encoding="utf-8") as f:
                    self.metadata = (yaml.load(f, Loader=_LOADER) or {}).get("rosbag2_bagfile_information")
            names = (self.metadata or {}).get("relative_file_paths") or []
            files = [os.path.join(path, os.path.basename(n)) for n in names]
            files = [f for f in files if os.path.isfile(f)] or sorted(glob.glob(os.path.join(path, "*.mcap")))
        elif os.path.isfile(path):
            self.path, files = os.path.dirname(path), [path]
        else:
            raise FileNotFoundError("no bag at %s" % path)
        if not files:
            raise FileNotFoundError("no .mcap file in %s" % path)
        self.files = files
        self.name = os.path.basename(self.path)
        self._typestore = None
        self._scan()

    def _records(self, path):
        """The MCAP records of one file in file order (chunks opened); stops quietly at a torn tail."""
        with open(path, "rb") as f:
            reader = StreamReader(f, record_size_limit=None)
            try:
                for record in reader.records:
                    yield record
            except Exception:   # a record cut short (or garbage after it): keep what came before
                self.truncated = True

    def _scan(self):
        self.truncated = False
        self.complete = True
        self.schemas = {}
        self.topics = {}
        self.start_ns, self.end_ns = None, None
        counts, types, qos = {}, {}, {}
        kept = [] if sum(os.path.getsize(f) for f in self.files) <= KEEP_IN_MEMORY else None
        for path in self.files:
            schema_names, channels, footer = {}, {}, None
            for record in self._records(path):
                if isinstance(record, Message):
                    topic = channels[record.channel_id]
                    counts[topic] += 1
                    if kept is not None:
                        kept.append(BagMessage(topic, types[topic], record.log_time, record.publish_time, record.data))
                    t = record.log_time
                    self.start_ns = t if self.start_ns is None else min(self.start_ns, t)
                    self.end_ns = t if self.end_ns is None else max(self.end_ns, t)
                elif isinstance(record, Schema):
                    schema_names[record.id] = record.name
                    self.schemas[record.name] = record.data.decode()
                elif isinstance(record, Channel):
                    channels[record.id] = record.topic
                    types.setdefault(record.topic, schema_names.get(record.schema_id, ""))
                    qos.setdefault(record.topic, record.metadata.get("offered_qos_profiles", ""))
                    counts.setdefault(record.topic, 0)
                elif isinstance(record, Footer):
                    footer = record
            if footer is None or footer.summary_start == 0:
                self.complete = False
        for topic, count in counts.items():
            self.topics[topic] = TopicInfo(types[topic], count,
                                           (yaml.load(qos[topic], Loader=_LOADER) if qos[topic] else None) or [])
        self._kept = kept
        status = [t for t, info in self.topics.items() if info.type == "robotarium_msgs/msg/TestbedStatus"]
        self.namespace = status[0].rsplit("/", 1)[0] if status else "/robotarium"

    @property
    def message_count(self):
        return sum(info.count for info in self.topics.values())

    @property
    def duration_ns(self):
        return 0 if self.start_ns is None else self.end_ns - self.start_ns

    def topic(self, suffix, required=True):
        """Full name of the bag's topic `suffix` in the testbed namespace ('poses' -> '/robotarium/poses')."""
        name = suffix if suffix.startswith("/") else "%s/%s" % (self.namespace.rstrip("/"), suffix)
        if name not in self.topics and required:
            raise KeyError("the bag %s has no topic %s (it has %s)" % (self.path, name, ", ".join(sorted(self.topics))))
        return name

    def messages(self, topics=None):
        """Every message (BagMessage, raw CDR bytes) in file order, optionally only of `topics`."""
        wanted = None if topics is None else set(topics)
        if self._kept is not None:
            yield from (m for m in self._kept if wanted is None or m.topic in wanted)
            return
        for path in self.files:
            schemas, channels = {}, {}
            for record in self._records(path):
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                elif isinstance(record, Channel):
                    channels[record.id] = (record.topic, schemas.get(record.schema_id, ""))
                elif isinstance(record, Message):
                    topic, type_name = channels[record.channel_id]
                    if wanted is None or topic in wanted:
                        yield BagMessage(topic, type_name, record.log_time, record.publish_time, record.data)

    @property
    def typestore(self):
        """A rosbags typestore with Jazzy's types and every schema stored in this bag."""
        if self._typestore is None:
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore
            store = get_typestore(Stores.ROS2_JAZZY)
            for name, text in self.schemas.items():
                types = get_types_from_msg(text, name)
                store.register({k: v for k, v in types.items() if k not in store.fielddefs or k == name})
            self._typestore = store
        return self._typestore

    def decode(self, message):
        return self.typestore.deserialize_cdr(message.data, message.type)

    def decoded(self, topics=None):
        """(BagMessage, decoded message) pairs in file order."""
        for message in self.messages(topics):
            yield message, self.decode(message)

    # -- the testbed's topics as arrays ----------------------------------------------------------

    def own_keys(self):
        """{topic suffix: SHA-256 of the key} that this run's own poses and cmd_safe arrays carry
        (from the simulator's statuses of the run), so that foreign messages recorded alongside (a
        replay, a stray publisher) are left out of poses() and commands(); {} for a bag recorded
        before the keys existed (nothing is left out then)."""
        if getattr(self, "_own_keys", None) is None:
            run_id = ((self.metadata or {}).get("custom_data") or {}).get("run_id")
            self._own_keys = {}
            for status in self.statuses():
                if status.state == 1 and getattr(status, "safety_key_sha256", "") and status.run_id == (
                        run_id or status.run_id):
                    self._own_keys = {"poses": status.poses_key_sha256, "cmd_safe": status.safety_key_sha256}
                    break
        return self._own_keys

    def _is_own(self, suffix, key):
        wanted = self.own_keys().get(suffix)
        return wanted is None or _sha256(key) == wanted

    @_once
    def poses(self):
        """The run's poses, one row per poses message: PoseTrack(steps, sim_time, stamp_ns, log_ns,
        ids, x, y, theta) with x, y, theta of shape (messages, N). Messages with another set of ids
        than the first are left out (a run has a fixed set of robots), and so are poses without the
        run's key (own_keys)."""
        rows = []
        for message, msg in self.decoded([self.topic("poses")]):
            if not self._is_own("poses", getattr(msg, "key", "")):
                continue
            rows.append((int(msg.step), float(msg.sim_time),
                         msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, message.log_time,
                         np.asarray(msg.ids, dtype=np.int64), np.asarray(msg.x, dtype=float),
                         np.asarray(msg.y, dtype=float), np.asarray(msg.theta, dtype=float)))
        if not rows:
            return PoseTrack(*(np.zeros(0, dtype=np.int64),) * 4, np.zeros(0, dtype=np.int64),
                             *(np.zeros((0, 0)),) * 3)
        ids = rows[0][4]
        rows = [r for r in rows if np.array_equal(r[4], ids)]
        return PoseTrack(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                         np.array([r[2] for r in rows], dtype=np.int64), np.array([r[3] for r in rows], dtype=np.int64),
                         ids, np.stack([r[5] for r in rows]), np.stack([r[6] for r in rows]), np.stack([r[7] for r in rows]))

    def commands(self, suffix="cmd_safe"):
        """Command arrays of a TwistArray topic in recorded order: list of Command(step, stamp_ns,
        log_ns, ids, v, omega) with numpy arrays; on cmd_safe only the run's own (own_keys)."""
        name = self.topic(suffix, required=False)
        if name not in self.topics:
            return []
        out = []
        for message, msg in self.decoded([name]):
            if not self._is_own(suffix, getattr(msg, "token", "")):
                continue   # foreign: the simulator dropped it too
            out.append(Command(int(msg.step), msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
                               message.log_time, np.asarray(msg.ids, dtype=np.int64),
                               np.array([t.linear.x for t in msg.twists], dtype=float),
                               np.array([t.angular.z for t in msg.twists], dtype=float),
                               bool(getattr(msg, "requested_exceeds_limits", False))))
        return out

    @_once
    def config(self):
        """The TestbedConfig the run was made with (the simulator's `config` topic); the packaged
        default for a bag recorded before the configuration travelled with runs."""
        from robotarium_core.config import DEFAULT, TestbedConfig
        name = self.topic("config", required=False)
        if name not in self.topics:
            return DEFAULT
        texts = [msg.data for _, msg in self.decoded([name])]
        return TestbedConfig.from_yaml(texts[-1]) if texts else DEFAULT

    def drawings(self):
        """What the script drew on r.axes: the drawing messages (robotarium_recording.drawing), in
        recorded order; [] for a run that drew nothing or a bag recorded before they were kept."""
        import json
        name = self.topic("drawing", required=False)
        if name not in self.topics:
            return []
        out = []
        for _, msg in self.decoded([name]):
            try:
                out.append(json.loads(msg.data))
            except ValueError:
                continue   # not ours: anything may publish on a topic
        return out

    @_once
    def experiment(self):
        """The experiment's settings (the simulator's `experiment` topic: api, obstacles, drive-on
        goals) as a dict; {} for a bag recorded before they travelled with runs."""
        import yaml
        name = self.topic("experiment", required=False)
        if name not in self.topics:
            return {}
        texts = [msg.data for _, msg in self.decoded([name])]
        return (yaml.load(texts[-1], Loader=_LOADER) or {}) if texts else {}

    @_once
    def statuses(self):
        """Decoded TestbedStatus messages in recorded order."""
        name = self.topic("status", required=False)
        return [msg for _, msg in self.decoded([name])] if name in self.topics else []


PoseTrack = namedtuple("PoseTrack", "steps sim_time stamp_ns log_ns ids x y theta")
# requested_exceeds_limits: False in bags recorded before the field existed.
Command = namedtuple("Command", "step stamp_ns log_ns ids v omega requested_exceeds_limits", defaults=(False,))


def recover_bag(path):
    """Make an unfinished recording (killed recorder) open in every reader, like `ros2 bag reindex`:
    cut the MCAP file after its last complete record, give it a provisional end (no summary),
    rewrite metadata.yaml from what the file really holds, and remove the temporary file a kill
    in the middle of replacing metadata.yaml leaves. Returns the Bag; a no-op if complete.
    Only for a bag no recorder writes any more."""
    bag = Bag(path)
    leftover = os.path.join(bag.path, ".metadata.yaml.tmp")
    if os.path.exists(leftover):
        os.remove(leftover)
    if bag.complete and not bag.truncated:
        return bag
    cuts = {}   # file -> offsets just after each of its complete records, the last one first to try
    for file_path in bag.files:
        with open(file_path, "rb") as f:
            cuts[file_path] = _complete_record_ends(f.read())
        _cut_after_record(file_path, cuts[file_path])
    while True:
        try:
            _write_recovered_metadata(path)
            return Bag(path)
        except OSError as error:
            # On a full disk even metadata.yaml may not fit: give up the last chunk to make room.
            last = bag.files[-1] if bag.files else None
            if error.errno not in (errno.ENOSPC, errno.EDQUOT) or last is None or len(cuts[last]) < 2:
                raise
            cuts[last].pop()
            _cut_after_record(last, cuts[last])


def _cut_after_record(file_path, ends):
    """Cut an MCAP file after the last complete record in `ends` and give it a provisional end. The
    end is written after the cut so a full disk has the cut's space back; if even that does not fit,
    cut one record earlier (`ends` loses what was given up)."""
    while True:
        try:
            with open(file_path, "r+b") as f:
                f.truncate(ends[-1])
                f.seek(ends[-1])
                f.write(_PROVISIONAL_TAIL)
            return
        except OSError as error:
            if error.errno not in (errno.ENOSPC, errno.EDQUOT) or len(ends) < 2:
                raise
            ends.pop()


def _write_recovered_metadata(path):
    """metadata.yaml rewritten from what the (cut) file holds, keeping the recorder's topic metadata."""
    bag = Bag(path)
    metadata = (bag.metadata and {"rosbag2_bagfile_information": dict(bag.metadata)}) or {
        "rosbag2_bagfile_information": {"version": METADATA_VERSION, "storage_identifier": "mcap",
                                        "compression_format": "", "compression_mode": "",
                                        "custom_data": {}, "ros_distro": ROS_DISTRO}}
    info = metadata["rosbag2_bagfile_information"]
    old_topics = {t["topic_metadata"]["name"]: t["topic_metadata"] for t in info.get("topics_with_message_count", [])}
    start, duration = bag.start_ns or 0, bag.duration_ns
    info.update({
        "duration": {"nanoseconds": duration}, "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": bag.message_count,
        "topics_with_message_count": [
            {"topic_metadata": old_topics.get(topic, {"name": topic, "type": t.type, "serialization_format": "cdr",
                                                      "offered_qos_profiles": t.offered_qos,
                                                      "type_description_hash": ""}),
             "message_count": t.count} for topic, t in bag.topics.items()],
        "relative_file_paths": [os.path.basename(f) for f in bag.files],
        "files": [{"path": os.path.basename(f), "starting_time": {"nanoseconds_since_epoch": start},
                   "duration": {"nanoseconds": duration}, "message_count": bag.message_count} for f in bag.files],
    })
    info.setdefault("custom_data", {})
    info["custom_data"] = dict(info["custom_data"] or {}, recovered="true")
    write_metadata_file(bag.path, metadata)
    return Bag(path)


def _complete_record_ends(data):
    """Offsets just after each complete data-section record of an MCAP file's bytes, in order (a
    chunk counts only if it decompresses and its CRC matches); just the magic's end if none is."""
    import io

    from mcap.data_stream import ReadDataStream
    from mcap.stream_reader import breakup_chunk
    pos = len(MAGIC)
    ends = []
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        end = pos + 9 + length
        if end > len(data) or opcode in (0x0F, 0x02) or not 0x01 <= opcode <= 0x0F:
            break
        if opcode == 0x06:
            try:
                breakup_chunk(Chunk.read(ReadDataStream(io.BytesIO(data[pos + 9:end]))), validate_crc=True)
            except Exception:
                break
        pos = end
        ends.append(end)
    return ends or [len(MAGIC)]
