"""The simulator node's part of the 2.x API: a 2.x experiment from its StartExperiment request, and
the messages it adds (sensor readings, the experiment's settings, the obstacles for viewers, and
the sensors per robot on standard message types for ROS tools: StandardSensors).

Kept out of simulator_node.py so that the node stays one thin shell; the maths is in
robotarium_core.rps2 and robotarium_core.sensors.
"""
import array
import math

import numpy as np
import yaml
from geometry_msgs.msg import Point
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, MagneticField, Range
from visualization_msgs.msg import Marker

from robotarium_core import cdr, model, rps2
from robotarium_core.sensors import GRAVITY, NUMBER_OF_DISTANCE_SENSORS
from robotarium_msgs.msg import SensorReadings


def testbed_for(request, poses, config):
    """A rps2.Testbed2 for a StartExperiment request with api "2" (RobotariumError if it is bad)."""
    n = poses.shape[1]
    obstacles = rps2.unflatten_obstacles(request.obstacles)
    goals_given = (len(request.drive_on_x), len(request.drive_on_y), len(request.drive_on_theta))
    goals = None
    if goals_given == (n, n, n):
        goals = model.validate_initial_conditions(
            np.array([request.drive_on_x, request.drive_on_y, request.drive_on_theta], dtype=float), n,
            config.robot_diameter, config.arena)
    elif goals_given != (0, 0, 0):
        raise model.RobotariumError("drive_on_x, drive_on_y and drive_on_theta need length %d each, or all empty "
                                    "for no drive-on phase; received lengths %s." % (n, goals_given))
    return rps2.Testbed2(poses, config, obstacles=obstacles, drive_on_goals=goals,
                         distance_sensors=bool(request.use_distance_sensors),
                         rng=np.random.default_rng(request.sensor_seed or config.sensor_seed))


def settings_yaml(run_id, api, testbed):
    """The experiment's settings (recorded, read by the safety node and the results)."""
    settings = {"run_id": run_id, "api": api or "", "number_of_robots": testbed.number_of_robots}
    if isinstance(testbed, rps2.Testbed2):
        settings["obstacles"] = testbed.obstacles.tolist()
        settings["use_distance_sensors"] = bool(testbed.sensors.distance_sensors)
        settings["drive_on_goals"] = None if testbed.drive_on_goals is None else testbed.drive_on_goals.tolist()
    return yaml.safe_dump(settings, sort_keys=False)


def obstacles_publisher(node, topic, qos):
    return node.create_publisher(Marker, topic, qos)


def publish_obstacles(node, publisher, testbed):
    """The experiment's obstacles as one LINE_LIST marker (empty: none), for RViz / Foxglove."""
    marker = Marker()
    marker.header.stamp = node.get_clock().now().to_msg()
    marker.header.frame_id = "arena"
    marker.ns = "obstacles"
    marker.type = Marker.LINE_LIST
    marker.action = Marker.ADD
    marker.pose.orientation.w = 1.0
    marker.scale.x = 0.02
    marker.color.r = marker.color.g = marker.color.b = 0.5
    marker.color.a = 1.0
    for (x1, y1), (x2, y2) in getattr(testbed, "obstacles", np.zeros((0, 2, 2))):
        marker.points.append(Point(x=float(x1), y=float(y1)))
        marker.points.append(Point(x=float(x2), y=float(y2)))
    publisher.publish(marker)


def _floats(values):
    return array.array("d", np.ascontiguousarray(values, dtype=np.float64).tobytes())


def sensor_readings(testbed, run_id, stamp):
    s = testbed.sensors
    msg = SensorReadings()
    msg.header.stamp = stamp
    msg.header.frame_id = "arena"
    msg.run_id = run_id
    msg.step = testbed.steps
    msg.number_of_robots = testbed.number_of_robots
    msg.distances = _floats(s.distances)
    msg.distance_endpoints = _floats(s.distance_endpoints)
    msg.encoders = array.array("i", np.ascontiguousarray(s.encoders, dtype=np.int32).tobytes())
    msg.accelerations = _floats(s.accelerations)
    msg.gyros = _floats(s.gyros)
    msg.magnetic_fields = _floats(s.magnetic_fields)
    msg.orientations = _floats(s.orientations)
    return msg


# -- the sensors per robot on standard message types, for ROS tools ----------------------------------

# Topics, relative to the simulator's namespace: robot_<i>/imu, robot_<i>/mag, robot_<i>/range.
IMU, MAG, RANGE = "robot_%d/imu", "robot_%d/mag", "robot_%d/range"
TESLA_PER_MICROTESLA = 1e-6


def standard_sensor_qos(messages_per_period):
    """Reliable (rviz, Foxglove and ros2 topic echo subscribe reliable or best effort; a best-effort
    writer would match neither a reliable reader) and volatile, a stream (robotarium_core.topics: a
    run's start waits for the recorder's readers of a new robot's topics), with a history of 5 s of
    simulated time at 10 Hz a matched reader may trail by."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50 * messages_per_period,
                      reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)


IMU_QOS, MAG_QOS = standard_sensor_qos(1), standard_sensor_qos(1)
RANGE_QOS = standard_sensor_qos(NUMBER_OF_DISTANCE_SENSORS)


def _diagonal(values):
    """Row-major 3 x 3 covariance with `values` on the diagonal."""
    return [values[0], 0.0, 0.0, 0.0, values[1], 0.0, 0.0, 0.0, values[2]]


def imu_rows(sensors, config):
    """N x 37 float64, the body of each robot's sensor_msgs/Imu after its header: orientation (x, y,
    z, w), its covariance, angular_velocity, its covariance, linear_acceleration, its covariance.

    - orientation: the fused yaw (degrees -> rad) as a rotation about z of the arena frame; roll and
      pitch are zero (the robots drive on a flat floor), so their variances are 0 and the yaw's is
      orientation_noise_std in rad, squared;
    - angular_velocity: the gyroscope, rad/s as 2.x; variances gyro_noise_std squared;
    - linear_acceleration: 2.x reads a + g (gravity as -9.81 on z), sensor_msgs/Imu the specific
      force a - g (REP 145: +9.81 on z at rest), so z is the 2.x reading + 2 x 9.81, x and y as
      they are; variances accelerometer_noise_std squared.
    The noise of each axis is independent in the model (robotarium_core.sensors), so every
    covariance is diagonal and known: none is -1 (REP 145's "not provided")."""
    n = sensors.orientations.shape[0]
    yaw = np.radians(sensors.orientations)
    rows = np.empty((n, 37))
    rows[:, 0:2] = 0.0
    rows[:, 2] = np.sin(yaw / 2)
    rows[:, 3] = np.cos(yaw / 2)
    rows[:, 4:13] = _diagonal([0.0, 0.0, math.radians(config.orientation_noise_std) ** 2])
    rows[:, 13:16] = sensors.gyros.T
    rows[:, 16:25] = _diagonal(np.square(config.gyro_noise_std))
    rows[:, 25:28] = sensors.accelerations.T
    rows[:, 27] += 2 * GRAVITY
    rows[:, 28:37] = _diagonal(np.square(config.accelerometer_noise_std))
    return rows


def magnetic_field_rows(sensors, config):
    """N x 12 float64, the body of each robot's sensor_msgs/MagneticField: the field in tesla (2.x
    reads microtesla) and its covariance (magnetometer_noise_std in tesla, squared, on the diagonal)."""
    n = sensors.magnetic_fields.shape[1]
    rows = np.empty((n, 12))
    rows[:, 0:3] = sensors.magnetic_fields.T * TESLA_PER_MICROTESLA
    rows[:, 3:12] = _diagonal(np.square(np.asarray(config.magnetometer_noise_std) * TESLA_PER_MICROTESLA))
    return rows


def range_rows(sensors, config):
    """N x 7 x 5 float32: field_of_view, min_range, max_range, range, variance of each robot's seven
    sensor_msgs/Range (2.x's ray order). The model casts a ray (field of view 0); a reading of -1
    (nothing within range, or a dropout: a real sensor cannot tell them apart either) is +inf, REP
    117's "no object detected within range"; NaN (no reading: the experiment has no distance
    sensors) stays NaN. variance: (distance_sensor_error x range)^2, the model's noise at that
    distance (outliers aside); 0 ("unknown") where there is no finite range."""
    d = sensors.distances.T                                         # N x 7
    r = np.where(d == -1.0, np.inf, d)
    rows = np.zeros(d.shape + (5,), dtype=np.float32)
    rows[..., 1] = 0.0
    rows[..., 2] = config.distance_sensor_range
    rows[..., 3] = r
    with np.errstate(invalid="ignore"):
        rows[..., 4] = np.where(np.isfinite(r), np.square(config.distance_sensor_error * r), 0.0)
    return rows


class StandardSensors:
    """A 2.x experiment's sensors per robot on standard message types, for ROS tools (rviz,
    Foxglove, ros2 topic echo) and the bag: robot_<i>/imu (sensor_msgs/Imu), robot_<i>/mag
    (sensor_msgs/MagneticField) and robot_<i>/range (sensor_msgs/Range, seven a period, one per
    distance sensor, frame_id robot_<i>/distance_<k>), at `standard_sensor_rate` Hz of simulated
    time: the first step at or past each multiple of its period, stamped as that step's
    SensorReadings, with the same values in SI units (the functions above).

    Why Range per ray and not a LaserScan: a LaserScan is one origin and evenly spaced angles; the
    2.x sensors sit at seven different points up to 6 cm apart (distance_sensor_x, _y) and look at
    180, 90, 45, 0, -45, -90 and -180 degrees (steps of 90 and 45 degrees, the first and last the
    same direction from two points), so a scan would misplace every reading. Each Range has its own
    frame (robot_<i>/distance_<k>: at (origin_offset + x_k, y_k) in robot_<i>, turned by heading_k).
    The seven go on one topic per robot, told apart by frame_id (rviz's Range display keeps the
    last "Buffer Length" of them), so that 50 robots make 150 topics, not 450: each topic costs
    discovery, a reader in the recorder and two event handlers there.

    Publishers are made the first time an experiment has that many robots and kept (a new
    publisher is a new discovery for every reader); they are made without event handlers, which
    the node's executor would otherwise wait on (robotarium_core.executor: about 4 us each per
    wait). The bytes are built here (robotarium_core.cdr's encoding, checked against rclpy's in
    tests/test_standard_sensors.py): an rclpy message object costs more than its publication.
    """

    def __init__(self, node, rate):
        self.node = node
        self.rate = rate
        self.publishers = []        # per robot: (imu, mag, range) publishers and their header tails
        self._last_period = 0

    def start(self, testbed):
        """A new 2.x experiment: publishers for its robots, the period count from zero."""
        self._last_period = 0
        if self.rate <= 0:
            return
        no_events = PublisherEventCallbacks(use_default_callbacks=False)
        for i in range(len(self.publishers), testbed.number_of_robots):
            frame = "robot_%d" % i
            self.publishers.append((
                self.node.create_publisher(Imu, IMU % i, IMU_QOS, event_callbacks=no_events),
                self.node.create_publisher(MagneticField, MAG % i, MAG_QOS, event_callbacks=no_events),
                self.node.create_publisher(Range, RANGE % i, RANGE_QOS, event_callbacks=no_events),
                cdr.header_tail(frame, align=8),   # Imu, MagneticField: float64s follow the header
                # Range: radiation_type (INFRARED: it knows only that and ULTRASOUND), then float32s
                [cdr.header_tail("%s/distance_%d" % (frame, k), bytes([Range.INFRARED]), align=4)
                 for k in range(NUMBER_OF_DISTANCE_SENSORS)]))

    def due(self, testbed):
        """Whether this step is the first at or past the next multiple of the period."""
        if self.rate <= 0 or testbed.steps == 0:
            return False
        period = math.floor(testbed.sim_time * self.rate + 1e-9)
        if period <= self._last_period:
            return False
        self._last_period = period
        return True

    def publish(self, testbed, sec, nanosec):
        sensors, config = testbed.sensors, testbed.config
        head = cdr.stamp_head(sec, nanosec)
        imu = imu_rows(sensors, config)
        mag = magnetic_field_rows(sensors, config)
        ranges = range_rows(sensors, config) if sensors.distance_sensors else None
        for i in range(testbed.number_of_robots):
            imu_pub, mag_pub, range_pub, tail, range_tails = self.publishers[i]
            imu_pub.publish(head + tail + imu[i].tobytes())
            mag_pub.publish(head + tail + mag[i].tobytes())
            if ranges is not None:
                for k, range_tail in enumerate(range_tails):
                    range_pub.publish(head + range_tail + ranges[i, k].tobytes())
