"""The simulator node's part of the 2.x API: a 2.x experiment from its StartExperiment request, and
the messages it adds (sensor readings, the experiment's settings, the obstacles for viewers).

Kept out of simulator_node.py so that the node stays one thin shell; the maths is in
robotarium_core.rps2 and robotarium_core.sensors.
"""
import array

import numpy as np
import yaml
from visualization_msgs.msg import Marker
from geometry_msgs.msg import Point

from robotarium_msgs.msg import SensorReadings
from robotarium_core import model, rps2


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
