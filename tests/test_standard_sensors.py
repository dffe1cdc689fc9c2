"""The 2.x sensors per robot on standard message types (robotarium_sim.rps2_io.StandardSensors):
robot_<i>/imu (sensor_msgs/Imu), robot_<i>/mag (sensor_msgs/MagneticField), robot_<i>/range
(sensor_msgs/Range, one per distance sensor) at `standard_sensor_rate` Hz of simulated time.

The unit tests check the bytes against rclpy's own deserializer and the conversions against the
2.x readings; the node test runs a 2.x experiment on the real simulator and recorder over DDS and
compares what a subscriber gets, and what the bag holds (read with rosbags), with the
SensorReadings of the same steps.
"""
import math
import os

import numpy as np
import pytest
import yaml
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, MagneticField, Range

from devtools.stack import NS, Stack, rosbags_messages
from robotarium_core import rps2
from robotarium_core.config import DEFAULT
from robotarium_core.sensors import GRAVITY
from robotarium_msgs.msg import SensorReadings
from robotarium_msgs.srv import StartExperiment
from robotarium_sim import rps2_io

OBSTACLES = np.array([[[-0.3, -0.6], [-0.3, 0.6]], [[0.3, -0.6], [0.3, 0.6]]])
POSES = np.array([[-0.8, 0.0, 0.8], [0.0, 0.4, 0.0], [0.0, 1.0, 3.0]])
V, W = np.array([0.1, 0.05, -0.08]), np.array([0.4, -1.0, 0.2])


# -- without ROS's graph: the bytes and the conversions ----------------------------------------------

class FakePublisher:
    def __init__(self, msg_type, topic, qos):
        self.msg_type, self.topic, self.qos = msg_type, topic, qos
        self.sent = []

    def publish(self, data):
        assert isinstance(data, bytes)   # built here, never an rclpy message object
        self.sent.append(deserialize_message(data, self.msg_type))
        self.bytes = data


class FakeNode:
    def __init__(self):
        self.publishers = {}

    def create_publisher(self, msg_type, topic, qos, event_callbacks=None):
        assert event_callbacks is not None and not event_callbacks.use_default_callbacks
        self.publishers[topic] = FakePublisher(msg_type, topic, qos)
        return self.publishers[topic]


def make_testbed(distance_sensors=True, n=3):
    tb = rps2.Testbed2(POSES[:, :n], DEFAULT, obstacles=OBSTACLES, distance_sensors=distance_sensors,
                       rng=np.random.default_rng(4))
    return tb


def step(tb, n=3):
    tb.set_commands(np.arange(n), V[:n], W[:n], now=0.0)
    tb.step()


def same_bytes(ours, theirs):
    """Equal in length and in every byte but a few where ours hold zero: the alignment padding
    (at most 7 bytes in these messages), which rclpy leaves as its buffer held it. The fields
    themselves are compared decoded."""
    if len(ours) != len(theirs):
        return False
    differ = [k for k in range(len(ours)) if ours[k] != theirs[k]]
    return all(ours[k] == 0 for k in differ) and len(differ) < 8


def yaw_quaternion(degrees):
    yaw = math.radians(degrees)
    return [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]


def check_against_readings(imu, mag, ranges, s, i, distance_sensors=True):
    """One robot's standard messages against its 2.x readings (s: the sensor model or a decoded
    SensorReadings reshaped), in SI units and ROS conventions."""
    c = DEFAULT
    assert imu.header.frame_id == mag.header.frame_id == "robot_%d" % i
    q = imu.orientation
    assert np.allclose([q.x, q.y, q.z, q.w], yaw_quaternion(s["orientations"][i]), rtol=0, atol=1e-15)
    assert np.array_equal(imu.orientation_covariance, np.diag([0, 0, math.radians(c.orientation_noise_std) ** 2]).ravel())
    g = imu.angular_velocity
    assert [g.x, g.y, g.z] == list(s["gyros"][:, i])
    assert np.array_equal(imu.angular_velocity_covariance, np.diag(np.square(c.gyro_noise_std)).ravel())
    a = imu.linear_acceleration
    ax, ay, az = s["accelerations"][:, i]
    assert [a.x, a.y] == [ax, ay] and a.z == az + 2 * GRAVITY          # specific force: +9.81 on z at rest
    assert abs(a.z - GRAVITY) < 0.5
    assert np.array_equal(imu.linear_acceleration_covariance, np.diag(np.square(c.accelerometer_noise_std)).ravel())
    m = mag.magnetic_field
    assert np.allclose([m.x, m.y, m.z], s["magnetic_fields"][:, i] * 1e-6, rtol=1e-15, atol=0)   # tesla
    assert abs(m.z - c.magnetometer_z_field * 1e-6) < 30e-6
    assert np.allclose(mag.magnetic_field_covariance, np.diag(np.square(np.array(c.magnetometer_noise_std) * 1e-6)).ravel(),
                       rtol=1e-15, atol=0)
    if not distance_sensors:
        assert ranges == []
        return
    assert [r.header.frame_id for r in ranges] == ["robot_%d/distance_%d" % (i, k) for k in range(7)]
    for k, r in enumerate(ranges):
        d = s["distances"][k, i]
        assert r.header.stamp == imu.header.stamp
        assert r.radiation_type == Range.INFRARED and r.field_of_view == 0.0
        assert r.min_range == 0.0 and r.max_range == np.float32(c.distance_sensor_range)
        if d == -1:
            assert r.range == math.inf and r.variance == 0.0      # REP 117: nothing detected within range
        else:
            assert r.range == np.float32(d) and r.variance == np.float32((c.distance_sensor_error * d) ** 2)


def test_bytes_are_the_messages_rclpy_reads_and_values_are_the_readings_in_si():
    node = FakeNode()
    standard = rps2_io.StandardSensors(node, 10.0)
    tb = make_testbed()
    standard.start(tb)
    assert sorted(node.publishers) == sorted("robot_%d/%s" % (i, kind) for i in range(3) for kind in ("imu", "mag", "range"))
    for _ in range(5):
        step(tb)
    standard.publish(tb, 1234, 567)
    s = tb.sensors
    readings = {name: getattr(s, name) for name in ("orientations", "gyros", "accelerations", "magnetic_fields",
                                                    "distances")}
    assert (readings["distances"] == -1).any() and (readings["distances"] >= 0).any()   # both kinds checked
    for i in range(3):
        imu, = node.publishers["robot_%d/imu" % i].sent
        mag, = node.publishers["robot_%d/mag" % i].sent
        ranges = node.publishers["robot_%d/range" % i].sent
        assert imu.header.stamp.sec == 1234 and imu.header.stamp.nanosec == 567
        check_against_readings(imu, mag, ranges, readings, i)
        # what rclpy would send (its alignment padding is whatever its buffer held; ours is zero)
        for kind, msg in (("imu", imu), ("mag", mag), ("range", ranges[-1])):
            assert same_bytes(node.publishers["robot_%d/%s" % (i, kind)].bytes, serialize_message(msg))
    # robots 10 and up (frame ids of other lengths, other padding) and no distance sensors: no range messages
    node = FakeNode()
    tb = rps2.Testbed2(np.array([np.linspace(-1, 1, 12), np.zeros(12), np.zeros(12)]), DEFAULT)
    standard = rps2_io.StandardSensors(node, 10.0)
    standard.start(tb)
    step(tb, 0)
    standard.publish(tb, 1, 2)
    for i in (9, 10, 11):
        imu, = node.publishers["robot_%d/imu" % i].sent
        mag, = node.publishers["robot_%d/mag" % i].sent
        check_against_readings(imu, mag, node.publishers["robot_%d/range" % i].sent,
                               {name: getattr(tb.sensors, name) for name in readings}, i, distance_sensors=False)
        assert same_bytes(node.publishers["robot_%d/imu" % i].bytes, serialize_message(imu))


def test_publishers_are_made_once_and_kept_and_none_at_rate_zero():
    node = FakeNode()
    standard = rps2_io.StandardSensors(node, 10.0)
    standard.start(make_testbed(n=2))
    first = dict(node.publishers)
    standard.start(make_testbed(n=3))
    assert len(node.publishers) == 9 and all(node.publishers[t] is p for t, p in first.items())
    assert node.publishers["robot_0/range"].qos.depth == 7 * node.publishers["robot_0/imu"].qos.depth
    off = FakeNode()
    rps2_io.StandardSensors(off, 0.0).start(make_testbed())
    assert off.publishers == {}


@pytest.mark.parametrize("rate", [10.0, 4.0, 30.0, 100.0])
def test_throttled_by_simulated_time(rate):
    """The first step at or past each multiple of 1/rate s of simulated time; never step 0 (the
    readings before the first step are 2.x's placeholders); every step when the rate exceeds it."""
    standard = rps2_io.StandardSensors(FakeNode(), rate)
    tb = make_testbed()
    standard.start(tb)
    due = []
    for k in range(301):
        tb.steps = k
        if standard.due(tb):
            due.append(k)
    periods = int(300 * DEFAULT.time_step * rate + 1e-9) if rate * DEFAULT.time_step < 1 else 300
    assert len(due) == periods
    if rate * DEFAULT.time_step < 1:
        assert due == [math.ceil(m / (rate * DEFAULT.time_step) - 1e-9) for m in range(1, periods + 1)]
    else:
        assert due == list(range(1, 301))
    standard.start(make_testbed())           # a new experiment counts from zero again
    tb.steps = 4
    assert standard.due(tb) == (rate * 4 * DEFAULT.time_step >= 1)


# -- the real nodes over DDS, and the bag -------------------------------------------------------------

def as_readings(msg):
    n = msg.number_of_robots
    return {"orientations": np.array(msg.orientations), "gyros": np.array(msg.gyros).reshape(3, n),
            "accelerations": np.array(msg.accelerations).reshape(3, n),
            "magnetic_fields": np.array(msg.magnetic_fields).reshape(3, n),
            "distances": np.array(msg.distances).reshape(7, n)}


def stamp_ns(msg):
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


RATE = 10.0


@pytest.mark.node
def test_a_2x_experiment_publishes_them_at_the_rate_and_they_are_recorded(tmp_path):
    n, steps = 3, 45
    config = tmp_path / "testbed.yaml"     # the rate set here, whatever the packaged default
    config.write_text(yaml.safe_dump({"/**": {"ros__parameters": dict(DEFAULT.to_dict(), standard_sensor_rate=RATE)}}))
    stack = Stack(tmp_path, config_file=config)
    try:
        probe = stack.probe
        readings = probe.collect(SensorReadings, NS + "/sensors")
        got = {(i, kind): probe.collect(cls, "%s/robot_%d/%s" % (NS, i, kind), qos)
               for i in range(n) for kind, cls, qos in (("imu", Imu, rps2_io.IMU_QOS), ("mag", MagneticField, rps2_io.MAG_QOS),
                                                        ("range", Range, rps2_io.RANGE_QOS))}
        request = StartExperiment.Request(name="standard", number_of_robots=n, real_time=False, api=rps2.API,
                                          use_distance_sensors=True, sensor_seed=3,
                                          obstacles=[float(v) for v in OBSTACLES.ravel()])
        request.x, request.y, request.theta = (list(map(float, row)) for row in POSES)
        started = probe.start_experiment(request, NS)
        assert started.success, started.message
        stack.run_id, stack.token = started.run_id, started.token
        assert probe.spin_until(lambda: any(p.step == 0 for p in stack.poses), 10)
        for k in range(1, steps + 1):
            stack.step(k, V, W)
        due = [k for k in range(1, steps + 1) if int(k * DEFAULT.time_step * RATE + 1e-9)
               > int((k - 1) * DEFAULT.time_step * RATE + 1e-9)]
        assert len(due) == 14 and due[:4] == [4, 7, 10, 13]    # 10 Hz of the 0.033 s steps' time
        done = lambda: all(len(got[(i, "imu")]) == len(due) and len(got[(i, "range")]) == 7 * len(due)  # noqa: E731
                           for i in range(n)) and len(readings) >= steps + 1
        assert probe.spin_until(done, 15), ({key: len(v) for key, v in got.items()}, stack.sim.output())
        by_stamp = {stamp_ns(r): r for r in readings if r.run_id == started.run_id}
        for i in range(n):
            imus, mags, ranges = got[(i, "imu")], got[(i, "mag")], got[(i, "range")]
            assert [by_stamp[stamp_ns(m)].step for m in imus] == due           # stamped as those steps' readings
            assert [stamp_ns(m) for m in mags] == [stamp_ns(m) for m in imus]
            for j, (imu, mag) in enumerate(zip(imus, mags)):
                check_against_readings(imu, mag, ranges[7 * j:7 * j + 7], as_readings(by_stamp[stamp_ns(imu)]), i)
        ended = stack.end()
        stack.wait_closed(ended.recording)
        # the packaged configuration publishes them too (10 Hz: what this test set)
        assert DEFAULT.standard_sensor_rate == RATE
    finally:
        stack.close()

    # the bag, read with rosbags alone: every message of every robot's topics, as the subscriber got them
    decoded, counts, _ = rosbags_messages(ended.recording)
    for (i, kind), received in got.items():
        topic = "%s/robot_%d/%s" % (NS, i, kind)
        assert counts[topic] == len(received), topic
        for bagged, live in zip(decoded[topic], received):
            assert stamp_ns(bagged) == stamp_ns(live) and bagged.header.frame_id == live.header.frame_id
            if kind == "imu":
                assert bagged.linear_acceleration.z == live.linear_acceleration.z
                assert bagged.orientation.z == live.orientation.z
            elif kind == "mag":
                assert bagged.magnetic_field.x == live.magnetic_field.x
            else:
                assert bagged.range == live.range or (math.isnan(bagged.range) and math.isnan(live.range))
    with open(os.path.join(ended.recording, "metadata.yaml")) as f:
        meta = f.read()
    assert "sensor_msgs/msg/Imu" in meta and "sensor_msgs/msg/MagneticField" in meta and "sensor_msgs/msg/Range" in meta
