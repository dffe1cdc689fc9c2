"""The Robotarium simulator node: a thin ROS 2 shell around robotarium_core.model.Testbed and
robotarium_sim.experiment (what a start asks for, the run's id, secrets and counters).

It takes the safety node's cmd_safe (read as CDR bytes; only arrays with the run's safety key and
the step they produce, model.StepGate) and publishes poses, status, the viewers' topics and a 2.x
experiment's sensors; it serves start_experiment and end_experiment and arms the safety node.
Real time (a timer at `rate` Hz, the command timeout) or lockstep (one step per accepted array),
ideal or hardware-like (robotarium_sim.hardware), chosen per experiment. An experiment belongs to
the client that started it and ends by itself when that client is gone.

The specification (topics, secrets, modes, the step gate): docs/simulator.md.
"""
import array
import secrets
import sys
import time
from itertools import chain

import numpy as np
from geometry_msgs.msg import PoseArray
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.serialization import serialize_message
from rclpy.task import Future
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from robotarium_core import cdr, markers, model, outcomes, presence, restarts, rps2, scene
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.line import Line
from robotarium_core.node_main import run_node
from robotarium_core.parameters import declare_config, declare_parameter
from robotarium_core.subscriptions import take_waiting
from robotarium_core.topics import (
    CMD_SAFE,
    CONFIG,
    DEFAULT_NAMESPACE,
    END_EXPERIMENT,
    EXPERIMENT,
    LATCHED,
    LISTENERS_WAIT,
    MARKERS,
    OBSTACLES,
    OUTPUT_QOS,
    POSE_ARRAY,
    POSE_ARRAY_QOS,
    POSES,
    RECORDING,
    SAFETY_ARM,
    SAFETY_REPORT,
    SAFETY_REPORT_QOS,
    SENSORS,
    START_EXPERIMENT,
    STATUS,
    STATUS_QOS,
    STATUS_STREAM,
    STATUS_STREAM_QOS,
    VIEWER_QOS,
    command_input_qos,
    listeners,
    node_names,
    warn_on_incompatible_qos,
)
from robotarium_msgs.msg import DropCounts, RobotPoses, SafetyReport, SensorReadings, TestbedStatus, TwistArray
from robotarium_msgs.srv import ArmSafety, EndExperiment, StartExperiment
from robotarium_sim import rps2_io
from robotarium_sim.experiment import Experiment, RunIds, build_testbed

SAFETY_WAIT = 10.0          # s a start waits for the safety node to answer (discovery is slow on a loaded machine)
SAFETY_WAIT_SETTLED = 2.0   # s it waits when the simulator has run longer than SAFETY_WAIT without seeing one (or
                            # since it lost one)
ARM_RESEND = 1.0            # s before an unanswered ArmSafety request is sent again
REARM_POLL = 0.1            # s between looks at a re-arm that is due (a safety node back during a run)
REPORT_WAIT = 3.0           # s an end waits for the safety node's reports of the arrays already applied
# s after a run's end in which stopping still waits for its IDLE status to be acknowledged: a run ended by its
# client as the lifeline fires ends ms before the stop; after a script that exited (`run` stops its testbed once
# the script's process is gone, 0.3 s or more) a reader of it not yet unmatched would never answer
ENDED_JUST_NOW = 0.5
CLIENT_DISCOVERY_WAIT = 10.0  # s after a start for the client's presence to appear before it counts as lost


class NoSafetyNode(str):
    """Why a start is refused when no safety node answered within the wait (arm_safety): the testbed is
    incomplete, its fault and not the request's; the start's response says so (`incomplete`), so a client
    tells it apart from every other refusal, whose words it passes on."""


def drop_counts(counts):
    """{reason: count} -> robotarium_msgs/DropCounts."""
    return DropCounts(**counts)


def to_float_array(values):
    """numpy float64 vector -> array.array('d') without a Python loop (what rclpy stores for float64[])."""
    return array.array("d", np.ascontiguousarray(values, dtype=np.float64).tobytes())


def copy_counters(testbed, target, tally=None):
    """The debug report's counters and the sim time (and the run's tally: first error steps, what
    the safety layer did), into a status message or an end response."""
    target.sim_time = testbed.sim_time
    target.collisions = testbed.collisions
    target.boundary_violations = testbed.boundary_violations
    if tally is not None:
        target.first_collision_step = tally.first_collision_step
        target.first_boundary_step = tally.first_boundary_step
        target.intervention_max_change = tally.largest_change
        target.intervention_change_sum = tally.change_sum
    target.actuator_limit_iterations = testbed.actuator_limit_iterations
    target.command_timeouts = testbed.command_timeouts
    target.hardware = testbed.seed is not None
    target.hardware_seed = testbed.seed or 0


STOPS = (SafetyReport.STATUS_STOP_NO_POSES, SafetyReport.STATUS_STOP_SOLVER_FAILED, SafetyReport.STATUS_STOP_BAD_INPUT)


def is_intervention(report, tolerance):
    """A safety intervention (SafetyReport.msg): a stop or a solved QP that changed a command beyond
    the tolerance (model.is_intervention). Scaling a command to the actuator limits is the
    thresholding's work, not an intervention."""
    return model.is_intervention(report.status in STOPS or report.status == SafetyReport.STATUS_SOLVED,
                                 report.max_change, tolerance)


class SimulatorNode(Node):
    def __init__(self):
        super().__init__("simulator", namespace=DEFAULT_NAMESPACE)
        self.config = declare_config(self)
        # The streams are volatile (robotarium_core.topics): a start waits for the readers a run needs.
        self.wait_for_recorder = declare_parameter(
            self, "wait_for_recorder", False, "true: a start waits for the recorder's readers even where the graph "
            "shows no recorder yet (./robotarium up and the launch file set it when they start one), so a run's first "
            "steps are never missing from its bag")
        self.listeners_wait = declare_parameter(
            self, "listeners_wait", LISTENERS_WAIT, "s a start waits for the readers a run needs (its client's, the "
            "safety node's, the recorder's) before it goes on without them, saying whose were missing",
            low=0.0, high=60.0)
        self.testbed = None          # the running experiment's model (None: idle)
        self.run = Experiment()      # the running experiment, or the last one (how it ended)
        self._ended_at = -np.inf     # monotonic time the last experiment ended (wind_down)
        self.run_ids = RunIds()
        self.recording = ""
        self._tick_timer = None
        self._starting = False
        self.client_watch = None
        self._client_deadline = None
        self.line = Line(self.config.line_lease)   # clients waiting for the testbed, first come first served

        self.poses_pub = self.create_publisher(RobotPoses, POSES, OUTPUT_QOS)
        self.pose_array_pub = self.create_publisher(PoseArray, POSE_ARRAY, POSE_ARRAY_QOS)
        # Viewers get the scene at viewer_rate, not every step (lockstep runs hundreds a second).
        self.markers_pub = self.create_publisher(MarkerArray, MARKERS, VIEWER_QOS)
        self.trails = scene.Trails(self.config.trail_length, self.config.time_step)
        self.status_pub = self.create_publisher(TestbedStatus, STATUS, STATUS_QOS)   # the newest only
        self.status_stream_pub = self.create_publisher(TestbedStatus, STATUS_STREAM, STATUS_STREAM_QOS)   # every one
        # The configuration of the running experiment, for the recorder and the report.
        self.config_pub = self.create_publisher(String, CONFIG, LATCHED)
        # The 2.x API's extras (robotarium_sim.rps2_io): sensors, the experiment's settings, obstacles.
        self.sensors_pub = self.create_publisher(SensorReadings, SENSORS, OUTPUT_QOS)
        self.experiment_pub = self.create_publisher(String, EXPERIMENT, LATCHED)
        self.obstacles_pub = rps2_io.obstacles_publisher(self, OBSTACLES, LATCHED)
        # The same sensors per robot on standard types for ROS tools, throttled by simulated time.
        self.standard_sensors = rps2_io.StandardSensors(self, self.config.standard_sensor_rate)
        self.commands = self.create_subscription(TwistArray, CMD_SAFE, self.on_commands,
                                                 command_input_qos(self.config.command_queue_depth), raw=True,
                                                 event_callbacks=warn_on_incompatible_qos(self, CMD_SAFE))
        # Raw (cdr.SAFETY_REPORT): one comes every lockstep step, and rclpy's message object (a nested
        # DropCounts) cost more than the step's model.
        self.safety_reports = self.create_subscription(SafetyReport, SAFETY_REPORT, self.on_safety_report,
                                                      SAFETY_REPORT_QOS, raw=True)
        self._requested_drops = (None, None)   # (the safety node's drop counts, as a DropCounts): made when they change
        self.create_subscription(String, RECORDING, self.on_recording, LATCHED)
        # A start waits for the safety node's answer (a coroutine): in a group of its own, so that
        # the node's other callbacks (that answer among them) run meanwhile.
        self.create_service(StartExperiment, START_EXPERIMENT, self.on_start,
                            callback_group=MutuallyExclusiveCallbackGroup())
        # An end waits for the safety node's last reports (a coroutine): in a group of its own too.
        self.create_service(EndExperiment, END_EXPERIMENT, self.on_end, callback_group=MutuallyExclusiveCallbackGroup())
        self.arm_client = self.create_client(ArmSafety, SAFETY_ARM)
        self.presence = presence.Presence(self, presence.alive_topic(presence.SIMULATOR), self.config.node_lease)
        self.ready_at = time.monotonic()
        self.safety_watch = presence.Watch(self, presence.alive_topic(presence.SAFETY), self.config.node_lease,
                                           on_lost=self.on_safety_lost, on_seen=self.on_safety_seen)
        self._rearm = None   # (run id, the ArmSafety future or None, when it was sent) while a re-arm is due
        self._safety_lost_at = -np.inf   # monotonic time the safety node's presence was last lost
        self.create_timer(REARM_POLL, self.rearm_safety)
        # ... due too when ./robotarium up announces it restarted the safety node (should its new presence be missed)
        self.create_subscription(String, restarts.topic(presence.SAFETY), lambda msg: self.on_safety_seen(),
                                 restarts.QOS)
        self.create_timer(1.0, self.publish_status_heartbeat)
        self.create_timer(1.0 / self.config.viewer_rate, self.publish_markers)
        self.create_timer(0.2, self.check_client)
        self.config_pub.publish(String(data=self.config.to_yaml()))
        self.get_logger().info("simulator ready in namespace %s" % self.get_namespace())

    # -- experiments -------------------------------------------------------------------------

    def holding(self):
        """Who holds the testbed, for those waiting: holder, run, since when, step."""
        if self.testbed is None:
            return "an experiment that is starting"
        return "%s: run %s since %s, step %d" % (self.run.holder or "a client", self.run.run_id, self.run.started_at,
                                                 self.testbed.steps)

    async def on_start(self, request, response):
        response.success = False
        now = time.monotonic()
        self.line.prune(now)
        if self.testbed is not None or self._starting or self.line.first() not in (None, request.ticket):
            # Busy, or others waited first: refused; with `wait`, a place in the line (first come, first served).
            response.busy = True
            busy = self.testbed is not None or self._starting
            response.holding = self.holding() if busy else "nobody (the next in line starts now)"
            if request.wait:
                response.ticket = self.line.join(request.ticket, request.holder or "a client", now)
                response.place = self.line.place(response.ticket)
            response.message = ("the testbed is busy: its experiment is still running (%s); %d waiting%s. It is free when "
                                "that experiment ends (its client ends it, or is gone for %g s; ./robotarium end --force "
                                "is the operator's override)." % (response.holding, len(self.line.entries),
                                   ", you are number %d" % response.place if response.place else "",
                                   self.config.client_lease))
            return response
        self.line.leave(request.ticket)
        c = self.config
        try:
            name, testbed = self.build_testbed(request)
        except model.RobotariumError as error:
            response.message = str(error)
            return response
        n = testbed.number_of_robots
        run = Experiment.started(self.run_ids.new(name), name, request.real_time, audit=request.audit,
                                 holder=request.holder)
        self._starting = True
        try:
            armed = await self.before_arming(request, testbed, run)
            if armed is None:
                armed = await self.arm_safety(arm_request(run, testbed, self.recorded()))
            if armed is True:
                if isinstance(testbed, rps2.Testbed2):
                    self.standard_sensors.start(testbed)
                await self.wait_for_listeners(request.client_node, testbed)
        finally:
            self._starting = False
        if armed is not True:
            response.message = armed
            response.incomplete = isinstance(armed, NoSafetyNode)
            return response

        self.testbed, self.run = testbed, run
        self.trails.reset()
        self.watch_client(run.run_id)
        if run.real_time:
            self._tick_timer = self.create_timer(1.0 / c.rate, self.tick)
        now = self.get_clock().now()
        run.started_ns = now.nanoseconds
        self.publish_state(now)
        # After the first RUNNING status, so that the recorder keeps them in the run's bag.
        self.config_pub.publish(String(data=c.to_yaml()))
        self.experiment_pub.publish(String(data=rps2_io.settings_yaml(self.run.run_id, request.api, self.testbed)))
        rps2_io.publish_obstacles(self, self.obstacles_pub, self.testbed)
        response.success = True
        response.run_id = self.run.run_id
        response.real_time = run.real_time
        response.token = run.token
        response.poses_key = run.poses_key
        response.client_alive_topic = self.client_watch.subscription.topic_name
        response.client_lease = c.client_lease
        response.x, response.y, response.theta = (to_float_array(row) for row in self.testbed.poses)
        response.message = "started %s: %d robots, %s%s%s" % (
            self.run.run_id, n, "real time at %g Hz" % c.rate if self.run.real_time else "lockstep",
            "" if self.testbed.seed is None else ", hardware-like (seed %d)" % self.testbed.seed,
            ", audited for verification (the safety node lets the script's commands through)" if self.run.audit else "")
        self.get_logger().info(response.message)
        return response

    def build_testbed(self, request):
        """The model a start asks for and the experiment's name (experiment.build_testbed); an arena
        of another kind (robotarium_hardware's) makes its own."""
        return build_testbed(request, self.config)

    async def before_arming(self, request, testbed, run):
        """What an arena does before the safety node is armed for a new experiment `run` on `testbed`:
        nothing here; robotarium_hardware's arena drives its robots to the initial conditions. None to
        go on, or why the start is refused."""
        return None

    async def arm_safety(self, request):
        """Hand the safety node the experiment to guard; True, or why it could not be done. The
        request is sent again every ARM_RESEND s: a safety node started a moment ago may not have
        matched it yet (and one killed a moment ago may still look present), and arming is the
        same however often it is done. A simulator up longer than SAFETY_WAIT that sees no safety node
        alive, and lost none in that time, has given discovery its time: it waits only SAFETY_WAIT_SETTLED
        (one just started) so that a client of an incomplete testbed hears it in moments, not after 10 s. One
        lost a moment ago may be back under a new participant not yet discovered (restarted in place, or by up:
        a client right after a restart in place was told "no safety node answers" 2 s later, a loaded machine)."""
        now = time.monotonic()
        settled = (now - max(self.ready_at, self._safety_lost_at) > SAFETY_WAIT) and not self.safety_watch.alive
        wait = SAFETY_WAIT_SETTLED if settled else SAFETY_WAIT
        deadline = now + wait
        while not self.arm_client.service_is_ready():
            if time.monotonic() > deadline:
                return NoSafetyNode("no safety node answers on %s within %.0f s: without it the robots cannot move. "
                                    "Is the testbed complete (./robotarium up starts all of it)?"
                                    % (self.arm_client.srv_name, wait))
            await self.sleep(0.05)
        if settled:   # one appeared after all: it gets the usual time to answer
            deadline = time.monotonic() + SAFETY_WAIT
        while time.monotonic() < deadline:
            future = self.arm_client.call_async(request)
            resend = time.monotonic() + ARM_RESEND
            while not future.done() and time.monotonic() < min(resend, deadline):
                await self.sleep(0.01)
            if future.done():
                result = future.result()
                return True if result.success else "the safety node refused the experiment: %s" % result.message
            self.arm_client.remove_pending_request(future)
        return NoSafetyNode("the safety node did not answer on %s within %.0f s." % (self.arm_client.srv_name, SAFETY_WAIT))

    def recorded(self):
        """Whether a recorder records this testbed's runs (./robotarium up's, or one the graph shows)."""
        return self.wait_for_recorder or presence.RECORDER in node_names(self)

    async def wait_for_listeners(self, client_node, testbed):
        """The streams are volatile (robotarium_core.topics): a run's first poses, status and sensors
        go out once the readers that need all of the run matched our writers (the client's, the safety
        node's, the recorder's), or after listeners_wait s, with a warning naming the missing ones."""
        # every reader the graph shows already; the safety node's and the recorder's where the graph
        # shows them (a test's stand-in for the safety node is not one); the client's, which named itself
        pairs = [(self.poses_pub, None), (self.status_stream_pub, None), (self.sensors_pub, None)]
        second_api = isinstance(testbed, rps2.Testbed2)
        if client_node:
            pairs += [(self.poses_pub, client_node)] + ([(self.sensors_pub, client_node)] if second_api else [])
        nodes = node_names(self)
        if presence.SAFETY in nodes:
            pairs.append((self.poses_pub, presence.SAFETY))
        if self.wait_for_recorder or presence.RECORDER in nodes:
            recorded = [self.poses_pub, self.pose_array_pub, self.status_stream_pub, self.sensors_pub]
            if second_api:
                recorded += [p for row in self.standard_sensors.publishers[:testbed.number_of_robots] for p in row[:3]]
            pairs += [(publisher, presence.RECORDER) for publisher in recorded]
        deadline = time.monotonic() + self.listeners_wait
        while missing := listeners(self, pairs):
            if time.monotonic() > deadline:
                self.get_logger().warning("starting without %s: not matched within %g s (a slow machine? their "
                                          "first samples may be lost)" % (", ".join(sorted(
                                              "%s's reader of %s" % (who or "a", p.topic_name) for p, who in missing)),
                                              self.listeners_wait))
                return
            await self.sleep(0.005)

    async def sleep(self, seconds):
        """Wait inside a coroutine callback while the executor goes on serving the others."""
        done = Future()
        timer = self.create_timer(seconds, lambda: done.done() or done.set_result(None))
        try:
            await done
        finally:
            self.destroy_timer(timer)

    def disarm_safety(self):
        if self.arm_client.service_is_ready():
            self.arm_client.call_async(ArmSafety.Request())   # nothing waits for it: the keys are dead anyway

    def watch_client(self, run_id):
        """Follow the presence of this experiment's client on a topic of its own."""
        topic = presence.alive_topic("client_" + secrets.token_hex(8))
        self.client_watch = presence.Watch(self, topic, self.config.client_lease, on_lost=self.on_client_lost)
        self._client_deadline = time.monotonic() + CLIENT_DISCOVERY_WAIT + self.config.client_lease

    def check_client(self):
        if self.testbed is None or self.client_watch is None:
            return
        # Its liveliness still missing (lost once its arrays stopped too), or a client that never showed
        # up (gone before its presence was discovered).
        if self.client_watch.lost or (not self.client_watch.seen and time.monotonic() > self._client_deadline):
            self.on_client_lost()

    def on_client_lost(self):
        # The liveliness assertions come from a thread of the client's DDS participant, which a starved
        # machine can hold back for seconds while the client's arrays keep coming (a lockstep client was
        # ended at step 1520 of a run it was driving): arrays of its run within the lease are a sign too.
        if self.testbed is None or time.monotonic() - self.run.last_command_at <= self.config.client_lease:
            return   # (check_client asks again)
        # The step of its last command: where its script stopped (in real time the testbed ticked on).
        self.get_logger().warning("the client of %s is gone (no sign of it for %g s; its last command came at "
                                  "step %d): ending the experiment at step %d" % (
                                      self.run.run_id, self.config.client_lease, self.run.last_command_step,
                                      self.testbed.steps))
        self.end_experiment("client lost at step %d" % self.run.last_command_step, outcome=outcomes.CLIENT_LOST,
                            detail="the testbed ended it at step %d: its client was gone for %g s (its last "
                            "command came at step %d)" % (self.testbed.steps, self.config.client_lease,
                                                          self.run.last_command_step))

    def on_safety_lost(self):
        self._safety_lost_at = time.monotonic()
        if self.testbed is not None:
            self.get_logger().warning("the safety node is gone: every robot stops")
            self.testbed.set_commands(np.arange(self.testbed.number_of_robots), 0.0, 0.0, now=time.monotonic())

    def on_safety_seen(self):
        """A safety node's presence came (back) during a run: one restarted mid-run guards nothing until it is
        armed again, with the run's keys and where the robots are; the run then goes on (docs/faults.md).
        One that guards the run already (its presence only lapsed) says so and changes nothing."""
        if self.testbed is not None and self._rearm is None:
            self._rearm = (self.run.run_id, None, 0.0)

    def rearm_safety(self):
        """Every REARM_POLL s while a re-arm is due: ask (again after ARM_RESEND), and take the answer."""
        if self._rearm is None:
            return
        run_id, future, sent = self._rearm
        if self.testbed is None or self.run.run_id != run_id:   # that run ended meanwhile
            if future is not None:
                self.arm_client.remove_pending_request(future)
            self._rearm = None
            return
        if future is not None and future.done():
            self._rearm = None
            result = future.result()
            if not result.success:
                self.get_logger().error("could not arm the safety node again for %s: %s" % (run_id, result.message))
            elif not result.already_armed:
                self.run.safety_rearmed()
                self.get_logger().warning("the safety node was restarted: armed it again for %s at step %d; the run "
                                          "goes on" % (run_id, self.testbed.steps))
                self.publish_status()   # (its safety_rearms tells the client to send its array again)
            return
        if future is not None and time.monotonic() - sent < ARM_RESEND:
            return
        if future is not None:
            self.arm_client.remove_pending_request(future)
        if self.arm_client.service_is_ready():
            future = self.arm_client.call_async(arm_request(self.run, self.testbed, self.recorded(), mid_run=True))
            self._rearm = (run_id, future, time.monotonic())

    async def on_end(self, request, response):
        if self.testbed is None:
            response.success = False
            response.message = "no experiment is running."
            return response
        if request.token != self.run.token and not request.force:
            response.success = False
            response.message = (
                "experiment %s belongs to the client that started it (this request does not carry its token). "
                "It ends when that client ends it or is gone for %g s; an operator can end it now with "
                "./robotarium end --force." % (self.run.run_id, self.config.client_lease))
            self.get_logger().warning("refused to end %s: the request does not carry its token" % self.run.run_id)
            return response
        if request.token == self.run.token:
            reason = outcomes.ENDED_BY_ITS_CLIENT + " at step %d" % self.testbed.steps
            outcome, detail = outcomes.of_request(request.outcome), request.detail
        else:   # an operator's end --force, or ./robotarium end by the experiment's own user (it says so in detail)
            reason = "%s at step %d" % (request.detail if request.detail.startswith("ended by ")
                                        else "ended by an operator (end --force)", self.testbed.steps)
            outcome, detail = outcomes.INTERRUPTED, "interrupted: %s" % reason
        run_id = self.run.run_id
        await self.wait_for_reports()
        if self.testbed is None or self.run.run_id != run_id:   # it ended meanwhile (its client lost, the time limit)
            response.success = False
            response.message = "experiment %s ended meanwhile: %s" % (run_id, self.run.end_reason)
            return response
        return self.end_experiment(reason, response, outcome, detail)

    def stop_ticking(self):
        """No more real-time ticks: the robots stand where they are."""
        if self._tick_timer is not None:
            self.destroy_timer(self._tick_timer)
            self._tick_timer = None

    async def wait_for_reports(self):
        """Until the safety node's report of every array it sent has come (each is counted in the
        run's report), REPORT_WAIT s at most: they travel on a topic of their own and may be a
        moment behind the arrays, more where a lost packet is being repaired on a loaded machine.
        Robots stop meanwhile (the end is asked for: no more ticks)."""
        self.stop_ticking()
        deadline = time.monotonic() + REPORT_WAIT
        while self.run.reports_missing and time.monotonic() < deadline:
            await self.sleep(0.01)
        if self.run.reports_missing:
            self.get_logger().warning("ending %s without the safety node's reports of %d array(s) after %.0f s: its "
                                      "counts in the report miss them" % (
                                          self.run.run_id, self.run.reports_missing, REPORT_WAIT))

    def end_experiment(self, reason, response=None, outcome=outcomes.INTERRUPTED, detail=""):
        """End the running experiment (robots stop, counters frozen, the safety node disarmed) for
        `reason` (who ended it); `outcome` and `detail` say how the run ended (robotarium_core.outcomes),
        in the IDLE status that closes it. Fills and returns an EndExperiment response."""
        response = response or EndExperiment.Response()
        self.stop_ticking()
        if self.client_watch is not None:
            self.client_watch.destroy()
            self.client_watch = None
        tb = self.testbed
        # The safety node's reports of the last arrays may still wait in our queue: count them first.
        for msg in take_waiting(self.safety_reports):
            self.on_safety_report(msg)
        self.run.end_reason = reason
        response.success = True
        response.run_id = self.run.run_id
        response.steps = tb.steps
        copy_counters(tb, response, self.run.tally)
        response.stale_pose_stops = self.run.stale_pose_stops
        response.obstacle_collisions = getattr(tb, "obstacle_hits", 0)
        response.audit = self.run.audit
        response.safety_interventions = self.run.safety_interventions
        response.ideal_interventions = self.run.ideal_interventions
        # A verification run's report is the Robotarium's counts alone: the script's own commands drove it.
        response.report = tb.report(completed=outcome == outcomes.COMPLETED,
                                     safety=None if self.run.audit else self.run.tally.safety(self.run.commands_accepted))
        response.recording = self.recording
        response.end_reason = reason
        response.dropped_cmd_safe = drop_counts(self.run.dropped)
        response.dropped_cmd_requested = self.requested_drops()
        response.message = "%s: %s" % (self.run.run_id, reason)
        self.publish_status()  # the final counters, still marked running, so recorders keep them
        self.testbed = None
        self.run.token = self.run.safety_key = self.run.poses_key = ""
        self.run.outcome, self.run.outcome_detail = outcome, detail
        self.publish_status()   # IDLE, with who ended the run and how it ended
        self._ended_at = time.monotonic()
        self.disarm_safety()
        self.get_logger().info(response.message)
        return response

    def at_rest(self):
        """No experiment runs: restarting the node loses nothing (dds_health.SharedMemoryPortWatch)."""
        return self.testbed is None

    def wind_down(self, reason):
        """Stopping (a signal, or the process that started the testbed is gone: node_main.run_node):
        end the running experiment as end_experiment does, and wait until the last statuses reached
        every subscriber, so the recorder records the end and closes the run. Also when the run had
        just ended otherwise: a client gone with `./robotarium run` (SIGKILL) ends its run a moment
        before the lifeline says stop, and a process that leaves at once takes that IDLE status
        along unsent (a whole-suite run: the bag's last status RUNNING). Not after a run long over:
        a reader that no longer answers (a killed client's, not yet unmatched) would cost the wait."""
        if self.testbed is not None:
            self.get_logger().warning("ending experiment %s: %s" % (self.run.run_id, reason))
            steps = self.testbed.steps
            self.end_experiment("the testbed stopped at step %d (%s)" % (steps, reason), outcome=outcomes.INTERRUPTED,
                                detail="interrupted: the testbed was stopped at step %d (%s)" % (steps, reason))
        if time.monotonic() - self._ended_at < ENDED_JUST_NOW:
            self.status_stream_pub.wait_for_all_acked(Duration(seconds=1.0))
            self.status_pub.wait_for_all_acked(Duration(seconds=0.2))
        return None

    # -- commands ----------------------------------------------------------------------------

    def on_commands(self, data):
        """Everything waiting on cmd_safe at once (subscriptions.take_waiting), so that a flood of
        foreign arrays never fills the queue and pushes the safety node's out."""
        for each in chain([data], take_waiting(self.commands)):   # one at a time: a refused one is freed at once
            self.on_command(each)

    def on_command(self, data):
        tb = self.testbed
        if tb is None:
            return
        try:
            msg = cdr.parse_commands(data, tb.number_of_robots, token=self.run.safety_key)
        except cdr.CdrError as error:
            return self.drop(error.reason, str(error))
        self.run.safe_arrays_heard += 1
        problem = model.check_commands(msg.ids, msg.v, msg.omega, tb.number_of_robots)
        if problem is not None:
            return self.drop(problem, "step %d" % msg.step)
        # Only an array filtered at the poses it will move the robots from (model.StepGate).
        wrong_step = self.run.gate.admit(msg.step, tb.steps, stop=not (np.any(msg.v) or np.any(msg.omega)))
        if wrong_step is not None:
            return self.drop("stale", wrong_step)
        self.run.commands_accepted += 1
        self.run.last_command_step = tb.steps + (0 if self.run.real_time else 1)
        now = time.monotonic()
        ids, v, w = msg.ids, msg.v, msg.omega
        if msg.refreshed:
            # The commands in force, filtered again: not the client's sign of life, and no robot whose
            # command timed out is revived (its timeout runs from the command it came from).
            live = now - tb.command_times[ids] <= self.config.command_timeout
            ids, v, w = ids[live], v[live], w[live]
        else:
            self.run.last_command_at = now
        # Real time: how far into the current tick it came (the hardware-like model sends it then).
        offset = min(max(now - self.run.last_tick, 0.0), tb.time_step) if self.run.real_time else 0.0
        tb.set_commands(ids, v, w, now=now, requested_exceeds_limits=msg.requested_exceeds_limits,
                        offset=offset, refreshed=msg.refreshed)
        if not self.run.real_time:
            tb.step()
            self.run.tally.after_step(tb)
            self.publish_state()

    def drop(self, reason, detail):
        """Count a dropped array (in status); say so in the log the first time for each reason."""
        if self.run.count_drop(reason):
            self.get_logger().warning(
                "dropped a command array on cmd_safe: %s (%s). Further drops of this kind are only counted in the "
                "status topic." % (model.DROP_REASONS[reason], detail))

    def on_safety_report(self, data):
        """A SafetyReport as its bytes (a raw subscription)."""
        if self.testbed is None:
            return
        try:
            msg = cdr.SAFETY_REPORT.parse(data)
        except cdr.CdrError:
            return   # not a SafetyReport: not the safety node's
        self.run.count_safety_report(
            is_intervention(msg, self.config.intervention_tolerance), msg.max_change,
            of_an_array=msg.status != SafetyReport.STATUS_COUNTS_ONLY,
            stale_stop=msg.status == SafetyReport.STATUS_STOP_NO_POSES, dropped=self.drops_in_report(msg),
            ideal=msg.ideal_change > self.config.intervention_tolerance)

    def requested_drops(self):
        """The safety node's drop counts of this run (a DropCounts), over its restarts."""
        if not self.run.safety_rearms:
            return self.run.dropped_requested or DropCounts()
        return DropCounts(**self.run.requested_drop_counts())

    def drops_in_report(self, report):
        """The report's drop counts (cdr.SAFETY_REPORT flattens them) as a DropCounts, the same object
        while they stay the same (they change only when the safety node drops an array)."""
        counts = tuple(getattr(report, reason) for reason in model.DROP_REASONS)
        if counts != self._requested_drops[0]:
            self._requested_drops = (counts, DropCounts(**dict(zip(model.DROP_REASONS, counts))))
        return self._requested_drops[1]

    def on_recording(self, msg):
        self.recording = msg.data

    # -- stepping and publishing ---------------------------------------------------------------

    def tick(self):
        tb = self.testbed
        if tb is None:
            return
        # Stamped with the tick's own time: the step's computation (and whatever preempts it) is
        # not the simulated world's, so the poses' stamps are as regular as the timer.
        now = self.get_clock().now()
        self.run.last_tick = time.monotonic()
        self.expire_commands(tb)
        tb.step()
        self.run.tally.after_step(tb)
        self.publish_state(now)

    def expire_commands(self, tb):
        """The command timeout at this tick (model.Testbed.expire_commands), said once per expiry: which robots
        stopped and how late their commands were (a starved client and a lost array look alike in the count;
        the log tells them apart by time)."""
        stale = tb.expire_commands(self.run.last_tick, self.config.command_timeout)
        if np.any(stale):
            age = self.run.last_tick - tb.command_times[stale].max()
            self.get_logger().warning(
                "%s: robots %s stopped at step %d: no command for %.2f s (the command timeout is %.2f s)"
                % (self.run.run_id, ",".join(map(str, np.flatnonzero(stale))), tb.steps, age,
                   self.config.command_timeout))

    def publish_state(self, now=None):
        tb = self.testbed
        now = now or self.get_clock().now()
        sec, nanosec = now.seconds_nanoseconds()
        x, y, theta = tb.poses
        self.poses_pub.publish(cdr.ROBOT_POSES.build(
            sec=sec, nanosec=nanosec, frame_id="arena", run_id=self.run.run_id, key=self.run.poses_key, step=tb.steps,
            sim_time=tb.sim_time, ids=np.arange(tb.number_of_robots), x=x, y=y, theta=theta))
        if isinstance(tb, rps2.Testbed2):
            self.sensors_pub.publish(rps2_io.sensor_readings(tb, self.run.run_id, now.to_msg()))
            if self.standard_sensors.due(tb):
                self.standard_sensors.publish(tb, sec, nanosec)
        if self.pose_array_pub.get_subscription_count() > 0:
            self.pose_array_pub.publish(cdr.POSE_ARRAY.build(sec=sec, nanosec=nanosec, frame_id="arena",
                                                             poses=cdr.planar_poses(x, y, theta)))
        self.trails.add(tb.steps, tb.poses)
        self.publish_status(now.to_msg())

    def publish_markers(self):
        """The scene for viewers: nothing is built while nobody listens."""
        if self.markers_pub.get_subscription_count() == 0:
            return
        tb = self.testbed
        self.markers_pub.publish(markers.marker_array(   # serialized: published as it is
            self.config, self.get_clock().now().nanoseconds, tb.poses if tb is not None else None,
            trails=self.trails.paths() if tb is not None else ()))

    def publish_status_heartbeat(self):
        # Real-time runs publish status every tick; idle and lockstep (which may wait) once a second.
        if self.testbed is None or not self.run.real_time:
            self.publish_status()

    def publish_status(self, stamp=None):
        tb = self.testbed
        msg = TestbedStatus()
        msg.header.stamp = stamp or self.get_clock().now().to_msg()
        msg.header.frame_id = "arena"
        msg.experiment = self.run.name
        msg.run_id = self.run.run_id
        msg.started.sec, msg.started.nanosec = divmod(self.run.started_ns, 1_000_000_000)
        msg.safety_rearms = self.run.safety_rearms
        msg.mode = "realtime" if self.run.real_time else "lockstep"
        msg.commands_accepted = self.run.commands_accepted
        msg.dropped_cmd_safe = drop_counts(self.run.dropped)
        msg.dropped_cmd_requested = self.requested_drops()
        msg.safety_interventions = self.run.safety_interventions
        msg.ideal_interventions = self.run.ideal_interventions
        msg.end_reason = self.run.end_reason
        if tb is not None:
            msg.poses_key_sha256, msg.safety_key_sha256 = self.run.key_hashes
        msg.outcome, msg.outcome_detail = self.run.outcome, self.run.outcome_detail
        msg.stale_pose_stops = self.run.stale_pose_stops
        msg.audit = self.run.audit
        msg.holder = self.run.holder if tb is not None else ""
        msg.waiting = self.line.holders()
        if tb is None:
            msg.state = TestbedStatus.STATE_IDLE
        else:
            msg.state = TestbedStatus.STATE_RUNNING
            msg.number_of_robots = tb.number_of_robots
            msg.step = tb.steps
            copy_counters(tb, msg, self.run.tally)
        # Serialised once for both writers (rclpy would convert and serialise the message for each).
        data = serialize_message(msg)
        self.status_stream_pub.publish(data)
        self.status_pub.publish(data)


def arm_request(run, testbed, recorded, mid_run=False):
    """The ArmSafety request for experiment `run` on `testbed` (`recorded`: a recorder records it); mid_run: with
    the step and poses it is at (a safety node restarted during the run)."""
    request = ArmSafety.Request(run_id=run.run_id, number_of_robots=testbed.number_of_robots, real_time=run.real_time,
                                token=run.token, safety_key=run.safety_key, poses_key=run.poses_key, audit=run.audit,
                                latency=testbed.latency, recorded=recorded)
    if mid_run:
        request.step = testbed.steps
        request.x, request.y, request.theta = (to_float_array(row) for row in testbed.poses)
    return request


def main(args=None):
    return run_node(SimulatorNode, "simulator", args, claim=presence.SIMULATOR, watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
