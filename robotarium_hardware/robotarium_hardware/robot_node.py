"""A simulated robot of the fleet: one process, one ROS node, one GTernal.

It behaves as a robot of a lab does: it takes geometry_msgs/Twist (or TwistStamped) on its own cmd_vel,
drives the GTernal's wheel model (robotarium_sim.hardware.Pipeline, as the hardware-like mode models
it: command latency and jitter, the robot's 16 ms loop, the firmware's wheel-speed PI with slew limit,
deadband, motor lag, unequal wheels, and its own command timeout: no command for `command_timeout`
and it brakes), publishes its odometry (nav_msgs/Odometry, 100 Hz: its sign of life) and its battery
(sensor_msgs/BatteryState, 1 Hz), and moves its body in the fleet's world (robotarium_hardware.world),
where the motion-capture and camera stand-ins see it. Its clock is the wall clock: the model advances to
the present every 10 ms and whenever a command comes.

    python -m robotarium_hardware.robot_node --ros-args -p name:=r0 -p world:=/dev/shm/FILE -p index:=0 \\
        -p x:=0.0 -p y:=0.0 -p theta:=0.0 [-p cmd_type:=TwistStamped] [-p command_timeout:=0.3]
"""
import dataclasses
import sys
import time

import numpy as np
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import BatteryState

from robotarium_core.config import DEFAULT
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.node_main import run_node
from robotarium_core.parameters import declare_parameter
from robotarium_hardware.steady import steady
from robotarium_hardware.templates import Template
from robotarium_hardware.world import World
from robotarium_sim.hardware import TICK, HardwareParameters, Pipeline

RATE = 100.0            # Hz: the model advanced to the present, the body written, the odometry published
BATTERY_PERIOD = 1.0    # s between BatteryState messages
BATTERY_DRAIN = 0.02    # percent of charge per second of running (a GTernal runs about an hour and a half)
# The robot's own command timeout: below the arena's 0.5 s, so that a robot cut off from its arena (the
# arena killed) is still within 0.5 s of the last command it was sent, latency and motor lag included.
COMMAND_TIMEOUT = 0.3
COMMAND_LATENCY = 0.01  # s, Wi-Fi and the robot's ROS stack (the Robotarium's MQTT: testbed.yaml's 0.03)
COMMAND_JITTER = 0.005  # s


class RobotNode(Node):
    def __init__(self):
        super().__init__("robot")
        name = declare_parameter(self, "name", "r0", "the robot's name: its topics are /<name>/cmd_vel, odom, "
                                 "battery_state")
        self.index = declare_parameter(self, "index", 0, "its row in the world file", low=0, high=1000, integer=True)
        world = declare_parameter(self, "world", "", "the fleet's world file (robotarium_hardware.world)")
        if not world:
            raise ValueError("no world file: pass -p world:=FILE (./robotarium fleet starts the robots with one)")
        start = [declare_parameter(self, axis, 0.0, "m or rad: where the robot stands at first (arena frame)")
                 for axis in ("x", "y", "theta")]
        cmd_type = declare_parameter(self, "cmd_type", "Twist", "Twist or TwistStamped")
        timeout = declare_parameter(self, "command_timeout", COMMAND_TIMEOUT, "s without a command before the robot "
                                    "brakes on its own", low=0.01, high=60.0)
        latency = declare_parameter(self, "command_latency", COMMAND_LATENCY, "s from a command to the robot's loop",
                                    low=0.0, high=1.0)
        jitter = declare_parameter(self, "command_jitter", COMMAND_JITTER, "s of extra latency, uniform", low=0.0,
                                   high=1.0)
        seed = declare_parameter(self, "seed", 1, "seed of the robot's loop phase, jitter and wheel radii", low=0,
                                 high=2**31 - 1, integer=True)
        if cmd_type not in ("Twist", "TwistStamped"):
            raise ValueError("cmd_type must be Twist or TwistStamped; received %r" % cmd_type)
        self.world = World(world)
        # The hardware-like mode's GTernal (testbed.yaml's numbers), its tracking off (the mocap's job), with
        # this robot's latency and its own command timeout.
        params = dataclasses.replace(HardwareParameters.from_config(DEFAULT), tracking_latency=0.0,
                                     tracking_noise_position=0.0, tracking_noise_heading=0.0, command_latency=latency,
                                     command_jitter=jitter, brake_timeout=timeout)
        self.pipeline = Pipeline(np.array(start, dtype=float).reshape(3, 1), params, seed)
        self.started = time.monotonic()
        self.battery = 95.0
        self.create_subscription(TwistStamped if cmd_type == "TwistStamped" else Twist, "/%s/cmd_vel" % name,
                                 self.on_command, 10)
        self.odom_pub = self.create_publisher(Odometry, "/%s/odom" % name, qos_profile_sensor_data)
        self.battery_pub = self.create_publisher(BatteryState, "/%s/battery_state" % name, qos_profile_sensor_data)
        odom = Odometry()
        odom.header.frame_id, odom.child_frame_id = "%s/odom" % name, "%s/base_link" % name
        self.odom = Template(odom, ("header.stamp.sec", "header.stamp.nanosec", "pose.pose.position.x",
                                    "pose.pose.position.y", "pose.pose.orientation.z", "pose.pose.orientation.w",
                                    "twist.twist.linear.x", "twist.twist.angular.z"))
        self.advance()
        self.create_timer(1.0 / RATE, self.advance)
        self.create_timer(BATTERY_PERIOD, self.publish_battery)
        scheduling = steady()
        self.get_logger().info("robot %s ready at (%.2f, %.2f, %.2f); %s" % (name, *start, scheduling))

    def on_command(self, msg):
        twist = msg.twist if isinstance(msg, TwistStamped) else msg
        v, w = twist.linear.x, twist.angular.z
        if not (np.isfinite(v) and np.isfinite(w)):
            return   # a robot's firmware ignores what it cannot drive
        self.advance(publish=False)
        self.pipeline.send([0], [v], [w])

    def advance(self, publish=True):
        p = self.pipeline
        target = int((time.monotonic() - self.started) / TICK)
        if target > p.t:
            p.advance(target - p.t)
        x, y, theta = p.true_poses[:, 0]
        speeds = p.wheel_speed[:, 0] * p.radii[:, 0]
        v, w = (speeds[0] + speeds[1]) / 2, (speeds[1] - speeds[0]) / p.base_length
        now = time.time()
        self.world.write(self.index, x, y, theta, v, w, now)
        if publish:
            sec, nanosec = divmod(int(now * 1e9), 10**9)
            self.odom_pub.publish(self.odom.build(sec, nanosec, x, y, np.sin(theta / 2), np.cos(theta / 2), v, w))

    def publish_battery(self):
        self.battery = max(0.0, 95.0 - BATTERY_DRAIN * (time.monotonic() - self.started))
        msg = BatteryState(percentage=self.battery / 100.0, voltage=3.3 + 0.9 * self.battery / 100.0, present=True)
        msg.header.stamp = self.get_clock().now().to_msg()
        self.battery_pub.publish(msg)


USAGE = __doc__.split("\n\n")[-1]


def main(args=None):
    argv = sys.argv if args is None else args
    if "--help" in argv or "-h" in argv[1:2]:
        print("A simulated robot of the fleet (./robotarium fleet starts them).\n\nusage:" + USAGE)
        return 0
    return run_node(RobotNode, "robot", args, watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
