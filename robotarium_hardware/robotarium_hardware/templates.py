"""Messages published many times a second with a few numbers changed (a robot's odometry, the
motion capture's poses), serialized once and patched in place: rclpy's message objects cost about
ten times more per message than the bytes, on a 2-core machine that runs a dozen robots."""
import operator
import struct

from rclpy.serialization import serialize_message

_INTS = {"sec": "<i", "nanosec": "<I"}


class Template:
    """The CDR bytes of `msg` with `fields` (dotted paths: "header.stamp.sec", "pose.position.x") to
    fill in by build(*values); the other fields keep the values msg has now."""

    def __init__(self, msg, fields):
        self.fields = []
        for k, path in enumerate(fields):
            *parents, name = path.split(".")
            holder = operator.attrgetter(".".join(parents))(msg) if parents else msg
            fmt = _INTS.get(name, "<d")
            sentinel = 0x7A5A0000 + k if fmt != "<d" else 987654.321 + k
            setattr(holder, name, sentinel)
            self.fields.append((fmt, struct.pack(fmt, sentinel)))
        self.data = bytearray(serialize_message(msg))
        self.offsets = []
        for _, packed in self.fields:
            offset = self.data.find(packed)
            if offset < 0 or self.data.find(packed, offset + 1) >= 0:
                raise ValueError("cannot place a field of %s in its bytes" % type(msg).__name__)
            self.offsets.append(offset)

    def build(self, *values):
        for (fmt, _), offset, value in zip(self.fields, self.offsets, values):
            struct.pack_into(fmt, self.data, offset, value)
        return bytes(self.data)
