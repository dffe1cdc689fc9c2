"""The camera stand-in: an overhead camera over the arena, at 30 Hz, as a lab's camera driver publishes it.

Each frame it looks at every robot's body in the fleet's world (robotarium_hardware.world) and renders
what the camera sees (robotarium_hardware.tags.Renderer: perspective, the robots' ArUco tags, the four
corner tags, blur, sensor noise), published as sensor_msgs/CompressedImage (JPEG, as image_transport's
compressed plugin sends a camera's images) on /camera/image_raw/compressed, stamped with the moment it
shows. A test can hide a robot's tag (a hand over it): std_msgs/String "r1 0.5" on /camera/hide hides
r1's tag from the next frame for 0.5 s; /camera/hidden (std_msgs/String, JSON) then says when the first
frame without it was taken ({"robot": "r1", "since": time.time()}).

    python -m robotarium_hardware.camera_node --ros-args -p world:=FILE -p robots:=[r0,r1] -p tags:=[10,11]
"""
import json
import sys
import time

from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import CompressedImage
from std_msgs.msg import String

from robotarium_core.config import DEFAULT
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.node_main import run_node
from robotarium_core.parameters import declare_parameter
from robotarium_hardware.fleet import Camera
from robotarium_hardware.steady import steady
from robotarium_hardware.tags import OverheadCamera, Renderer, compressed_bytes
from robotarium_hardware.world import World

RATE = 30.0   # Hz


class CameraNode(Node):
    def __init__(self):
        super().__init__("camera")
        world = declare_parameter(self, "world", "", "the fleet's world file (robotarium_hardware.world)")
        self.names = list(declare_parameter(self, "robots", ["r0"], "the robots' names, in the world file's order"))
        self.tags = list(declare_parameter(self, "tags", [10], "each robot's ArUco id (DICT_4X4_50)", integer=True))
        rate = declare_parameter(self, "rate", RATE, "Hz", low=1.0, high=120.0)
        topic = declare_parameter(self, "image_topic", Camera.image_topic, "where the images go")
        seed = declare_parameter(self, "seed", 1, "seed of the sensor noise", low=0, high=2**31 - 1, integer=True)
        if not world:
            raise ValueError("no world file: pass -p world:=FILE (./robotarium fleet starts the stand-in with one)")
        if len(self.tags) != len(self.names):
            raise ValueError("robots and tags must have one entry per robot; received %d and %d"
                             % (len(self.names), len(self.tags)))
        self.world = World(world)
        camera = Camera()
        self.renderer = Renderer(OverheadCamera(), DEFAULT.arena, camera.corner_tags, camera.corner_tag_size,
                                 camera.tag_size, DEFAULT.robot_diameter, seed=seed)
        self.hidden = {}   # robot index -> until (time.time())
        self.announce = set()
        # JPEG, as image_transport's compressed plugin sends it (<topic>/compressed): a raw 1 MB frame is 16 UDP
        # fragments, more than a socket's default buffer holds, and two frames of three were lost here best effort
        # (19 of 30 a second reliable, 47 ms late); 100 kB frames all come, best effort, as cameras publish.
        self.image_pub = self.create_publisher(CompressedImage, topic + "/compressed", qos_profile_sensor_data)
        self.hidden_pub = self.create_publisher(String, "/camera/hidden", 10)
        self.create_subscription(String, "/camera/hide", self.on_hide, 10)
        self.create_timer(1.0 / rate, self.frame)
        scheduling = steady()
        self.get_logger().info("camera ready: %d robots' tags at %g Hz on %s; %s" % (len(self.names), rate, topic,
                                                                                     scheduling))

    def on_hide(self, msg):
        try:
            name, seconds = msg.data.split()
            k, until = self.names.index(name), time.time() + float(seconds)
        except ValueError:
            self.get_logger().warning("/camera/hide takes 'ROBOT SECONDS'; received %r" % msg.data)
            return
        self.hidden[k] = until
        self.announce.add(k)

    def frame(self):
        now = time.time()
        n = len(self.names)
        poses = self.world.poses_at(now)[:, :n]
        placed = self.world.placed()[:n]
        hidden = {k for k, until in self.hidden.items() if now < until} | {k for k in range(n) if not placed[k]}
        image = self.renderer.render(poses[:, placed], [t for t, p in zip(self.tags, placed) if p],
                                     hidden={i for i, k in enumerate(k for k in range(n) if placed[k]) if k in hidden})
        sec, nanosec = divmod(int(now * 1e9), 10**9)
        self.image_pub.publish(compressed_bytes(sec, nanosec, "camera", image))
        for k in sorted(self.announce & hidden):
            self.hidden_pub.publish(String(data=json.dumps({"robot": self.names[k], "since": now})))
        self.announce -= hidden


def main(args=None):
    argv = sys.argv if args is None else args
    if "--help" in argv or "-h" in argv[1:2]:
        print(__doc__)
        return 0
    return run_node(CameraNode, "camera", args, watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
