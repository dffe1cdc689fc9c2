"""The hardware arena node: the simulator's place in the testbed, moving a lab's own robots.

It is the simulator node (robotarium_sim.simulator_node: the same topics, services, status,
experiment life, secrets, model.StepGate, command timeout and counters; node name `simulator`)
with the world replaced by the fleet of a fleet file (robotarium_hardware.fleet): each robot's
cmd_vel out at 30 Hz, its pose in from motion capture or the tag tracker, the roster on
<ns>/fleet. A start takes the first N robots present and tracked, drives them onto the initial
conditions (rps2.DriveOn, under the safety node), then runs in real time; a robot that loses
tracking or stops answering stops every robot and ends the run. How: docs/own-robots.md.

    ros2 run robotarium_hardware arena --ros-args -r __ns:=/robotarium -p fleet_file:=fleet.yaml \
        --params-file install/share/robotarium_core/config/testbed.yaml
"""
import dataclasses
import json
import sys
import threading
import time

import numpy as np
from geometry_msgs.msg import PoseStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import BatteryState
from std_msgs.msg import String

from robotarium_core import cdr, control, kinematics, model, outcomes, presence, rps2
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.node_main import run_node
from robotarium_core.parameters import declare_parameter
from robotarium_core.subscriptions import take_waiting
from robotarium_core.topics import CMD_REQUESTED, LATCHED, OUTPUT_QOS, readers_matched
from robotarium_hardware import fleet as fleets
from robotarium_hardware.steady import steady
from robotarium_hardware.tracking import FleetTestbed, Roster
from robotarium_msgs.msg import TwistArray
from robotarium_sim import experiment
from robotarium_sim.experiment import Experiment
from robotarium_sim.simulator_node import SimulatorNode, arm_request

FLEET = "fleet"               # the roster topic (relative to the namespace)
# s between looks for a robot that lost tracking or stopped answering: a hidden tag is known only SETTLE after the
# frame without it came, so each ms of this period's phase is a ms more that every robot drives on (budget 0.2 s)
FAULT_CHECK = 0.005
STALLED = 0.03                # s since the last look that mean this process stalled (its poses may still wait)
ROSTER_PERIOD = 1.0           # s between roster messages
START_READY_WAIT = 1.0        # s a start waits for the robots it needs to be present and tracked before it refuses
# 2.x's drive-on controller (robotarium_client robotarium2.DRIVE_ON_CONTROLLER), from core's control laws; it
# stops driving within position_error - position_epsilon (2 cm) and turning within rotation_error (0.03 rad),
# inside the fleet's drive_on_position_error and drive_on_rotation_error (3 cm, 0.05 rad: 2.x's 0.1 rad would not do).
DRIVE_ON = dict(linear_velocity_gain=0.8, angular_velocity_limit=np.pi / 3, speed_limit=0.15, position_error=0.05,
                position_epsilon=0.03, rotation_error=0.03)
DRIVE_ON_STEP_WAIT = 2.0      # s the drive-on waits for the next tick before it gives up


def drive_on_controller(states, goals, approach):
    """2.x's hybrid pose controller (create_pose_controller_hybrid with the drive-on's gains), on core's
    control laws: f(states, goals, approach) -> (dxu, approach)."""
    d = DRIVE_ON

    def si_to_uni(dxi, x):
        return kinematics.si_to_uni_heading(dxi, x[2], d["linear_velocity_gain"], d["angular_velocity_limit"],
                                            gain_in_angle=False, no_spin_at_rest=False)
    dxu, approaching, turning = control.hybrid_pose_step(
        states, goals, approach != 0, si_to_uni, speed_limit=d["speed_limit"], turn_gain=2,
        position_error=d["position_error"], position_epsilon=d["position_epsilon"], rotation_error=d["rotation_error"])
    approach = approach.copy()
    approach[turning] = approaching[turning]
    return dxu, approach


class DriveOnAborted(Exception):
    pass


class HardwareArenaNode(SimulatorNode):
    def __init__(self):
        super().__init__()
        path = declare_parameter(self, "fleet_file", "", "the fleet file: the robots, their topics, tracking and "
                                 "calibration (robotarium_hardware.fleet)")
        if not path:
            raise ValueError("no fleet file: pass -p fleet_file:=FILE (./robotarium up --fleet FILE; "
                             "./robotarium fleet writes one for a simulated fleet)")
        self.fleet = fleets.load(path)   # FleetError (a ValueError): run_node says it and exits 2
        self.roster = Roster(self.fleet)
        # what the safety node widens its margins by (ArmSafety.latency): the fleet's declared latencies
        self.latency = self.fleet.command_latency + self.fleet.tracking_latency
        self.driving = False
        self._drive_abort = None
        self._last_check = time.monotonic()
        self._stepped = threading.Condition()
        self.command_pubs = []
        self._twists = []
        self.inputs = []   # (subscription, what to do with a message): the poses and signs of life
        for i, robot in enumerate(self.fleet.robots):
            stamped = robot.cmd_type == "TwistStamped"
            self.command_pubs.append(self.create_publisher(TwistStamped if stamped else Twist,
                                                           self.fleet.cmd_topic(robot), 10))
            self._twists.append(TwistStamped() if stamped else Twist())
            self.inputs.append((self.create_subscription(
                PoseStamped, self.fleet.pose_topic(robot), lambda data, i=i: self.roster.pose_message(
                    i, data, time.monotonic()), qos_profile_sensor_data, raw=True),
                lambda data, now, i=i: self.roster.pose_message(i, data, now)))
            if robot.answer_topic:
                self.inputs.append((self.create_subscription(
                    Odometry, robot.answer_topic, lambda data, i=i: self.roster.answer(i, time.monotonic()),
                    qos_profile_sensor_data, raw=True), lambda data, now, i=i: self.roster.answer(i, now)))
            if robot.battery_topic:
                self.create_subscription(BatteryState, robot.battery_topic,
                                         lambda msg, i=i: self.roster.battery_state(i, msg.percentage),
                                         qos_profile_sensor_data)
        # The drive-on phase's commands go through the safety node like a client's.
        self.drive_pub = self.create_publisher(TwistArray, CMD_REQUESTED, OUTPUT_QOS)
        self.roster_pub = self.create_publisher(String, FLEET, LATCHED)
        self.create_timer(FAULT_CHECK, self.check_faults)
        self.create_timer(ROSTER_PERIOD, self.publish_roster)
        scheduling = steady()
        self.get_logger().info("hardware arena ready: fleet %s, %d robots (%s), tracking %s; %s" % (
            self.fleet.name, len(self.fleet.robots), ", ".join(self.fleet.names), self.fleet.tracking, scheduling))

    # -- a start -----------------------------------------------------------------------------------

    async def on_start(self, request, response):
        if request.name != "!":   # (the client's first, always refused probe)
            request.real_time = True    # real robots have no lockstep
            request.hardware = False    # nor a model of hardware: they are the hardware
            # Robots a moment behind (one odometry message a loaded machine held back past answer_timeout: a
            # start was refused "r2 not answering", 2026-11-30) are waited for a little before the start is refused.
            deadline = time.monotonic() + START_READY_WAIT
            while np.count_nonzero(self.roster.ready(time.monotonic())) < request.number_of_robots \
                    and time.monotonic() < deadline:
                await self.sleep(0.02)
        return await super().on_start(request, response)

    def build_testbed(self, request):
        if request.api == rps2.API:
            raise model.RobotariumError("this testbed moves the robots of fleet %s, for scripts of the guide's API "
                                        "(rps); 2.x scripts (sensors, obstacles, charger slots) run on the simulator "
                                        "(./robotarium run without a fleet)." % self.fleet.name)
        name, planned = experiment.build_testbed(request, self.config)   # the request's checks, its initial conditions
        robots = self.roster.pick(planned.number_of_robots, time.monotonic())
        self.roster.in_the_way(robots, time.monotonic(), self.config.arena)
        return name, FleetTestbed(planned.poses, self.config, robots, lambda: self.roster.measured(robots), self.latency)

    async def before_arming(self, request, testbed, run):
        """The drive-on phase: from where the robots stand to the initial conditions (testbed.poses), as a
        run of its own (own secrets, the safety node armed for it, not recorded); then the experiment's
        testbed starts from the poses measured there. None, or why the start is refused."""
        goals, robots = testbed.poses.copy(), testbed.robots
        start = self.roster.measured(robots)
        c = dataclasses.replace(self.config, drive_on_position_error=self.fleet.drive_on_position_error,
                                drive_on_rotation_error=self.fleet.drive_on_rotation_error)
        if not model.at_pose_mask(start, goals, c.drive_on_position_error, c.drive_on_rotation_error).all():
            try:
                drive_testbed = FleetTestbed(start, c, robots, lambda: self.roster.measured(robots), self.latency)
            except model.RobotariumError as error:
                return "the robots cannot drive on from where they stand: %s" % error
            problem = await self.drive_on(run.run_id, drive_testbed, goals, c)
            if problem is not None:
                return problem
        testbed.poses = self.roster.measured(robots)
        return None

    async def drive_on(self, run_id, testbed, goals, config):
        drive = Experiment.started(run_id + "_drive_on", "drive_on", True)
        n = testbed.number_of_robots
        armed = await self.arm_safety(arm_request(drive, testbed, self.recorded()))
        if armed is not True:
            return armed
        self.get_logger().info("driving %d robots (%s) on to the initial conditions of %s" % (
            n, ", ".join(self.fleet.robots[i].name for i in testbed.robots), run_id))
        previous, self.run, self.testbed, self.driving, self._drive_abort = self.run, drive, testbed, True, None
        self._tick_timer = self.create_timer(1.0 / self.config.rate, self.tick)
        result = {}
        try:
            deadline = time.monotonic() + 10.0
            while not readers_matched(self, self.drive_pub, "safety") and time.monotonic() < deadline:
                await self.sleep(0.01)
            # No barrier of its own (the safety node is the barrier) and no waves: robots start wherever they stand.
            drive_on = rps2.DriveOn(goals, config, drive_on_controller, lambda dxu, x: dxu, np.random.default_rng(),
                                    waves=False)
            thread = threading.Thread(target=self._drive, args=(drive_on, drive, testbed, result), daemon=True)
            thread.start()
            while thread.is_alive():
                await self.sleep(0.02)
        finally:
            self.stop_ticking()
            self.send_zeros()
            self.testbed, self.run, self.driving = None, previous, False
        if "error" in result:
            self.disarm_safety()   # (after a drive-on that worked, the experiment's arming follows at once)
            return "the drive-on phase failed: %s" % result["error"]
        self.get_logger().info("at the initial conditions of %s after %d steps" % (run_id, result["steps"]))
        return None

    def _drive(self, drive_on, drive, testbed, result):
        """The drive-on loop (its own thread: DriveOn.run waits for each tick in step())."""
        ids = np.arange(testbed.number_of_robots)

        def set_velocities(dxu):
            sec, nanosec = self.get_clock().now().seconds_nanoseconds()
            self.drive_pub.publish(cdr.TWIST_ARRAY.build(sec=sec, nanosec=nanosec, frame_id="arena", token=drive.token,
                                                         step=0, ids=ids, twists=cdr.twists(dxu[0], dxu[1])))

        def step():
            with self._stepped:
                steps = testbed.steps
                if not self._stepped.wait_for(lambda: testbed.steps > steps or self._drive_abort,
                                              DRIVE_ON_STEP_WAIT):
                    raise DriveOnAborted("no tick for %.0f s" % DRIVE_ON_STEP_WAIT)
            if self._drive_abort:
                raise DriveOnAborted(self._drive_abort)
        try:
            result["steps"] = drive_on.run(lambda: testbed.poses.copy(), set_velocities, step)
        except (DriveOnAborted, model.RobotariumError) as error:
            result["error"] = str(error)

    # -- real time ---------------------------------------------------------------------------------

    def tick(self):
        tb = self.testbed
        if tb is None:
            return
        now = self.get_clock().now()
        self.run.last_tick = time.monotonic()
        self.expire_commands(tb)
        tb.step()   # counts on the poses before, then takes the newest measured ones
        self.run.tally.after_step(tb)
        self.send_commands(tb.robots, tb.commands_out(), now)
        self.publish_state(now)
        with self._stepped:
            self._stepped.notify_all()

    def send_commands(self, robots, dxu, now=None):
        stamp = (now or self.get_clock().now()).to_msg()
        for k, i in enumerate(robots):
            msg = self._twists[i]
            twist = msg.twist if isinstance(msg, TwistStamped) else msg
            if isinstance(msg, TwistStamped):
                msg.header.stamp = stamp
                msg.header.frame_id = self.fleet.robots[i].name
            twist.linear.x, twist.angular.z = float(dxu[0, k]), float(dxu[1, k])
            self.command_pubs[i].publish(msg)

    def send_zeros(self):
        """Every robot of the fleet stops."""
        everyone = np.arange(len(self.fleet.robots))
        self.send_commands(everyone, np.zeros((2, len(everyone))))

    def check_faults(self):
        tb, now = self.testbed, time.monotonic()
        late, self._last_check = now - self._last_check > STALLED, now
        if tb is None or late:
            return   # a check this late means this process stalled: its poses may still wait in its queues
        # Everything that came is counted first (the executor may not have got to every subscription yet).
        for subscription, handle in self.inputs:
            for data in take_waiting(subscription):
                handle(data, now)
        faults = self.roster.faults(tb.robots, now)
        if not faults:
            return
        self.send_zeros()   # at once: every robot stops
        cause = "%s at step %d%s" % ("; ".join(faults), tb.steps, " of the drive-on" if self.driving else "")
        self.get_logger().warning("%s (%s)" % (cause, "; ".join(
            "%s: pose %.0f ms ago, stamp %.0f ms behind, answer %.0f ms ago" % (
                self.fleet.robots[i].name, 1e3 * (now - self.roster.pose_at[i]),
                1e3 * (np.nanmax(self.roster.stamps) - self.roster.stamps[i]), 1e3 * (now - self.roster.answer_at[i]))
            for i in tb.robots)))
        if self.driving:
            with self._stepped:
                self._drive_abort = cause
                self._stepped.notify_all()
            self.stop_ticking()
            return
        self.get_logger().warning("%s: every robot stops; ending %s" % (cause, self.run.run_id))
        self.end_experiment(cause, outcome=outcomes.INTERRUPTED, detail="interrupted: %s" % cause)

    def publish_status(self, stamp=None):
        if not self.driving:   # the drive-on is no experiment: the status says the last one's end until the next starts
            super().publish_status(stamp)

    def end_experiment(self, reason, response=None, outcome=outcomes.INTERRUPTED, detail=""):
        response = super().end_experiment(reason, response, outcome, detail)
        self.send_zeros()
        return response

    def wind_down(self, reason):
        done = super().wind_down(reason)
        self.send_zeros()
        return done

    def publish_roster(self):
        now = time.monotonic()
        self.roster_pub.publish(String(data=json.dumps({
            "fleet": self.fleet.name, "tracking": self.fleet.tracking,
            "robots": [dict(name=s.name, tracked=s.tracked, answering=s.answering,
                            battery=None if np.isnan(s.battery) else round(s.battery, 1),
                            pose_age=None if np.isinf(s.pose_age) else round(s.pose_age, 3), dropped=s.dropped)
                       for s in self.roster.states(now)]})))


USAGE = """usage: ros2 run robotarium_hardware arena --ros-args -r __ns:=/robotarium -p fleet_file:=FILE
                                        [--params-file testbed.yaml]

The hardware arena: the simulator's place in the testbed, moving the robots of a fleet file (their
cmd_vel out; their poses from motion capture or the tag tracker in). ./robotarium up --fleet FILE starts
it with the safety node and the recorder. See docs/own-robots.md."""


def main(args=None):
    if "--help" in (args or sys.argv) or "-h" in (args or sys.argv)[1:2]:
        print(USAGE)
        return 0
    return run_node(HardwareArenaNode, "arena", args, claim=presence.SIMULATOR, watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
