"""Writing a run's bag: a rosbag2 folder with MCAP storage (the layout: robotarium_recording.bag),
without ROS (no rclpy). The schemas, type hashes and QoS profiles it stores come from
robotarium_recording.schema.

Writing (BagWriter) is built to survive a SIGKILL: chunks are closed at least every
`chunk_seconds`, and every flush writes the new chunks *and* a provisional end of file (DataEnd,
a Footer without summary, the closing magic) in one system call, overwritten by the next flush.
So at any moment the file on disk is a complete MCAP file without a summary, which the mcap
library and rosbags open by scanning; metadata.yaml is replaced atomically after each flush.
`close()` writes the real summary (indexes, statistics) and the final metadata.yaml.
"""
import os
import struct
import time
from collections import namedtuple

import yaml
from mcap.writer import CompressionType, Writer

from robotarium_recording.schema import message_definition, type_hash

ROS_DISTRO = "jazzy"
METADATA_VERSION = 9          # rosbag2 of Jazzy: QoS policies written as names
MAGIC = b"\x89MCAP0\r\n"
LIBRARY = "robotarium recorder (mcap-python)"
METADATA_TMP = ".metadata.yaml.tmp"   # the new metadata.yaml before it replaces the old one

# A DataEnd record (crc 0 = not computed), a Footer with no summary, the magic.
PROVISIONAL_TAIL = (struct.pack("<BQI", 0x0F, 4, 0) + struct.pack("<BQQQI", 0x02, 20, 0, 0, 0) + MAGIC)
# libyaml's emitter when PyYAML has it: the pure-Python one costs the recorder ~5 % of a core.
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def _dump_qos(profiles):
    return yaml.dump(list(profiles), Dumper=_DUMPER, sort_keys=False, default_flow_style=False).strip() if profiles else ""


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
        data = bytes(self._pending) + (PROVISIONAL_TAIL if tail else b"")
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
    tmp = os.path.join(bag_dir, METADATA_TMP)
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            yaml.dump(metadata, f, Dumper=_DUMPER, sort_keys=False, default_flow_style=False)
        os.replace(tmp, os.path.join(bag_dir, "metadata.yaml"))
    except OSError:
        if os.path.exists(tmp):   # a full disk: the old metadata.yaml stays, no half-written copy beside it
            os.remove(tmp)
        raise
