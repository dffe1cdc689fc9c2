"""The always-on safety node: every command on its way to the robots passes a barrier certificate.

It forwards only cmd_requested arrays with the armed experiment's token, scaled to the actuator
limits along their arc, merged into the commands in force and filtered through the testbed's
certificate (robotarium_safety.testbed_certificate) at the poses of the step they move the robots
from (robotarium_safety.guard), as cmd_safe with the safety key; a stop where poses are stale, the
input malformed or the certificate failed, never the raw command. Audit mode (verify) lets the
script's own commands through and reports what it would change. Poses, cmd_safe and safety_report
travel as CDR bytes (robotarium_core.cdr).

The specification (topics, audit, lockstep and real time, stale poses): docs/safety.md#the-safety-node.
"""
import sys
import time
from collections import deque
from itertools import chain

import numpy as np
import yaml
from rclpy.node import Node
from std_msgs.msg import String

from robotarium_core import cdr, model, presence
from robotarium_core.config import SAFE_LOADER
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.node_main import run_node
from robotarium_core.parameters import declare_config
from robotarium_core.subscriptions import take_waiting
from robotarium_core.topics import (
    CMD_REQUESTED,
    CMD_SAFE,
    DEFAULT_NAMESPACE,
    EXPERIMENT,
    LATCHED,
    OUTPUT_QOS,
    POSES,
    SAFETY_ARM,
    SAFETY_REPORT,
    SAFETY_REPORT_QOS,
    TESTBED_QOS,
    command_input_qos,
    listeners,
    node_names,
    warn_on_incompatible_qos,
)
from robotarium_msgs.msg import RobotPoses, SafetyReport, TwistArray
from robotarium_msgs.srv import ArmSafety
from robotarium_safety.guard import Guard, filter_commands
from robotarium_safety.testbed_certificate import TestbedCertificate

STALE_LOG_INTERVAL = 1.0   # s between log lines while poses stay too old


class SafetyNode(Node):
    def __init__(self):
        super().__init__("safety", namespace=DEFAULT_NAMESPACE)
        self.config = c = declare_config(self, "safety")
        self.certificate = TestbedCertificate(c)   # centres apart and inside: the least change
        # What a verification's certificate (no latency, lockstep) would change: the run's own may keep
        # wider margins (real time, hardware-like), and the portal compares like with like.
        self.ideal_certificate = TestbedCertificate(c)

        self.armed = ArmSafety.Request()   # the experiment guarded (run_id empty: none)
        self.poses = None            # 3 x N, newest
        self.poses_step = -1
        self.poses_time = -np.inf    # monotonic receive time
        self.commands = None         # 2 x N, the current requested command of every robot
        self.guard = Guard(True, c.lockstep_wait, c.command_timeout)   # what is forwarded, at which poses (issue 22)
        self.last_step = 0           # the last step forwarded
        self.forwarded = 0           # the client's arrays forwarded since the node was armed
        self.held = deque()          # (request, received) commands waiting for the simulator to match cmd_safe
        self._simulator_matched = (False, -1)   # (matched, our writer's match count when last checked)
        self.dropped = dict.fromkeys(model.DROP_REASONS, 0)
        self._dropped_reported = dict(self.dropped)
        self._logged = set()
        self.stale_stops = 0         # commands turned into a stop because the newest poses were too old
        self._stale_spell = None     # (first stop's time, stops so far, last log time) while poses stay old

        self.safe_pub = self.create_publisher(TwistArray, CMD_SAFE, OUTPUT_QOS)
        self.report_pub = self.create_publisher(SafetyReport, SAFETY_REPORT, SAFETY_REPORT_QOS)
        # Poses first: the executor serves ready subscriptions in the order they were created.
        self.poses_subscription = self.create_subscription(RobotPoses, POSES, self.on_poses, TESTBED_QOS, raw=True)
        self.requests = self.create_subscription(TwistArray, CMD_REQUESTED, self.on_requests,
                                                 command_input_qos(c.command_queue_depth), raw=True,
                                                 event_callbacks=warn_on_incompatible_qos(self, CMD_REQUESTED))
        self.create_service(ArmSafety, SAFETY_ARM, self.on_arm)
        self.presence = presence.Presence(self, presence.alive_topic(presence.SAFETY), c.node_lease)
        # 2.x experiments (the simulator's `experiment` settings): 2.x's rule for the actuator-limit flag.
        self.api = ""
        self.create_subscription(String, EXPERIMENT, self.on_experiment, LATCHED)
        self.create_timer(0.02, self.check_pending)
        self.create_timer(1.0, self.report_drops)
        self.get_logger().info(
            "safety node ready in namespace %s: robot centres kept %.3f m apart (collision at %.3f m), %.3f m "
            "inside the arena %s, plus what an arena's latency adds" % (
                self.get_namespace(), c.robot_diameter + c.collision_margin, c.robot_diameter, c.boundary_margin,
                list(c.arena)))

    def at_rest(self):
        """No experiment is guarded: restarting the node loses nothing (dds_health.SharedMemoryPortWatch)."""
        return not self.armed.run_id

    def on_arm(self, request, response):
        """The simulator starts (run_id set) or ends (empty) an experiment: guard that one only. Asked again
        for the experiment it guards (the simulator re-arms whenever this node's presence comes back), it
        changes nothing; a node restarted mid-run is armed with where the run is (step, poses) and goes on."""
        if request.run_id and request.number_of_robots < 1:
            response.message = "an experiment needs at least one robot."
            return response
        mid_run = bool(len(request.x) or len(request.y) or len(request.theta))   # (step 0 too: before the first step)
        if request.run_id and (request.run_id, request.token) == (self.armed.run_id, self.armed.token) and not (
                mid_run and len(self.armed.x) and not self.forwarded):
            response.success = response.already_armed = True
            response.message = "guarding %s already" % request.run_id
            return response
        # (Armed mid-run and asked again before any array went through: the simulator never heard the answer; a
        # restarted node's first answers can go out before its writer matched the simulator's reader, "failed to
        # send response", and the run waited 30 s for a re-arm that had happened. Armed again, where the run is now.)
        n = request.number_of_robots if request.run_id else 0
        if mid_run and not len(request.x) == len(request.y) == len(request.theta) == n:
            response.message = "a re-arm at step %d needs the poses of all %d robots." % (request.step, n)
            return response
        self.armed = request
        self.certificate.latency = request.latency
        self.certificate.real_time = bool(request.real_time)
        self.api = ""   # until this run's settings arrive (on_experiment)
        self.poses, self.poses_step, self.poses_time = None, -1, -np.inf
        self.commands = np.zeros((2, n))   # nobody has a command yet
        self.guard = Guard(bool(request.real_time), self.config.lockstep_wait, self.config.command_timeout)
        self.held.clear()
        self.last_step = self.forwarded = 0
        self.dropped = dict.fromkeys(model.DROP_REASONS, 0)
        self._dropped_reported = dict(self.dropped)
        if mid_run:   # the poses it is at, as if they had just come
            self.poses = np.array([request.x, request.y, request.theta])
            self.poses_step, self.poses_time = request.step, time.monotonic()
            self.guard.on_poses(request.step, self.poses_time)
        response.success = True
        response.message = ("%s %s (%d robots)%s" % ("auditing (verification: the script's own commands go through)"
                                                     if request.audit else "guarding", request.run_id, n,
                                                     " from step %d on" % request.step if mid_run else "")
                            if request.run_id else "disarmed")
        self.get_logger().info(response.message)
        return response

    def drop(self, reason, text):
        self.dropped[reason] += 1
        self.warn_once("drop_" + reason, "dropped a command array on cmd_requested: %s (%s)" % (model.DROP_REASONS[reason], text))

    def report_drops(self):
        """Drops with no array filtered since: say so at most once a second (the simulator puts them in status).
        Unarmed, none: a node restarted mid-run would count the client's arrays before its re-arm into the run."""
        if self.armed.run_id and self.dropped != self._dropped_reported:
            sec, nanosec = self.get_clock().now().seconds_nanoseconds()
            self._dropped_reported = dict(self.dropped)
            self.report_pub.publish(cdr.SAFETY_REPORT.build(
                sec=sec, nanosec=nanosec, frame_id="arena", status=SafetyReport.STATUS_COUNTS_ONLY,
                step=self.last_step, **self.dropped))

    def warn_once(self, kind, text):
        if kind not in self._logged:
            self._logged.add(kind)
            self.get_logger().warning(text + " (logged once; every case is in safety_report)")

    def on_poses(self, data):
        armed = self.armed
        try:
            msg = cdr.ROBOT_POSES.parse(data, max_elements=armed.number_of_robots)
        except cdr.CdrError:
            msg = None   # not a RobotPoses of this run's size: not this run's poses either
        if not armed.run_id or msg is None or msg.key != armed.poses_key or len(msg.x) != armed.number_of_robots:
            # A replayed bag, a stray publisher, or the end of an earlier run: not this run's poses.
            if armed.run_id:
                self.warn_once("foreign_poses", "ignoring poses without this run's key (a replay or another "
                                                "publisher on %s?)" % POSES)
            return
        self.poses = np.array([msg.x, msg.y, msg.theta])
        self.poses_step = msg.step
        self.poses_time = time.monotonic()
        self.decide(*self.guard.on_poses(msg.step, time.monotonic()))

    def on_experiment(self, msg):
        try:
            settings = yaml.load(msg.data, Loader=SAFE_LOADER) or {}
        except yaml.YAMLError as error:
            self.get_logger().warning("ignored experiment settings I cannot read: %s" % error)
            return
        if isinstance(settings, dict) and settings.get("run_id") and settings.get("run_id") == self.armed.run_id:
            self.api = settings.get("api") or ""   # 2.x's rule for the actuator-limit flag

    def on_requests(self, data):
        """Everything waiting on cmd_requested at once (subscriptions.take_waiting): foreign arrays are
        dropped in microseconds; of the client's own, in real time only the newest counts (as on
        the robots' firmware), in lockstep each is a step."""
        # One at a time, as taken: an array refused is freed before the next is taken.
        valid = [request for request in map(self.check_request, chain([data], take_waiting(self.requests))) if request]
        if self.armed.real_time:
            valid = valid[-1:]
        for request in valid:
            self.on_request(request)

    def check_request(self, data):
        """The client's array as Commands, or None when it was dropped (and counted)."""
        armed = self.armed
        if not armed.run_id:
            return self.drop("foreign", "no experiment is running")
        try:
            return cdr.parse_commands(data, armed.number_of_robots, token=armed.token)
        except cdr.CdrError as error:
            return self.drop(error.reason, str(error))

    def on_request(self, request):
        if self.held or not self.simulator_listens():
            if len(self.held) >= self.config.held_commands_limit:   # a flood before the simulator matched
                return self.drop("stale", "more than held_commands_limit arrays wait for the simulator")
            self.held.append((request, time.monotonic()))   # in order, behind any already held
            return
        self.accept(request)

    def simulator_listens(self):
        """Whether what we publish on cmd_safe and safety_report now reaches the simulator and the
        recorder where there is one (the streams are volatile: robotarium_core.topics). Asked once
        the run's poses came (before that every command becomes a stop anyway). Looked up in the graph
        only while not matched, or when our writers' match counts changed."""
        if self.poses is None:
            return True
        counts = (self.safe_pub.get_subscription_count(), self.report_pub.get_subscription_count())
        matched, checked_at = self._simulator_matched
        if not matched or counts != checked_at:
            recorded = self.armed.recorded or presence.RECORDER in node_names(self)
            readers = [presence.SIMULATOR] + ([presence.RECORDER] if recorded else [])
            missing = listeners(self, [(publisher, who) for publisher in (self.safe_pub, self.report_pub)
                                       for who in readers])
            self._simulator_matched = (not missing, counts)
        return self._simulator_matched[0]

    def release_held(self):
        if not self.held:
            return
        waited = time.monotonic() - self.held[0][1]
        if not self.simulator_listens():
            if waited <= self.config.lockstep_wait:
                return
            self.warn_once("simulator_unmatched", "the simulator (or the recorder) has not matched our cmd_safe "
                                                  "and safety_report writers after %.1f s; sending anyway" % waited)
        while self.held:
            self.accept(self.held.popleft()[0])

    def accept(self, request):
        if self.armed.real_time:
            # A real-time command is filtered with the newest poses that have come (and marked with their step).
            for data in take_waiting(self.poses_subscription):
                self.on_poses(data)
        self.decide(*self.guard.on_request(request, time.monotonic()))

    def decide(self, forward, drops):
        """Do what the guard decided: count its drops, filter and send what it forwards."""
        for reason, text in drops:
            self.drop(reason, text)
        for request, step in forward:
            self.filter(request, step)

    def check_pending(self):
        self.release_held()
        self.decide([], self.guard.expire(time.monotonic()))

    def filter(self, request, step):
        """Filter `request` (None: the commands in force, again) at the newest poses and send it
        marked `step` (the step it produces: the guard forwards an array only when the newest poses
        are those of step - 1 in lockstep)."""
        started = time.perf_counter()
        refreshed = request is None
        if refreshed:
            request = cdr.Commands("", step, np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), False, 0, 0)
        ids, v, w = request.ids, request.v, request.omega
        report = {"step": step, "refreshed": refreshed}   # the SafetyReport's fields (cdr.SAFETY_REPORT)
        self.last_step = max(self.last_step, step)
        self.forwarded += not refreshed

        # In lockstep time stands still between steps: only real-time poses age.
        now = time.monotonic()
        report["pose_age"] = pose_age = now - self.poses_time if self.poses is not None else -1.0
        if self.poses is None or (self.armed.real_time and pose_age > self.config.pose_timeout):
            self.note_stale_stop(now, pose_age)
            return self.send_stop(request, report, SafetyReport.STATUS_STOP_NO_POSES, started, refreshed)
        if self._stale_spell is not None:
            first, stops, _ = self._stale_spell
            self._stale_spell = None
            self.get_logger().info("fresh poses again: %d command array(s) were stopped over %.1f s (%d in all)"
                                   % (stops, now - first, self.stale_stops))
        n = self.poses.shape[1]
        problem = model.check_commands(ids, v, w, n)
        if problem is not None:
            self.dropped[problem] += 1
            self.warn_once(problem, "malformed command array (%s): sending stop" % problem)
            return self.send_stop(request, report, SafetyReport.STATUS_STOP_BAD_INPUT, started)

        self.commands[0, ids] = v
        self.commands[1, ids] = w
        # The debug report's actuator count judges the script's own commands (over_limits), never
        # our interventions.
        filtered = filter_commands(self.certificate, self.commands, self.poses, self.config, self.api)
        info = self.certificate.info
        if filtered.fell_back:
            self.warn_once("solver", "barrier certificate failed (%s): sending stop" % info["reason"])
            status = SafetyReport.STATUS_STOP_SOLVER_FAILED
        else:
            status = (SafetyReport.STATUS_SOLVED if np.any(filtered.change > 0) else
                      SafetyReport.STATUS_SATURATED if np.any(filtered.requested != self.commands) else
                      SafetyReport.STATUS_PASSTHROUGH)
        report["status"] = status
        report["solver_status"] = info["status"]
        report["max_change"] = float(filtered.change.max()) if n else 0.0
        report["robots_changed"] = int(np.count_nonzero(filtered.change > self.config.intervention_tolerance))
        report["ideal_change"] = report["max_change"]
        if self.certificate.latency or self.certificate.real_time:
            report["ideal_change"] = float(filter_commands(self.ideal_certificate, self.commands, self.poses,
                                                           self.config, self.api).change.max(initial=0.0))
        safe = filtered.safe
        if self.armed.audit:   # verification: what the certificate would do is reported, the script's own commands go
            report["audit"] = True
            safe = self.commands.copy()
        self.publish(step, np.arange(n), safe[0], safe[1], report, started, filtered.over_limits, refreshed)

    def note_stale_stop(self, now, age):
        """Count a stop for want of recent poses; log the first of a spell, then once a second."""
        self.stale_stops += 1
        what = ("no poses from the simulator yet" if age < 0 else
                "the newest poses are %.2f s old (more than pose_timeout %.2f s)" % (age, self.config.pose_timeout))
        if self._stale_spell is None:
            self._stale_spell = (now, 1, now)
            self.get_logger().warning("%s: sending stop (stop %d)" % (what, self.stale_stops))
            return
        first, stops, logged = self._stale_spell
        if now - logged >= STALE_LOG_INTERVAL:
            self.get_logger().warning("%s: still sending stops (%d in this spell, %d in all)"
                                      % (what, stops + 1, self.stale_stops))
            logged = now
        self._stale_spell = (first, stops + 1, logged)

    def send_stop(self, request, report, status, started, refreshed=False):
        # How far the stop is from what was asked: the largest finite requested speed.
        requested = np.abs(np.concatenate((np.asarray(request.v, dtype=float), np.asarray(request.omega, dtype=float))))
        requested = requested[np.isfinite(requested)]
        report["max_change"] = float(requested.max()) if requested.size else 0.0
        report["robots_changed"] = len(request.v)
        if self.poses is not None:
            ids = np.arange(self.poses.shape[1])  # stop every robot we know of
            self.commands[:] = 0.0
        else:
            ids = np.arange(self.armed.number_of_robots)
        report["status"] = status
        # the script's doing (a malformed array) or the testbed's (stale poses): only the first is the script's
        report["ideal_change"] = report["max_change"] if status == SafetyReport.STATUS_STOP_BAD_INPUT else 0.0
        self.publish(report["step"], ids, np.zeros(len(ids)), np.zeros(len(ids)), report, started, refreshed=refreshed)

    def publish(self, step, ids, v, w, report, started, requested_exceeds_limits=False, refreshed=False):
        now = self.get_clock().now()
        sec, nanosec = now.seconds_nanoseconds()
        self.safe_pub.publish(cdr.TWIST_ARRAY.build(
            sec=sec, nanosec=nanosec, frame_id="arena", token=self.armed.safety_key, step=step, ids=ids,
            twists=cdr.twists(v, w), requested_exceeds_limits=bool(requested_exceeds_limits), refreshed=refreshed))
        self._dropped_reported = dict(self.dropped)
        self.report_pub.publish(cdr.SAFETY_REPORT.build(
            sec=sec, nanosec=nanosec, frame_id="arena", number_of_robots=len(ids),
            solve_time=time.perf_counter() - started, **self.dropped, **report))


def main(args=None):
    return run_node(SafetyNode, "safety", args, claim=presence.SAFETY, watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
