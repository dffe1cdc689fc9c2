"""The Robotarium simulator node: a thin ROS 2 shell around robotarium_core.model.Testbed.

Topics (relative to the node's namespace, /robotarium by default):
  cmd_safe        robotarium_msgs/TwistArray   in:  the safety node's commands (the only command input)
  safety_report   robotarium_msgs/SafetyReport in:  counted as safety interventions
  poses           robotarium_msgs/RobotPoses   out: every step
  pose_array      geometry_msgs/PoseArray      out: every step, for viewers (built only when someone listens)
  status          robotarium_msgs/TestbedStatus out: every step, and once a second while idle or in lockstep
Services:
  start_experiment robotarium_msgs/StartExperiment, end_experiment robotarium_msgs/EndExperiment

Modes, chosen per experiment: real time (a timer at `rate` Hz; a robot whose last command is older
than `command_timeout` stops) or lockstep (exactly one step per accepted command array, as fast as
commands come, so a run is deterministic). In lockstep a command array's `step` is the step it
produces; one whose step was already taken is a re-send and is ignored, so a client may re-send
safely when a message was lost before discovery completed (step 0 means "unnumbered": always taken).
"""
import array
import math
import re
import sys
import time

import numpy as np
from geometry_msgs.msg import Pose, PoseArray
from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import String

from robotarium_msgs.msg import RobotPoses, SafetyReport, TestbedStatus, TwistArray
from robotarium_msgs.srv import EndExperiment, StartExperiment
from robotarium_core import model
from robotarium_core.node_tools import declare_config, run_node
from robotarium_core.topics import (CMD_SAFE, CONFIG, DEFAULT_NAMESPACE, END_EXPERIMENT, LATCHED, POSE_ARRAY, POSES,
                                    RECORDING, SAFETY_REPORT, START_EXPERIMENT, STATUS, TESTBED_QOS,
                                    warn_on_incompatible_qos)

DROP_REASONS = {
    "nonfinite": "NaN or inf in a velocity",
    "length_mismatch": "ids and twists of different lengths, or an id given twice",
    "unknown_id": "an id that is not a robot of this experiment",
}


def to_float_array(values):
    """numpy float64 vector -> array.array('d') without a Python loop (what rclpy stores for float64[])."""
    return array.array("d", np.ascontiguousarray(values, dtype=np.float64).tobytes())


def copy_counters(testbed, target):
    """The debug report's counters and the sim time, into a status message or an end response."""
    target.sim_time = testbed.sim_time
    target.collisions = testbed.collisions
    target.boundary_violations = testbed.boundary_violations
    target.actuator_limit_iterations = testbed.actuator_limit_iterations
    target.command_timeouts = testbed.command_timeouts


class SimulatorNode(Node):
    def __init__(self):
        super().__init__("simulator", namespace=DEFAULT_NAMESPACE)
        self.config = declare_config(self)
        self.testbed = None
        self.real_time = True
        self.experiment = ""
        self.run_id = ""
        self.recording = ""
        self.safety_interventions = 0
        self.commands_accepted = 0
        self.dropped = {kind: 0 for kind in DROP_REASONS}
        self._logged_drops = set()
        self._clock_start = 0.0
        self._tick_timer = None

        self.poses_pub = self.create_publisher(RobotPoses, POSES, TESTBED_QOS)
        self.pose_array_pub = self.create_publisher(PoseArray, POSE_ARRAY, 10)
        self.status_pub = self.create_publisher(TestbedStatus, STATUS, TESTBED_QOS)
        # The configuration of the running experiment, for the recorder and the report.
        self.config_pub = self.create_publisher(String, CONFIG, LATCHED)
        self.create_subscription(TwistArray, CMD_SAFE, self.on_command, TESTBED_QOS,
                                 event_callbacks=warn_on_incompatible_qos(self, CMD_SAFE))
        self.create_subscription(SafetyReport, SAFETY_REPORT, self.on_safety_report, TESTBED_QOS)
        self.create_subscription(String, RECORDING, self.on_recording, LATCHED)
        self.create_service(StartExperiment, START_EXPERIMENT, self.on_start)
        self.create_service(EndExperiment, END_EXPERIMENT, self.on_end)
        self.create_timer(1.0, self.publish_status_heartbeat)
        self.config_pub.publish(String(data=self.config.to_yaml()))
        self.get_logger().info("simulator ready in namespace %s" % self.get_namespace())

    # -- experiments -------------------------------------------------------------------------

    def on_start(self, request, response):
        response.success = False
        if self.testbed is not None:
            response.message = ("experiment %r is still running; end it (end_experiment) before starting another."
                                % self.experiment)
            return response
        name = request.name or "experiment"
        if not re.fullmatch(r"[A-Za-z0-9_-]{1,64}", name):
            response.message = "name %r must be 1 to 64 letters, digits, '-' or '_'." % name
            return response
        c = self.config
        try:
            model.validate_number_of_robots(int(request.number_of_robots), c.max_robots)
            n = int(request.number_of_robots)
            given = (len(request.x), len(request.y), len(request.theta))
            if given == (0, 0, 0):
                seed = request.seed or None
                poses = model.random_initial_conditions(n, np.random.default_rng(seed))
            elif given == (n, n, n):
                poses = np.array([request.x, request.y, request.theta], dtype=float)
            else:
                raise model.RobotariumError(
                    "initial conditions need x, y and theta of length %d each, or all empty for random ones; "
                    "received lengths %s." % (n, given))
            self.testbed = model.Testbed(poses, c)
        except model.RobotariumError as error:
            response.message = str(error)
            return response

        self.real_time = bool(request.real_time)
        self.experiment = name
        self.run_id = "%s_%s" % (name, time.strftime("%Y%m%d-%H%M%S"))
        self.safety_interventions = 0
        self.commands_accepted = 0
        self.dropped = {kind: 0 for kind in DROP_REASONS}
        self._logged_drops = set()
        self._clock_start = time.monotonic()
        if self.real_time:
            self._tick_timer = self.create_timer(1.0 / c.rate, self.tick)
        self.publish_state()
        self.config_pub.publish(String(data=c.to_yaml()))
        response.success = True
        response.run_id = self.run_id
        response.x, response.y, response.theta = (to_float_array(row) for row in self.testbed.poses)
        response.message = "started %s: %d robots, %s" % (
            self.run_id, n, "real time at %g Hz" % c.rate if self.real_time else "lockstep")
        self.get_logger().info(response.message)
        return response

    def on_end(self, request, response):
        if self.testbed is None:
            response.success = False
            response.message = "no experiment is running."
            return response
        if self._tick_timer is not None:
            self.destroy_timer(self._tick_timer)
            self._tick_timer = None
        tb = self.testbed
        response.success = True
        response.run_id = self.run_id
        response.steps = tb.steps
        copy_counters(tb, response)
        response.report = tb.report()
        response.recording = self.recording
        response.message = "ended %s after %d steps" % (self.run_id, tb.steps)
        self.publish_status()  # the final counters, still marked running, so recorders keep them
        self.testbed = None
        self.publish_status()
        self.get_logger().info(response.message)
        return response

    def wind_down(self, reason):
        """Stopping (a signal, or the process that started the testbed is gone: node_tools.run_node):
        end the running experiment as end_experiment does, and wait until its last statuses reached
        every subscriber, so the recorder records the end and closes the run."""
        if self.testbed is not None:
            self.get_logger().warning("ending experiment %s: %s" % (self.run_id, reason))
            self.on_end(EndExperiment.Request(), EndExperiment.Response())
            self.status_pub.wait_for_all_acked(Duration(seconds=1.0))
        return None

    # -- commands ----------------------------------------------------------------------------

    def on_command(self, msg):
        tb = self.testbed
        if tb is None:
            return
        if not self.real_time and 0 < msg.step <= tb.steps:
            return  # a lockstep command re-sent by a client that missed our poses: already applied
        ids = np.frombuffer(msg.ids, dtype=np.uint32) if len(msg.ids) else np.zeros(0, dtype=np.uint32)
        v = np.array([t.linear.x for t in msg.twists], dtype=float)
        w = np.array([t.angular.z for t in msg.twists], dtype=float)
        problem = model.check_commands(ids, v, w, tb.number_of_robots)
        if problem is not None:
            self.dropped[problem] += 1
            if problem not in self._logged_drops:
                self._logged_drops.add(problem)
                self.get_logger().warning(
                    "dropped a command array (step %d): %s. Further drops of this kind are only counted "
                    "in the status topic." % (msg.step, DROP_REASONS[problem]))
            self.publish_status()
            return
        self.commands_accepted += 1
        tb.set_commands(ids, v, w, now=time.monotonic(), requested_exceeds_limits=msg.requested_exceeds_limits)
        if not self.real_time:
            tb.step()
            self.publish_state()

    def on_safety_report(self, msg):
        if self.testbed is not None and msg.status != SafetyReport.STATUS_PASSTHROUGH:
            self.safety_interventions += 1

    def on_recording(self, msg):
        self.recording = msg.data

    # -- stepping and publishing ---------------------------------------------------------------

    def tick(self):
        tb = self.testbed
        if tb is None:
            return
        tb.expire_commands(time.monotonic(), self.config.command_timeout)
        tb.step()
        self.publish_state()

    def publish_state(self):
        tb = self.testbed
        stamp = self.get_clock().now().to_msg()
        msg = RobotPoses()
        msg.header.stamp = stamp
        msg.header.frame_id = "arena"
        msg.run_id = self.run_id
        msg.step = tb.steps
        msg.sim_time = tb.sim_time
        msg.ids = array.array("I", range(tb.number_of_robots))
        msg.x, msg.y, msg.theta = (to_float_array(row) for row in tb.poses)
        self.poses_pub.publish(msg)
        if self.pose_array_pub.get_subscription_count() > 0:
            self.pose_array_pub.publish(self.pose_array(tb.poses, stamp))
        self.publish_status(stamp)

    @staticmethod
    def pose_array(poses, stamp):
        out = PoseArray()
        out.header.stamp = stamp
        out.header.frame_id = "arena"
        for x, y, theta in poses.T:
            pose = Pose()
            pose.position.x, pose.position.y = float(x), float(y)
            pose.orientation.z, pose.orientation.w = math.sin(theta / 2), math.cos(theta / 2)
            out.poses.append(pose)
        return out

    def publish_status_heartbeat(self):
        # Real-time runs publish status every tick; idle and lockstep (which may wait) once a second.
        if self.testbed is None or not self.real_time:
            self.publish_status()

    def publish_status(self, stamp=None):
        tb = self.testbed
        msg = TestbedStatus()
        msg.header.stamp = stamp or self.get_clock().now().to_msg()
        msg.header.frame_id = "arena"
        msg.experiment = self.experiment
        msg.run_id = self.run_id
        msg.mode = "realtime" if self.real_time else "lockstep"
        msg.commands_accepted = self.commands_accepted
        msg.dropped_nonfinite = self.dropped["nonfinite"]
        msg.dropped_length_mismatch = self.dropped["length_mismatch"]
        msg.dropped_unknown_id = self.dropped["unknown_id"]
        msg.safety_interventions = self.safety_interventions
        if tb is None:
            msg.state = TestbedStatus.STATE_IDLE
        else:
            msg.state = TestbedStatus.STATE_RUNNING
            msg.number_of_robots = tb.number_of_robots
            msg.step = tb.steps
            copy_counters(tb, msg)
        self.status_pub.publish(msg)


def main(args=None):
    return run_node(SimulatorNode, "simulator", args)


if __name__ == "__main__":
    sys.exit(main())
