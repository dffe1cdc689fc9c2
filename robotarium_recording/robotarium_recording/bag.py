"""Recorded runs: rosbag2 folders with MCAP storage, read without ROS (no rclpy).

A run folder is what `ros2 bag record -s mcap` makes: <run_id>/metadata.yaml (rosbag2 metadata,
version 9, Jazzy) and <run_id>/<run_id>_0.mcap (profile "ros2": one `ros2msg` schema per type,
`cdr` messages, zstd-compressed chunks), written by bag_writer.BagWriter from schema's message
definitions, type hashes and QoS profiles. Reading (Bag) scans the records in file order and stops
cleanly at a torn tail, so a file cut mid-write gives back every complete chunk; `recover_bag()`
rewrites such a file's tail and metadata.yaml so that other readers open it too (like `ros2 bag
reindex`). Our own hot types (poses, command arrays, safety reports, statuses, strings) decode with
robotarium_core.cdr where the bag's schema of the type is today's definition word for word; every other
message, and every message of an older bag, with a rosbags typestore: Jazzy's standard types plus the
schemas stored in the bag itself (so an old bag still decodes after our .msg files change).
"""
import functools
import glob
import hashlib
import io
import json
import os
import struct
from collections import namedtuple
from types import SimpleNamespace

import numpy as np
import yaml
from mcap.data_stream import ReadDataStream
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from robotarium_core import cdr, outcomes
from robotarium_core.config import DEFAULT, SAFE_LOADER, TestbedConfig
from robotarium_recording import schema
from robotarium_recording.bag_writer import (
    MAGIC,
    METADATA_TMP,
    METADATA_VERSION,
    PROVISIONAL_TAIL,
    ROS_DISTRO,
    write_metadata_file,
)

# A bag of up to this many bytes keeps its messages in memory from the scan that opens it, so the
# report, the plot and the video read the file once, not once per topic they need.
KEEP_IN_MEMORY = 64 * 1024 * 1024


# -- reading -----------------------------------------------------------------------------------

@functools.lru_cache(maxsize=64)
def _sha256(text):
    return hashlib.sha256(text.encode()).hexdigest()


# Read with robotarium_core.cdr (numpy over the bytes) rather than a rosbags typestore, which is built from the
# bag's schemas and compiles a reader per type: 0.2 s of every run's results for a 300-step bag (2026-12-01).
FAST_TYPES = {layout.type_name: layout for layout in (cdr.ROBOT_POSES, cdr.TWIST_ARRAY, cdr.SAFETY_REPORT,
                                                      cdr.TESTBED_STATUS, cdr.STRING_MESSAGE)}


@functools.lru_cache(maxsize=None)
def _definition_today(type_name):
    try:
        return schema.message_definition(type_name)
    except (OSError, ValueError):   # no .msg here (no ROS environment): rosbags reads the bag's own schema
        return None


def _vector(row):
    return SimpleNamespace(x=float(row[0]), y=float(row[1]), z=float(row[2]))


def _as_message(fields):
    """A cdr Layout's flat fields (its namedtuple as a dict) in the shape of the decoded message: header.stamp,
    started, nested DropCounts, Twist objects; the rest as they are."""
    if "sec" in fields:
        fields["header"] = SimpleNamespace(stamp=SimpleNamespace(sec=fields.pop("sec"), nanosec=fields.pop("nanosec")),
                                           frame_id=fields.pop("frame_id"))
    if "started_sec" in fields:
        fields["started"] = SimpleNamespace(sec=fields.pop("started_sec"), nanosec=fields.pop("started_nanosec"))
    for nested, prefix in (("dropped_cmd_safe", "dropped_cmd_safe_"), ("dropped_cmd_requested", "dropped_cmd_requested_"),
                           ("dropped", "")):
        if prefix + "stale" in fields:   # (a SafetyReport's DropCounts "dropped" is flattened without a prefix)
            fields[nested] = SimpleNamespace(**{reason: fields.pop(prefix + reason) for reason in cdr.DROP_COUNTS})
    if "twists" in fields:
        fields["twists"] = [SimpleNamespace(linear=_vector(row[:3]), angular=_vector(row[3:])) for row in fields["twists"]]
    return SimpleNamespace(**fields)


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
                    self.metadata = (yaml.load(f, Loader=SAFE_LOADER) or {}).get("rosbag2_bagfile_information")
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
        self._fast = {}   # fast_layout's answer per type, for these schemas
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
                                           (yaml.load(qos[topic], Loader=SAFE_LOADER) if qos[topic] else None) or [])
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
            # rosbags' types take seconds to import: only for a bag whose messages are decoded
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore
            store = get_typestore(Stores.ROS2_JAZZY)
            for name, text in self.schemas.items():
                types = get_types_from_msg(text, name)
                store.register({k: v for k, v in types.items() if k not in store.fielddefs or k == name})
            self._typestore = store
        return self._typestore

    def fast_layout(self, type_name):
        """The robotarium_core.cdr Layout that reads this bag's `type_name` messages (FAST_TYPES), or None: rosbags
        reads them (another type, or one whose schema in the bag is not today's)."""
        fast = self._fast   # once per type: decode() asks for every message
        if type_name not in fast:
            layout = FAST_TYPES.get(type_name)
            fast[type_name] = layout if layout is not None and self.schemas.get(type_name) == _definition_today(
                type_name) else None
        return fast[type_name]

    def decode(self, message):
        layout = self.fast_layout(message.type)
        if layout is not None:
            return _as_message(layout.parse(message.data, max_string=len(message.data))._asdict())
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
                               bool(getattr(msg, "requested_exceeds_limits", False)),
                               bool(getattr(msg, "refreshed", False))))
        return out

    @_once
    def config(self):
        """The TestbedConfig the run was made with (the simulator's `config` topic); the packaged
        default for a bag recorded before the configuration travelled with runs."""
        name = self.topic("config", required=False)
        if name not in self.topics:
            return DEFAULT
        texts = [msg.data for _, msg in self.decoded([name])]
        return TestbedConfig.from_yaml(texts[-1]) if texts else DEFAULT

    def drawings(self):
        """What the script drew on r.axes: the drawing messages (robotarium_recording.drawing), in
        recorded order; [] for a run that drew nothing or a bag recorded before they were kept."""
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
        name = self.topic("experiment", required=False)
        if name not in self.topics:
            return {}
        texts = [msg.data for _, msg in self.decoded([name])]
        return (yaml.load(texts[-1], Loader=SAFE_LOADER) or {}) if texts else {}

    @_once
    def statuses(self):
        """Decoded TestbedStatus messages in recorded order."""
        name = self.topic("status", required=False)
        return [msg for _, msg in self.decoded([name])] if name in self.topics else []


PoseTrack = namedtuple("PoseTrack", "steps sim_time stamp_ns log_ns ids x y theta")
# requested_exceeds_limits: False in bags recorded before the field existed.
Command = namedtuple("Command", "step stamp_ns log_ns ids v omega requested_exceeds_limits refreshed",
                     defaults=(False, False))


def recover_bag(path):
    """Make an unfinished recording (killed recorder) open in every reader, like `ros2 bag reindex`:
    cut the MCAP file after its last complete record, give it a provisional end (no summary),
    rewrite metadata.yaml from what the file really holds, and remove the temporary file a kill
    in the middle of replacing metadata.yaml leaves. Returns the Bag; a no-op if complete.
    Only for a bag no recorder writes any more."""
    bag = Bag(path)
    leftover = os.path.join(bag.path, METADATA_TMP)
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
            if not outcomes.disk_full(error) or last is None or len(cuts[last]) < 2:
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
                f.write(PROVISIONAL_TAIL)
            return
        except OSError as error:
            if not outcomes.disk_full(error) or len(ends) < 2:
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
