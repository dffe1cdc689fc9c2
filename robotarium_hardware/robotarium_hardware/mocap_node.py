"""The motion-capture stand-in: what vrpn_mocap publishes for a Vicon or OptiTrack over the arena.

At `rate` Hz (120) it looks at every robot's body in the fleet's world (robotarium_hardware.world: a
robot whose process died still stands there) and publishes its pose as geometry_msgs/PoseStamped on
/vrpn_mocap/<robot>/pose, in the motion capture's own frame (the fleet file's calibration takes it to the
arena's), z up, the heading as a quaternion about z, with the tracking noise of the testbed
configuration (tracking_noise_position, tracking_noise_heading) and now and then a dropped frame of a
robot (`dropout`, a marker hidden for a frame).

    python -m robotarium_hardware.mocap_node --ros-args -p world:=FILE -p robots:=[r0,r1] \\
        [-p calibration:=[x,y,yaw]] [-p rate:=120.0] [-p dropout:=0.002] [-p seed:=1]
"""
import sys
import time

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data

from robotarium_core.config import DEFAULT
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.node_main import run_node
from robotarium_core.parameters import declare_parameter
from robotarium_hardware.fleet import Calibration
from robotarium_hardware.steady import steady
from robotarium_hardware.templates import Template
from robotarium_hardware.world import World

RATE = 120.0       # Hz, a motion capture's usual frame rate
DROPOUT = 0.002    # probability that a robot is missing from a frame


class MocapNode(Node):
    def __init__(self):
        super().__init__("mocap")
        world = declare_parameter(self, "world", "", "the fleet's world file (robotarium_hardware.world)")
        names = declare_parameter(self, "robots", ["r0"], "the robots' names, in the world file's order")
        frame = declare_parameter(self, "calibration", [0.0, 0.0, 0.0], "x, y, yaw of this motion capture's frame in "
                                  "the arena (the fleet file's calibration)")
        rate = declare_parameter(self, "rate", RATE, "Hz", low=1.0, high=1000.0)
        self.dropout = declare_parameter(self, "dropout", DROPOUT, "probability of a robot missing from a frame",
                                         low=0.0, high=1.0)
        seed = declare_parameter(self, "seed", 1, "seed of the noise and dropouts", low=0, high=2**31 - 1, integer=True)
        if not world:
            raise ValueError("no world file: pass -p world:=FILE (./robotarium fleet starts the stand-in with one)")
        self.world = World(world)
        self.names = list(names)[:self.world.size]
        self.calibration = Calibration(*frame)
        self.rng = np.random.default_rng(seed)
        self.noise = (DEFAULT.tracking_noise_position, DEFAULT.tracking_noise_heading)
        self.publishers_ = [self.create_publisher(PoseStamped, "/vrpn_mocap/%s/pose" % name, qos_profile_sensor_data)
                            for name in self.names]
        msg = PoseStamped()
        msg.header.frame_id = "world"
        self.template = Template(msg, ("header.stamp.sec", "header.stamp.nanosec", "pose.position.x", "pose.position.y",
                                       "pose.orientation.z", "pose.orientation.w"))
        self.create_timer(1.0 / rate, self.frame)
        scheduling = steady()
        self.get_logger().info("motion capture ready: %d bodies at %g Hz; %s" % (len(self.names), rate, scheduling))

    def frame(self):
        now = time.time()
        placed = self.world.placed()
        x, y, theta = self.world.poses_at(now)
        n = len(self.names)
        x, y, theta = x[:n], y[:n], theta[:n]
        x = x + self.rng.normal(0.0, self.noise[0], n)
        y = y + self.rng.normal(0.0, self.noise[0], n)
        theta = theta + self.rng.normal(0.0, self.noise[1], n)
        mx, my, mtheta = self.calibration.from_arena(x, y, theta)
        seen = placed[:n] & (self.rng.random(n) >= self.dropout)
        sec, nanosec = divmod(int(now * 1e9), 10**9)
        for i in np.flatnonzero(seen):
            self.publishers_[i].publish(self.template.build(sec, nanosec, mx[i], my[i], np.sin(mtheta[i] / 2),
                                                            np.cos(mtheta[i] / 2)))


def main(args=None):
    argv = sys.argv if args is None else args
    if "--help" in argv or "-h" in argv[1:2]:
        print(__doc__)
        return 0
    return run_node(MocapNode, "mocap", args, watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
