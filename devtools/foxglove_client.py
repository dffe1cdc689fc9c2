"""A Foxglove WebSocket client for tests, as Foxglove itself connects: the SDK's subprotocol
`foxglove.sdk.v1` (the Foxglove WebSocket protocol), the `websockets` package's threaded client.

The server sends `serverInfo` and `advertise` (JSON: each channel's id, topic, encoding and
schema); the client sends `subscribe` with ids of its own; each message then arrives as a binary
frame: opcode 0x01, the subscription id (uint32 LE), the log time (uint64 LE, ns), the payload.

Protobuf channels (the SDK's typed channels: foxglove.SceneUpdate, foxglove.Grid) are decoded
with the schema the server advertised (a FileDescriptorSet, base64), by a small reader of the
protobuf wire format below, into dicts of field name -> value; so what a test reads is what any
Foxglove client would, not what the server meant to send. CDR channels are left as bytes (a test
deserializes them with rclpy).
"""
import base64
import json
import struct
import threading
import time

from websockets.sync.client import connect

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 0x01


# -- the protobuf wire format, driven by a FileDescriptorSet ---------------------------------------

def _varint(data, pos):
    value = shift = 0
    while True:
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        if not byte & 0x80:
            return value, pos
        shift += 7


def _wire(data):
    """(field number, wire type, raw value) of each field of a serialized message, in order."""
    pos = 0
    while pos < len(data):
        key, pos = _varint(data, pos)
        number, kind = key >> 3, key & 7
        if kind == 0:
            value, pos = _varint(data, pos)
        elif kind == 1:
            value, pos = data[pos:pos + 8], pos + 8
        elif kind == 2:
            size, pos = _varint(data, pos)
            value, pos = data[pos:pos + size], pos + size
        elif kind == 5:
            value, pos = data[pos:pos + 4], pos + 4
        else:
            raise ValueError("protobuf wire type %d is not supported" % kind)
        yield number, kind, value


def _signed(value, bits):
    return value - (1 << bits) if value >= 1 << (bits - 1) else value


# FieldDescriptorProto.Type -> how to read one value of it
_FIXED = {1: "<d", 2: "<f", 6: "<Q", 7: "<I", 15: "<i", 16: "<q"}
_VARINT = {3: lambda v: _signed(v, 64), 4: int, 5: lambda v: _signed(v, 64), 8: bool, 13: int, 14: int,
           17: lambda v: (v >> 1) ^ -(v & 1), 18: lambda v: (v >> 1) ^ -(v & 1)}
_STRING, _MESSAGE, _BYTES = 9, 11, 12
_REPEATED = 3


class ProtobufSchema:
    """The message types of a FileDescriptorSet; decode(type name, bytes) -> dict."""

    def __init__(self, descriptor_set):
        self.messages = {}   # full name -> {number: (name, type, repeated, type name)}
        for number, _, file in _wire(descriptor_set):
            if number == 1:
                fields = list(_wire(file))
                package = next((bytes(v).decode() for n, _, v in fields if n == 2), "")
                for n, _, message in fields:
                    if n == 4:
                        self._add(package, message)

    def _add(self, scope, descriptor):
        parts = list(_wire(descriptor))
        name = "%s.%s" % (scope, next(bytes(v).decode() for n, _, v in parts if n == 1))
        fields = {}
        for n, _, value in parts:
            if n == 2:
                f = {k: v for k, _, v in _wire(value)}
                fields[f[3]] = (bytes(f[1]).decode(), f[5], f.get(4) == _REPEATED,
                                bytes(f.get(6, b"")).decode().lstrip("."))
            elif n == 3:
                self._add(name, value)
        self.messages[name] = fields

    def decode(self, type_name, data):
        fields = self.messages[type_name]
        out = {name: [] if repeated else (None if kind == _MESSAGE else b"" if kind == _BYTES else
                                          "" if kind == _STRING else 0)
               for name, kind, repeated, _ in fields.values()}
        for number, wire, value in _wire(bytes(data)):
            if number not in fields:
                continue
            name, kind, repeated, nested = fields[number]
            if kind in _FIXED or kind in _VARINT:
                if wire == 2:   # a packed repeated field
                    values = self._packed(kind, value)
                else:
                    values = [struct.unpack(_FIXED[kind], value)[0] if kind in _FIXED else _VARINT[kind](value)]
            elif kind == _STRING:
                values = [bytes(value).decode()]
            elif kind == _BYTES:
                values = [bytes(value)]
            else:
                values = [self.decode(nested, value)]
            if repeated:
                out[name].extend(values)
            else:
                out[name] = values[-1]
        return out

    @staticmethod
    def _packed(kind, data):
        if kind in _FIXED:
            return [v[0] for v in struct.iter_unpack(_FIXED[kind], bytes(data))]
        values, pos = [], 0
        while pos < len(data):
            value, pos = _varint(data, pos)
            values.append(_VARINT[kind](value))
        return values


# -- the client ---------------------------------------------------------------------------------------------

class FoxgloveClient:
    """Connects to ws://host:port, subscribes to `topics` as soon as they are advertised, and keeps
    every message received on them: messages[topic] = [(log time ns, payload bytes), ...]."""

    def __init__(self, url, topics, timeout=10.0):
        self.socket = connect(url, subprotocols=[SUBPROTOCOL], max_size=None, open_timeout=timeout)
        self.subprotocol = self.socket.subprotocol
        self.wanted = set(topics)
        self.server_info = None
        self.channels = {}        # topic -> advertised channel (JSON)
        self.schemas = {}         # topic -> ProtobufSchema
        self.messages = {topic: [] for topic in topics}
        self._subscriptions = {}  # subscription id -> topic
        self._lock = threading.Condition()
        self._closing = False
        self.error = None
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self):
        try:
            while not self._closing:
                try:
                    frame = self.socket.recv(timeout=0.2)
                except TimeoutError:
                    continue
                if isinstance(frame, str):
                    self._control(json.loads(frame))
                elif frame and frame[0] == MESSAGE_DATA:
                    subscription, log_time = struct.unpack_from("<IQ", frame, 1)
                    with self._lock:
                        self.messages[self._subscriptions[subscription]].append((log_time, frame[13:]))
                        self._lock.notify_all()
        except Exception as error:   # noqa: BLE001 - kept for the test to report
            if not self._closing:
                self.error = error
            with self._lock:
                self._lock.notify_all()

    def _control(self, message):
        if message["op"] == "serverInfo":
            self.server_info = message
        elif message["op"] == "advertise":
            new = []
            for channel in message["channels"]:
                if channel["topic"] in self.wanted and channel["topic"] not in self.channels:
                    self.channels[channel["topic"]] = channel
                    if channel.get("schemaEncoding") == "protobuf":
                        self.schemas[channel["topic"]] = ProtobufSchema(base64.b64decode(channel["schema"]))
                    subscription = len(self._subscriptions) + 1
                    self._subscriptions[subscription] = channel["topic"]
                    new.append({"id": subscription, "channelId": channel["id"]})
            if new:
                self.socket.send(json.dumps({"op": "subscribe", "subscriptions": new}))

    def decode(self, topic, payload):
        """A protobuf channel's message as a dict (by its advertised schema); other channels' bytes as they are."""
        if topic in self.schemas:
            return self.schemas[topic].decode(self.channels[topic]["schemaName"], payload)
        return payload

    def wait_until(self, predicate, timeout):
        """Until predicate() holds (checked whenever a message arrives); False after `timeout`."""
        deadline = time.monotonic() + timeout
        with self._lock:
            while not predicate():
                if self.error is not None:
                    raise self.error
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._lock.wait(min(remaining, 0.5))
        return True

    def close(self):
        self._closing = True
        self.socket.close()
        self._thread.join(5)
