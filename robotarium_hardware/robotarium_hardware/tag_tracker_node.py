"""The tag tracker: an overhead camera's images in, the robots' poses out, in the arena's frame.

sensor_msgs/Image (mono8, bgr8 or rgb8) on the fleet file's camera.image_topic, or CompressedImage (JPEG,
PNG) on <image_topic>/compressed, in; for each image, the
ArUco tags (OpenCV, DICT_4X4_50: robotarium_hardware.tags.TagTracker): the four corner tags give the
arena's frame, each robot's tag (its id in the fleet file) its pose, published as geometry_msgs/PoseStamped
on <camera.pose_prefix>/<robot>/pose (frame `arena`, stamped with the image's stamp: the hardware arena
reads them as it reads motion capture). A robot whose tag is not in an image gets no pose for it. Images
that are not images are dropped and counted. Every 10 s the log says frames, poses, latency (stamp to
publication) and CPU per frame.

    ros2 run robotarium_hardware tag_tracker --ros-args -p fleet_file:=FILE
"""
import sys
import time

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CompressedImage, Image

from robotarium_core.config import DEFAULT
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.node_main import run_node
from robotarium_core.parameters import declare_parameter
from robotarium_hardware import fleet as fleets
from robotarium_hardware.steady import steady
from robotarium_hardware.tags import TagTracker, parse_compressed, parse_image
from robotarium_hardware.templates import Template

REPORT_PERIOD = 10.0   # s between the log's figures
MISSES_LOGGED = 20     # tags missing from a frame (after one that had them) said in the log


class TagTrackerNode(Node):
    def __init__(self):
        super().__init__("tag_tracker")
        path = declare_parameter(self, "fleet_file", "", "the fleet file: each robot's tag, the corner tags, topics")
        if not path:
            raise ValueError("no fleet file: pass -p fleet_file:=FILE")
        fleet = fleets.load(path)
        arena = declare_parameter(self, "arena", list(DEFAULT.arena), "the arena [x_min, x_max, y_min, y_max] (m): "
                                  "the corner tags' centres are its corners")
        self.fleet = fleet
        self.tracker = TagTracker(arena, fleet.camera.corner_tags, {r.tag: i for i, r in enumerate(fleet.robots)})
        self.pose_pubs = [self.create_publisher(PoseStamped, fleet.pose_topic(r), 10) for r in fleet.robots]
        msg = PoseStamped()
        msg.header.frame_id = "arena"
        self.template = Template(msg, ("header.stamp.sec", "header.stamp.nanosec", "pose.position.x", "pose.position.y",
                                       "pose.orientation.z", "pose.orientation.w"))
        # the newest frame only: a tracker that falls behind skips frames rather than answering late
        newest = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)   # matches reliable cameras too
        self.create_subscription(Image, fleet.camera.image_topic, lambda data: self.on_image(data, parse_image),
                                 newest, raw=True)
        self.create_subscription(CompressedImage, fleet.camera.image_topic + "/compressed",
                                 lambda data: self.on_image(data, parse_compressed), newest, raw=True)
        self.frames = self.dropped = self.poses = self.missed = 0
        self.last = {}
        self.latency, self.cpu = [], []
        self.create_timer(REPORT_PERIOD, self.report)
        scheduling = steady()
        self.get_logger().info("tag tracker ready: %d robots' tags (%s) on %s; %s" % (
            len(fleet.robots), ", ".join("%s %d" % (r.name, r.tag) for r in fleet.robots), fleet.camera.image_topic,
            scheduling))

    def on_image(self, data, parse):
        cpu = time.process_time()
        try:
            stamp, gray = parse(data)
        except ValueError:
            self.dropped += 1
            return
        found = self.tracker.track(gray)
        for i in set(self.last) - set(found):   # a tag seen in the frame before, not in this one
            self.missed += 1
            if self.missed <= MISSES_LOGGED:
                self.get_logger().info("%s's tag (%d) not found in the frame of %.3f; it was at (%.3f, %.3f) a frame "
                                       "before" % (self.fleet.robots[i].name, self.fleet.robots[i].tag, stamp,
                                                   *self.last[i][:2]))
        self.last = found
        sec, nanosec = divmod(int(round(stamp * 1e9)), 10**9)
        for i, (x, y, theta) in found.items():
            self.pose_pubs[i].publish(self.template.build(sec, nanosec, x, y, np.sin(theta / 2), np.cos(theta / 2)))
        self.frames += 1
        self.poses += len(found)
        self.latency.append(time.time() - stamp)
        self.cpu.append(time.process_time() - cpu)

    def report(self):
        if self.frames:
            self.get_logger().info("%d frames, %.1f robots seen a frame, latency median %.1f ms, CPU %.1f ms a frame; "
                                   "%d images dropped; tags read on a second look: %d of %d" % (
                                       self.frames, self.poses / self.frames, 1e3 * np.median(self.latency),
                                       1e3 * np.median(self.cpu), self.dropped, self.tracker.recovered,
                                       self.tracker.retries))
        self.frames = self.poses = 0
        self.latency, self.cpu = [], []


def main(args=None):
    argv = sys.argv if args is None else args
    if "--help" in argv or "-h" in argv[1:2]:
        print(__doc__)
        return 0
    return run_node(TagTrackerNode, "tag_tracker", args, watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
