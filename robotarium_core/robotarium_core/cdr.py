"""The testbed's hot messages as CDR bytes, read and written with numpy: no rclpy, no Python
object per robot.

rclpy makes a Python object per robot of a Twist[] or a PoseArray, which costs more than a step;
a raw subscription and a bytes publish cost microseconds. The bytes are exactly what rclpy would
send (test/test_cdr.py compares them), so any subscriber or bag reader sees ordinary messages.
Each message is a `Layout`; `parse` checks every length before reading anything (a bad array is
a CdrError, never a crash or a large allocation), `build` returns the bytes, and `parse_commands`
checks a command array's token and lengths first, dropping a foreign, oversized or malformed one
with its reason. The wire format and the measurements: docs/architecture.md.
"""
from __future__ import annotations

import struct
from collections import namedtuple
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Iterable, Mapping, Sequence

    from numpy.typing import ArrayLike

ENCAPSULATION = b"\x00\x01\x00\x00"     # plain CDR, little endian


_COUNT = struct.Struct("<I")   # string lengths and sequence counts
MAX_STRING = 4096   # bytes of a string field parse accepts by default (frame_id, token)


FOREIGN, OVERSIZED, MALFORMED = "foreign", "oversized", "malformed"


class CdrError(ValueError):
    """Bytes that are not a valid serialized message of the expected layout; `reason` says why in
    DropCounts' words (MALFORMED, OVERSIZED: a sequence longer than max_elements, FOREIGN)."""

    def __init__(self, text: str, reason: str = MALFORMED) -> None:
        super().__init__(text)
        self.reason = reason


class _Scalar:
    def __init__(self, fmt: str, default: float = 0) -> None:
        self.size = self.align = struct.calcsize(fmt)
        self.fmt = fmt
        self.default = default
        self.struct = struct.Struct("<" + fmt)

    def read(self, reader: _Reader) -> int | float | bool:
        pos = reader.align(self.align)
        reader.need(pos, self.size)
        reader.pos = pos + self.size
        return self.struct.unpack_from(reader.data, pos)[0]

    def write(self, writer: _Writer, value: float) -> None:
        writer.align(self.align)
        writer.put(self.struct.pack(value))


class _String:
    default = ""

    def read(self, reader: _Reader) -> str:
        pos = reader.align(4)
        reader.need(pos, 4)
        length = _COUNT.unpack_from(reader.data, pos)[0]
        if length > reader.max_string:
            raise CdrError("a string of %d bytes at offset %d (at most %d accepted)" % (length, pos, reader.max_string))
        reader.need(pos + 4, length)
        reader.pos = pos + 4 + length
        # The length counts the terminating NUL (some writers send 0 for an empty string).
        return bytes(reader.data[pos + 4:pos + 3 + length]).decode("utf-8", errors="replace") if length else ""

    def write(self, writer: _Writer, value: str) -> None:
        encoded = value.encode("utf-8") + b"\x00"
        writer.align(4)
        writer.put(_COUNT.pack(len(encoded)))
        writer.put(encoded)


def _sequence_count(reader: _Reader, what: str) -> int:
    """A sequence's count field, read; more than reader.max_elements is OVERSIZED, before any element is read."""
    pos = reader.align(4)
    reader.need(pos, 4)
    count = _COUNT.unpack_from(reader.data, pos)[0]
    reader.pos = pos + 4
    if reader.max_elements is not None and count > reader.max_elements:
        raise CdrError("a sequence of %d %s at offset %d (at most %d accepted)" % (count, what, pos, reader.max_elements),
                       OVERSIZED)
    return count


class _StringSequence:
    """A sequence of strings (string[]), as a tuple of str; each string as _String reads it."""

    default = ()

    def read(self, reader: _Reader) -> tuple[str, ...]:
        count = _sequence_count(reader, "strings")
        reader.need(reader.pos, 4 * count)   # each string takes at least its length field: no huge count
        return tuple(STRING.read(reader) for _ in range(count))

    def write(self, writer: _Writer, value: Sequence[str]) -> None:
        writer.align(4)
        writer.put(_COUNT.pack(len(value)))
        for text in value:
            STRING.write(writer, text)


class _Sequence:
    """A sequence of one primitive type, or of structs of `width` float64 members (Twist: 6,
    Pose: 7), as a numpy array (shape (count,) or (count, width))."""

    def __init__(self, dtype: type[np.generic], width: int | None = None) -> None:
        self.dtype = np.dtype(dtype).newbyteorder("<")
        self.width = width
        self.element = self.dtype.itemsize * (width or 1)
        self.align = self.dtype.itemsize
        self.default = np.zeros((0, width) if width else 0, dtype=self.dtype)

    def read(self, reader: _Reader) -> np.ndarray:
        count = _sequence_count(reader, "elements")
        if count == 0:
            return self.default
        start = reader.align(self.align)
        reader.need(start, count * self.element)
        values = np.frombuffer(reader.data, dtype=self.dtype, count=count * (self.width or 1), offset=start)
        reader.pos = start + count * self.element
        return values.reshape(count, self.width) if self.width else values

    def write(self, writer: _Writer, value: ArrayLike) -> None:
        values = np.ascontiguousarray(value, dtype=self.dtype)
        count = values.shape[0] if values.ndim else 0
        if self.width and values.shape[1:] != (self.width,):
            raise ValueError("expected an array of shape (count, %d), got %s" % (self.width, values.shape))
        writer.align(4)
        writer.put(_COUNT.pack(count))
        if count:
            writer.align(self.align)
            writer.put(values.tobytes())


INT32, UINT32, UINT64, FLOAT64 = _Scalar("i"), _Scalar("I"), _Scalar("Q"), _Scalar("d", 0.0)
FLOAT32 = _Scalar("f", 0.0)
BOOL = _Scalar("?", False)
UINT8 = _Scalar("B")
STRING = _String()
HEADER = (("sec", INT32), ("nanosec", UINT32), ("frame_id", STRING))   # std_msgs/Header


class _Reader:
    def __init__(self, data: bytes | bytearray | memoryview, max_elements: int | None, max_string: int) -> None:
        if len(data) < 4:
            raise CdrError("%d bytes: too short for a serialized message" % len(data))
        if data[0] != 0 or data[1] != 1:
            raise CdrError("encapsulation %s is not little-endian plain CDR (00 01)" % bytes(data[:2]).hex())
        self.data = memoryview(data)[4:]
        self.pos = 0
        self.max_elements = max_elements
        self.max_string = max_string

    def align(self, size: int) -> int:
        return self.pos + (-self.pos) % size

    def need(self, pos: int, size: int) -> None:
        if pos + size > len(self.data):
            raise CdrError("truncated: %d bytes needed at offset %d of %d" % (size, pos, len(self.data)))


class _Writer:
    def __init__(self) -> None:
        self.parts = [ENCAPSULATION]
        self.length = 0
        self.padding = []   # (offset, size) of each padding run, counted from the encapsulation header's end

    def align(self, size: int) -> None:
        pad = (-self.length) % size
        if pad:
            self.padding.append((self.length, pad))
            self.put(b"\x00" * pad)

    def put(self, data: bytes) -> None:
        self.parts.append(data)
        self.length += len(data)


def _steps(fields: Sequence[tuple[str, _Scalar | _String | _Sequence]]) -> list[tuple]:
    """A layout's fields as parse and build take them: a string or sequence alone, (name, kind,
    None); a run of consecutive scalars, ([(name, default), ...], None, structs), where structs[k]
    packs the whole run, its alignment padding included, when it starts at an offset of k modulo 8
    (8, the largest alignment, fixes every pad). One struct call instead of a Python call per field:
    most fields are scalars, and parse and build run for every message of every lockstep step."""
    steps, run = [], []

    def end_run() -> None:
        if run:
            structs = []
            for start in range(8):
                fmt, offset = "<", start
                for _, kind in run:
                    pad = (-offset) % kind.align
                    fmt += "%dx%s" % (pad, kind.fmt) if pad else kind.fmt
                    offset += pad + kind.size
                structs.append(struct.Struct(fmt))
            steps.append(([(name, kind.default) for name, kind in run], None, structs))
            run.clear()

    for name, kind in fields:
        if isinstance(kind, _Scalar):
            run.append((name, kind))
        else:
            end_run()
            steps.append((name, kind, None))
    end_run()
    return steps


class Layout:
    """One message type's fields in wire order: parse(bytes) -> namedtuple, build(**fields) -> bytes."""

    def __init__(self, type_name: str, fields: Iterable[tuple[str, _Scalar | _String | _Sequence]]) -> None:
        self.type_name = type_name
        self.fields = tuple(fields)
        self.Message = namedtuple(type_name.rsplit("/", 1)[-1], [name for name, _ in self.fields])
        self._names = frozenset(self.Message._fields)
        self._steps = _steps(self.fields)

    def parse(self, data: bytes | bytearray | memoryview, max_elements: int | None = None, max_string: int = MAX_STRING) -> tuple:
        """The fields of a serialized message (numpy arrays are read-only views of `data`).
        Raises CdrError when the bytes do not hold this layout, or when a sequence is longer
        than max_elements or a string longer than max_string."""
        reader = _Reader(data, max_elements, max_string)
        values = []
        for _, kind, run in self._steps:
            if run is None:
                values.append(kind.read(reader))
            else:   # consecutive scalars: one unpack (_steps)
                packed = run[reader.pos & 7]
                reader.need(reader.pos, packed.size)
                values += packed.unpack_from(reader.data, reader.pos)
                reader.pos += packed.size
        return self.Message(*values)

    def build(self, **values: object) -> bytes:
        """Serialized bytes; fields not given are zero or empty (the bytes of _write, made faster)."""
        unknown = values.keys() - self._names
        if unknown:
            raise TypeError("%s has no field %s" % (self.type_name, ", ".join(sorted(unknown))))
        writer = _Writer()
        for name, kind, run in self._steps:
            if run is None:
                kind.write(writer, values.get(name, kind.default))
            else:   # consecutive scalars: one pack (_steps); `name` is their [(name, default), ...]
                writer.put(run[writer.length & 7].pack(*[values.get(field, default) for field, default in name]))
        return b"".join(writer.parts)

    def _writer(self, values: Mapping[str, object]) -> _Writer:
        writer = _Writer()
        self._write(writer, values)
        return writer

    def _write(self, writer: _Writer, values: Mapping[str, object]) -> None:
        unknown = set(values) - set(self.Message._fields)
        if unknown:
            raise TypeError("%s has no field %s" % (self.type_name, ", ".join(sorted(unknown))))
        for name, kind in self.fields:
            kind.write(writer, values.get(name, kind.default))


_STAMP = struct.Struct("<iI")   # builtin_interfaces/Time: sec, nanosec


def stamp_head(sec: int, nanosec: int) -> bytes:
    """The first bytes of a message that starts with a std_msgs/Header: the encapsulation header and
    the stamp (its frame_id follows: header_tail)."""
    return ENCAPSULATION + _STAMP.pack(sec, nanosec)


def header_tail(frame_id: str, following: bytes = b"", align: int = 1) -> bytes:
    """The bytes of such a message from its frame_id on: the frame_id, the encoded fields that follow
    it (`following`, fields of their own alignment 1), then the padding to `align`, the alignment of
    the next field. For a message sent as stamp_head + header_tail + a fixed-size rest that numpy
    builds (rps2_io's sensor_msgs per robot), the part that never changes is built once."""
    writer = _Writer()
    writer.put(bytes(_STAMP.size))   # the stamp's place: the frame_id is aligned counting it
    _String().write(writer, frame_id)
    writer.put(following)
    writer.align(align)
    return b"".join(writer.parts[2:])   # without the encapsulation header and the stamp


def build_sequence(layout: Layout, elements: Sequence[Mapping[str, object]]) -> bytes:
    """The bytes of a message whose only field is a sequence of `layout` structs (a MarkerArray):
    `elements` is a list of {field: value} dicts."""
    writer = _Writer()
    writer.put(_COUNT.pack(len(elements)))
    for values in elements:
        layout._write(writer, values)
    return b"".join(writer.parts)


TWIST_ARRAY = Layout("robotarium_msgs/msg/TwistArray", HEADER + (
    ("token", STRING),
    ("step", UINT64),
    ("ids", _Sequence(np.uint32)),
    ("twists", _Sequence(np.float64, 6)),     # linear x, y, z, angular x, y, z per robot
    ("requested_exceeds_limits", BOOL),
    ("refreshed", BOOL),
))

ROBOT_POSES = Layout("robotarium_msgs/msg/RobotPoses", HEADER + (
    ("run_id", STRING),
    ("key", STRING),
    ("step", UINT64),
    ("sim_time", FLOAT64),
    ("ids", _Sequence(np.uint32)),
    ("x", _Sequence(np.float64)),
    ("y", _Sequence(np.float64)),
    ("theta", _Sequence(np.float64)),
))

# One per command array the safety node filters: built here, an rclpy message object cost it more
# than the barrier QP at 5 robots (~0.1 ms). The nested DropCounts is flattened to its fields.
SAFETY_REPORT = Layout("robotarium_msgs/msg/SafetyReport", HEADER + (
    ("step", UINT64), ("status", UINT8), ("number_of_robots", UINT32), ("max_change", FLOAT64),
    ("robots_changed", UINT32), ("solve_time", FLOAT64), ("solver_status", STRING),
    ("foreign", UINT64), ("oversized", UINT64), ("malformed", UINT64), ("nonfinite", UINT64),   # dropped (DropCounts)
    ("length_mismatch", UINT64), ("unknown_id", UINT64), ("stale", UINT64),
    ("pose_age", FLOAT64), ("audit", BOOL), ("refreshed", BOOL), ("ideal_change", FLOAT64),
))

POSE_ARRAY = Layout("geometry_msgs/msg/PoseArray", HEADER + (
    ("poses", _Sequence(np.float64, 7)),      # position x, y, z, orientation x, y, z, w per robot
))

# visualization_msgs/Marker, nested structs flattened (pose, scale, color, lifetime, texture, mesh_file);
# a MarkerArray is build_sequence(MARKER, markers).
MARKER = Layout("visualization_msgs/msg/Marker", HEADER + (
    ("ns", STRING), ("id", INT32), ("type", INT32), ("action", INT32),
    ("x", FLOAT64), ("y", FLOAT64), ("z", FLOAT64),                                   # pose.position
    ("qx", FLOAT64), ("qy", FLOAT64), ("qz", FLOAT64), ("qw", _Scalar("d", 1.0)),     # pose.orientation
    ("scale_x", FLOAT64), ("scale_y", FLOAT64), ("scale_z", FLOAT64),
    ("r", FLOAT32), ("g", FLOAT32), ("b", FLOAT32), ("a", FLOAT32),                   # color
    ("lifetime_sec", INT32), ("lifetime_nanosec", UINT32), ("frame_locked", BOOL),
    ("points", _Sequence(np.float64, 3)),                                            # geometry_msgs/Point[]
    ("colors", _Sequence(np.float32, 4)),                                            # std_msgs/ColorRGBA[]
    ("texture_resource", STRING),
    ("texture_sec", INT32), ("texture_nanosec", UINT32), ("texture_frame_id", STRING),
    ("texture_format", STRING), ("texture_data", _Sequence(np.uint8)),               # sensor_msgs/CompressedImage
    ("uv_coordinates", _Sequence(np.float32, 2)),
    ("text", STRING), ("mesh_resource", STRING),
    ("mesh_filename", STRING), ("mesh_data", _Sequence(np.uint8)),                   # visualization_msgs/MeshFile
    ("mesh_use_embedded_materials", BOOL),
))


# The fields of a TestbedStatus up to its step: the simulator publishes one every lockstep step; a
# client acts only on an IDLE status of its own run and the recorder needs only these, so they read
# them and deserialise the whole message (nested DropCounts, strings) only when they need it
# (rclpy's message object costs ~0.1 ms a step). Read with max_string=len(data): an experiment's name
# may be longer than MAX_STRING, and a string cannot take more than the message's bytes anyway.
TESTBED_STATUS_HEAD = Layout("robotarium_msgs/msg/TestbedStatus", HEADER + (
    ("state", UINT8), ("experiment", STRING), ("run_id", STRING), ("started_sec", INT32), ("started_nanosec", UINT32),
    ("safety_rearms", UINT32), ("mode", STRING), ("number_of_robots", UINT32),
    ("step", UINT64),
))

# A whole TestbedStatus (a bag's statuses, read without rosbags: robotarium_recording.bag), its nested DropCounts
# flattened to dropped_cmd_safe_<reason> and dropped_cmd_requested_<reason>.
DROP_COUNTS = ("foreign", "oversized", "malformed", "nonfinite", "length_mismatch", "unknown_id", "stale")
TESTBED_STATUS = Layout("robotarium_msgs/msg/TestbedStatus", TESTBED_STATUS_HEAD.fields + (
    ("sim_time", FLOAT64), ("collisions", UINT64), ("boundary_violations", UINT64),
    ("actuator_limit_iterations", UINT64), ("first_collision_step", UINT64), ("first_boundary_step", UINT64),
    ("command_timeouts", UINT64), ("commands_accepted", UINT64),
    *(("dropped_cmd_safe_" + reason, UINT64) for reason in DROP_COUNTS),
    *(("dropped_cmd_requested_" + reason, UINT64) for reason in DROP_COUNTS),
    ("safety_interventions", UINT64), ("ideal_interventions", UINT64),
    ("poses_key_sha256", STRING), ("safety_key_sha256", STRING), ("end_reason", STRING),
    ("outcome", UINT8), ("outcome_detail", STRING), ("stale_pose_stops", UINT64), ("hardware", BOOL),
    ("hardware_seed", UINT32), ("holder", STRING), ("waiting", _StringSequence()), ("audit", BOOL),
    ("intervention_max_change", FLOAT64), ("intervention_change_sum", FLOAT64),
))

STRING_MESSAGE = Layout("std_msgs/msg/String", (("data", STRING),))

# The fields of a TwistArray up to its token: read first, so a foreign array costs no more.
_TWIST_ARRAY_HEAD = Layout("robotarium_msgs/msg/TwistArray", HEADER + (("token", STRING),))

# A command array's and a safety report's fields up to their step: the recorder reads which step each is for
# (a lockstep run's bag is whole once it holds those of the run's last step).
TWIST_ARRAY_STEP = Layout("robotarium_msgs/msg/TwistArray", HEADER + (("token", STRING), ("step", UINT64)))
SAFETY_REPORT_STEP = Layout("robotarium_msgs/msg/SafetyReport", HEADER + (("step", UINT64),))
SENSOR_READINGS_STEP = Layout("robotarium_msgs/msg/SensorReadings", HEADER + (("run_id", STRING), ("step", UINT64)))

# A parsed command array: ids, v (linear.x) and omega (angular.z) as numpy arrays.
Commands = namedtuple("Commands", "token step ids v omega requested_exceeds_limits sec nanosec refreshed",
                      defaults=(False,))


def max_twist_array_bytes(max_robots: int) -> int:
    """The most bytes a serialized TwistArray of at most `max_robots` robots can take: the
    encapsulation, the header with a frame_id of MAX_STRING bytes, a token of as many, the step,
    max_robots ids and twists, the two flags, and every alignment pad (at most 7 bytes each)."""
    return 4 + 8 + 2 * (4 + MAX_STRING) + 8 + (4 + 4 * max_robots) + (4 + 48 * max_robots) + 2 + 5 * 7


def parse_commands(data: bytes | bytearray | memoryview, max_robots: int, token: str | None = None) -> Commands:
    """A TwistArray's serialized bytes (a raw=True subscription) -> Commands, or CdrError with its
    reason: OVERSIZED when the bytes are more than an array of `max_robots` robots can take
    (max_twist_array_bytes: from their length alone, before anything is read), or when ids or
    twists hold more than `max_robots` entries, from their count fields alone; FOREIGN when
    `token` (str) is given and the array carries another, before anything after the token is
    read; MALFORMED when the bytes are not a TwistArray. Ids and twists of different lengths,
    unknown ids and NaN are left to robotarium_core.model.check_commands."""
    if len(data) > max_twist_array_bytes(max_robots):
        raise CdrError("%d bytes: more than an array of %d robots can take (%d)"
                       % (len(data), max_robots, max_twist_array_bytes(max_robots)), OVERSIZED)
    if token is not None and _TWIST_ARRAY_HEAD.parse(data).token != token:
        raise CdrError("the array does not carry the running experiment's token", FOREIGN)
    msg = TWIST_ARRAY.parse(data, max_elements=max_robots)
    return Commands(msg.token, msg.step, msg.ids.astype(np.int64), msg.twists[:, 0].astype(float),
                    msg.twists[:, 5].astype(float), bool(msg.requested_exceeds_limits), msg.sec, msg.nanosec,
                    bool(msg.refreshed))


def twists(v: np.ndarray | Sequence[float], w: np.ndarray | Sequence[float]) -> np.ndarray:
    """(count, 6) Twist rows with linear.x = v and angular.z = w."""
    rows = np.zeros((len(v), 6))
    rows[:, 0] = v
    rows[:, 5] = w
    return rows


def planar_poses(x: np.ndarray | Sequence[float], y: np.ndarray | Sequence[float],
                 theta: np.ndarray | Sequence[float]) -> np.ndarray:
    """(count, 7) Pose rows of robots on the floor: position (x, y, 0), heading as a quaternion
    about z (as the simulator's PoseArray always was: z = sin(theta/2), w = cos(theta/2))."""
    rows = np.zeros((len(x), 7))
    rows[:, 0] = x
    rows[:, 1] = y
    rows[:, 5] = np.sin(np.asarray(theta) / 2)
    rows[:, 6] = np.cos(np.asarray(theta) / 2)
    return rows
