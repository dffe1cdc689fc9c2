"""The recorder node: every experiment of the testbed, recorded as a rosbag2 folder with MCAP storage.

It takes every topic of its namespace and the namespace's /rosout serialized, opens a bag at
<bags_dir>/<run_id>/ when the status says a new run is RUNNING and closes it after the IDLE status
that follows, announcing the path on <ns>/recording. The testbed's streams and the drawing are
subscribed from the start, any other topic once it has publishers, with one reader per kind of
publisher (samples.py). Which messages belong to a run is decided by RunRecorder below (no ROS).

The specification (subscriptions, a run's bounds, timestamps, parameters): docs/ros-interface.md#the-recorder.
Run: ros2 run robotarium_recording recorder [--ros-args -r __ns:=/other -p bags_dir:=/data/bags]
"""
import errno
import importlib
import json
import os
import sys
import time
from collections import deque

from rcl_interfaces.msg import Log
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_msgs.msg import String

from robotarium_core import cdr, outcomes, presence, restarts
from robotarium_core.config import DEFAULT, FIELDS
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.node_main import run_node
from robotarium_core.parameters import declare_parameter
from robotarium_core.subscriptions import take_waiting
from robotarium_core.topics import (
    CMD_REQUESTED,
    CMD_SAFE,
    CONFIG,
    DEFAULT_NAMESPACE,
    DRAWING,
    EXPERIMENT,
    LATCHED,
    MARKERS,
    POSE_ARRAY,
    POSES,
    RECORDED_RUNS,
    RECORDED_RUNS_QOS,
    RECORDING,
    RECORDING_ERROR,
    SAFETY_REPORT,
    SENSORS,
    STATUS,
    STATUS_STREAM,
)
from robotarium_msgs.msg import TestbedStatus
from robotarium_recording import bag, bag_writer, samples, schema

# Our own announcement is not part of a run; the viewers' markers are drawn from the poses (a subscription
# here would make the simulator build them all the time, and they would fill the bag).
EXCLUDED_TOPICS = {RECORDING, RECORDING_ERROR, MARKERS}
# Subscribed from the start, with the kind of reader their writers need (robotarium_core.topics).
STREAMS = {CMD_REQUESTED: "robotarium_msgs/msg/TwistArray", CMD_SAFE: "robotarium_msgs/msg/TwistArray",
           POSES: "robotarium_msgs/msg/RobotPoses", POSE_ARRAY: "geometry_msgs/msg/PoseArray",
           SAFETY_REPORT: "robotarium_msgs/msg/SafetyReport", SENSORS: "robotarium_msgs/msg/SensorReadings"}
LATCHED_STREAMS = {DRAWING: "std_msgs/msg/String"}

# s between ticks (RunRecorder.tick): chunks flushed, a simulator gone noticed. While a run closes they come every
# CLOSING_TICK s: a whole lockstep run's bag closes at the first tick after its short grace (20 ticks a second all
# the time would be CPU the real-time nodes beside the recorder miss).
TICK = 0.2
CLOSING_TICK = 0.05
# Deep queues: at N = 50 and 30 Hz a topic carries 30 messages a second; nothing may be dropped
# while a chunk is compressed.
SUBSCRIPTION_DEPTH = 1000


def default_bags_dir():
    root = os.environ.get("ROBOTARIUM_ROOT")
    return os.path.join(root, "bags") if root else os.path.abspath("bags")


class RunRecorder:
    """Splits the stream of messages into runs and writes each run's bag. Plain Python.

    describe(topic) -> (type_name, offered_qos_profiles) is asked once per topic per bag.
    on_started(path) / on_finished(path, writer) are called when a bag is opened / closed.
    Times are ns since the epoch (receive and publish times of each message).

    run_step_of(topic, data) -> (run id, step) of a poses message (None for any other): a closing run's bag
    stays open past grace_ns until it holds the poses of the run's last step (its last RUNNING
    status says which), catch_up_ns more at most. A reliable stream delivers in order, so one lost
    packet holds back every later poses message until the writer repairs it, which takes up to its
    heartbeat period (Fast DDS's 3 s; the testbed's profile makes it 0.1 s) when the recorder was
    starved of CPU: the bag then closed without them. Poses of another run never go into a run's bag.

    A lockstep run's bag is whole once it holds its last step's poses, the step's message on each of
    `step_topics` (step_of(topic, data) -> the step a command array, safety report or sensor readings are for)
    and a message of each of `start_topics`: every one of them was sent before the simulator ended the run. It
    closes lockstep_grace_ns after the end (for the log lines of the end) instead of grace_ns: a
    recorded lockstep run's results no longer wait half a second for messages that cannot come.

    `followed_topics` (of step_topics) are streams a run may not have, one message a step with the poses
    where it has them (a 2.x run's sensor readings): once a run's bag holds one, its last step's is waited
    for as its poses' are (catch_up_ns more at most). A stream held back behind a lost packet of a starved
    recorder closed a 2.x run's bag 47 steps short of its sensor readings (a whole-suite run at load 35).
    """

    def __init__(self, bags_dir, describe, on_started=None, on_finished=None, log=None,
                 preroll_ns=3_000_000_000, grace_ns=500_000_000, chunk_seconds=1.0, live_after_ns=None,
                 on_write_error=None, run_step_of=None, catch_up_ns=4_000_000_000, restarted_ns=None,
                 step_of=None, step_topics=(), start_topics=(), lockstep_grace_ns=50_000_000, followed_topics=()):
        self.bags_dir = os.path.abspath(bags_dir)
        self.describe = describe
        self.on_started = on_started or (lambda path: None)
        self.on_finished = on_finished or (lambda path, writer: None)
        self.log = log or (lambda text: None)
        self.preroll_ns = preroll_ns
        self.grace_ns = grace_ns
        self.run_step_of = run_step_of or (lambda topic, data: None)
        self.catch_up_ns = catch_up_ns
        self.end_step = None          # the current run's step in its last RUNNING status
        self.poses_step = -1          # the newest poses step in its bag
        self.step_of = step_of or (lambda topic, data: None)
        self.step_topics, self.start_topics = tuple(step_topics), tuple(start_topics)
        self.followed_topics = tuple(followed_topics)
        self.lockstep_grace_ns = lockstep_grace_ns
        self.lockstep = False         # the current run steps in lockstep (its statuses say so)
        self.steps_written = {}       # step topic -> the newest step of it in the current run's bag
        self.closing_ns = None        # when the current run's end came
        self.chunk_seconds = chunk_seconds
        self.preroll = deque()        # (topic, data, recv_ns, pub_ns) received while not recording
        self.writer = None
        self.run_id = None
        self.state = "idle"           # idle -> recording -> closing -> idle
        self.end_ns = None
        self.start_ns = None
        self.grace_until = None
        self.finished = {}            # run id -> stamp of its last status (ns)
        # Statuses published before this are history handed over on matching, not live.
        self.live_after_ns = time.time_ns() if live_after_ns is None else live_after_ns
        self.pending = {}             # run id -> stamp of its first RUNNING status seen in history
        self.namespace = ""
        # A write that fails (a full disk) stops this run's recording, never the recorder: what is on
        # disk is made readable, on_write_error(run_id, path, why) says so, the run's later messages
        # are counted as not recorded, and the next run gets a new bag.
        self.on_write_error = on_write_error or (lambda run_id, path, why: None)
        self.write_errors = 0         # failed writes, over the recorder's life
        self.not_recorded = 0         # messages of the current run after its recording stopped
        self.stopped_path = None      # the bag of the current run whose recording stopped ("" if none was made)
        # A recorder restarted mid-run (robotarium_core.restarts) leaves the run it finds running alone: its bag is
        # the one the recorder before it wrote (the client names the restart as where its recording stopped); a
        # second bag of the run's rest would be taken for it. Such a run started before the restart (epoch ns,
        # restarted_ns); one started after it is recorded whole, even when its first status heard here is of a
        # later step (this process matched the simulator's status stream late).
        self.restarted_ns = restarted_ns
        self.left_alone = set()       # run ids

    def on_message(self, topic, data, recv_ns, pub_ns, log_line=False):
        run_step = self.run_step_of(topic, data)
        if self.state == "recording" and run_step is not None and run_step[0] and run_step[0] != self.run_id:
            # Poses of another run never go into this run's bag. Newer than its start, they prove the simulator
            # began another run: a restarted simulator's next run can come before the news of the restart (or a
            # lapse of its presence) does, and its step 0 went into the bag of the run the old process left.
            if pub_ns > self.start_ns:
                self.finish("the simulator began another run (%s)" % run_step[0])
            self.preroll.append((topic, data, recv_ns, pub_ns))
            self._prune(recv_ns)
            return
        if self.state == "recording" or (self.state == "closing" and (log_line or pub_ns <= self.end_ns)):
            self._write(topic, data, recv_ns, pub_ns, run_step)
        else:
            self.preroll.append((topic, data, recv_ns, pub_ns))
            self._prune(recv_ns)

    def on_status(self, topic, data, recv_ns, pub_ns, running, run_id, step=None, started_ns=0, lockstep=False):
        """A status of the simulator: `started_ns` is its run's start (TestbedStatus.started; 0: not known);
        `lockstep`: its run steps in lockstep (TestbedStatus.mode)."""
        if self.restarted_ns is not None and running and run_id and self.run_id is None \
                and run_id not in self.pending and run_id not in self.left_alone \
                and (started_ns < self.restarted_ns if started_ns else step):
            self.left_alone.add(run_id)
            self.log("run %s was running at step %d when this recorder was restarted: its recording is the bag the "
                     "recorder before wrote; the rest of the run is not recorded" % (run_id, step or 0))
        if run_id in self.left_alone:
            self.on_message(topic, data, recv_ns, pub_ns)
            return
        if running and self._is_new_run(run_id, pub_ns):
            if pub_ns < self.live_after_ns:   # history: wait for a live status of this run
                self.pending[run_id] = min(pub_ns, self.pending.get(run_id, pub_ns))
                self.on_message(topic, data, recv_ns, pub_ns)
                return
            if self.writer is not None:
                self.finish("a new run began")
            # From the run's start: what overtook a status heard late (its first commands, poses) is in the preroll.
            self._start(run_id, min(self.pending.pop(run_id, pub_ns), started_ns or pub_ns))
            self.end_step, self.lockstep = step, lockstep
            self._write(topic, data, recv_ns, pub_ns, None)   # (a status: no poses' run and step)
        elif not running and run_id in self.pending:   # that run ended before we started
            self.finished[run_id] = max(pub_ns, self.pending.pop(run_id))
            self.on_message(topic, data, recv_ns, pub_ns)
        elif self.state == "recording" and run_id == self.run_id:
            self._write(topic, data, recv_ns, pub_ns, None)
            self.end_ns = pub_ns
            if running and step is not None:
                self.end_step, self.lockstep = step, lockstep
            if not running:
                self.state, self.grace_until, self.closing_ns = "closing", recv_ns + self.grace_ns, recv_ns
        else:
            self.on_message(topic, data, recv_ns, pub_ns)

    def _is_new_run(self, run_id, pub_ns):
        """A RUNNING status starts a run unless it belongs to the one being recorded or to one
        already closed (a late status); the same run id stamped after that run ended is a new run
        (two experiments of one name started within a second)."""
        if not run_id or (self.state == "recording" and run_id == self.run_id):
            return False
        if self.state == "closing" and run_id == self.run_id:
            return pub_ns > self.end_ns
        return pub_ns > self.finished.get(run_id, -1)

    def tick(self, now_ns, simulator_present=True):
        """Call a few times a second: flushes chunks, ends the grace period, and closes a run whose
        simulator went away without ending it."""
        if self.writer is not None:
            try:
                self.writer.maybe_flush()
            except OSError as error:
                self._write_failed(error)
        if self.state == "closing" and (now_ns >= self.grace_until or (
                now_ns >= self.closing_ns + self.lockstep_grace_ns and self.whole())):
            behind = self.behind()
            if not behind:
                self.finish("the experiment ended")
            elif now_ns >= self.grace_until + self.catch_up_ns:
                self.finish("the experiment ended; " + "; ".join(
                    "its %s from step %d on never came (the last is %d)" % (what, step + 1, self.end_step)
                    for what, step in behind))
        elif self.state == "recording" and not simulator_present:
            self.finish("the simulator went away without ending the experiment")
        self._prune(now_ns)

    def behind(self):
        """[(what, its newest step)] of the streams a closing run's bag still waits for: its poses, and the
        followed topics it has, up to the run's last step (see the class)."""
        if self.end_step is None:
            return []
        behind = [("poses", self.poses_step)] if self.poses_step < self.end_step else []
        if self.writer is not None:
            behind += [(topic.rsplit("/", 1)[-1].replace("_", " "), self.steps_written.get(topic, -1))
                       for topic in self.followed_topics
                       if topic in self.writer.topics and self.steps_written.get(topic, -1) < self.end_step]
        return behind

    def whole(self):
        """A closing lockstep run's bag holds everything its last step sent (see the class)."""
        return (self.lockstep and self.writer is not None and self.end_step is not None
                and self.poses_step >= self.end_step
                and all(self.steps_written.get(topic, -1) >= self.end_step for topic in self.step_topics
                        if topic not in self.followed_topics or topic in self.writer.topics)
                and all(topic in self.writer.topics for topic in self.start_topics))

    def simulator_restarted(self, restart):
        """The simulator was restarted (robotarium_core.restarts): the run being recorded ended with its old
        process (nothing else would close its bag until the next run's status, which would land in it)."""
        if self.state == "recording" and restart.during(self.start_ns / 1e9):
            self.finish("the simulator went away without ending the experiment: %s" % restart.describe())

    def finish(self, why):
        writer, self.writer = self.writer, None
        self.state = "idle"
        if self.stopped_path is not None:   # its recording stopped on a write error
            self.finished[self.run_id] = self.end_ns if self.end_ns is not None else time.time_ns()
            self.log("run %s ended (%s); %d of its messages after the write error were not recorded"
                     % (self.run_id, why, self.not_recorded))
            self.stopped_path, self.not_recorded = None, 0
            return
        if writer is None:
            return
        self.finished[self.run_id] = self.end_ns if self.end_ns is not None else time.time_ns()
        try:
            writer.close()
        except OSError as error:
            self.writer = writer
            self._write_failed(error)
            self.writer, self.stopped_path, self.not_recorded = None, None, 0
            return
        self.log("closed %s (%s): %d messages, %s" % (writer.path, why, writer.message_count, ", ".join(
            "%s %d" % (t.name, t.count[0]) for t in writer.topics.values())))
        self.on_finished(writer.path, writer)

    def _start(self, run_id, start_ns):
        self.run_id, self.end_ns, self.start_ns = run_id, start_ns, start_ns
        self.end_step, self.poses_step = None, -1
        self.lockstep, self.steps_written, self.closing_ns = False, {}, None
        self.state = "recording"
        self.stopped_path, self.not_recorded = None, 0
        try:
            os.makedirs(self.bags_dir, exist_ok=True)
            for suffix in range(1000):   # never overwrite an old run
                path = os.path.join(self.bags_dir, run_id if suffix == 0 else "%s_%d" % (run_id, suffix))
                try:
                    self.writer = bag_writer.BagWriter(path, chunk_seconds=self.chunk_seconds, custom_data={
                        "run_id": run_id, "namespace": self.namespace, "recorder": "robotarium_recording recorder"})
                    break
                except FileExistsError:
                    continue
            else:
                raise OSError(errno.EEXIST, "no free folder name for run %s in %s" % (run_id, self.bags_dir))
        except OSError as error:   # a full disk: the run goes on unrecorded
            self.preroll.clear()
            self._write_failed(error)
            return
        # Messages that overtook the RUNNING status (poses of step 0, first commands).
        for topic, data, recv_ns, pub_ns in self.preroll:
            if pub_ns >= start_ns:
                self._write(topic, data, recv_ns, pub_ns, self.run_step_of(topic, data))
        self.preroll.clear()
        self.log("recording run %s to %s" % (run_id, self.writer.path))
        self.on_started(self.writer.path)

    def _write(self, topic, data, recv_ns, pub_ns, run_step):
        """Into the run's bag; run_step: run_step_of(topic, data), which the caller has (parsed once)."""
        if self.writer is None:   # this run's recording stopped on a write error
            self.not_recorded += 1
            return
        try:
            if topic not in self.writer.topics:
                type_name, offered_qos = self.describe(topic)
                self.writer.add_topic(topic, type_name, offered_qos)
            self.writer.write(topic, data, recv_ns, pub_ns)
            if run_step is not None and run_step[1] > self.poses_step:
                self.poses_step = run_step[1]
            if topic in self.step_topics:
                step = self.step_of(topic, data)
                if step is not None and step > self.steps_written.get(topic, -1):
                    self.steps_written[topic] = step
            self.writer.maybe_flush()
        except OSError as error:
            self.not_recorded += 1
            self._write_failed(error)

    def _write_failed(self, error):
        """A write of this run's bag failed: stop recording the run, make what is on disk readable,
        and say so (on_write_error)."""
        self.write_errors += 1
        writer, self.writer = self.writer, None
        why = outcomes.DISK_FULL if outcomes.disk_full(error) else (error.strerror or str(error))
        path = writer.path if writer is not None else ""
        if writer is not None:
            writer.abandon()
            try:
                bag.recover_bag(path)   # cut a torn chunk, metadata.yaml from what the file holds
            except Exception as salvage:   # noqa: BLE001 - the disk may not take even that; the file still reads
                self.log("could not tidy %s after the write error (%s): readers scan it" % (path, salvage))
        self.stopped_path = path
        self.log("recording of run %s stopped: %s (%s)%s" % (self.run_id, why, error,
                                                         "; what was written is in %s" % path if path else ""))
        self.on_write_error(self.run_id, path, why)

    def _prune(self, now_ns):
        while self.preroll and self.preroll[0][2] < now_ns - self.preroll_ns:
            self.preroll.popleft()

    def close(self):
        if self.writer is not None:
            self.finish("the recorder was stopped")


def message_class(type_name):
    pkg, kind, name = schema.split_type(type_name)
    return getattr(importlib.import_module("%s.%s" % (pkg, kind)), name)


def offered_qos(endpoints):
    """rosbag2-style profiles of the publishers' offered QoS (TopicEndpointInfo list)."""
    profiles = []
    for info in endpoints:
        q = info.qos_profile
        profiles.append(schema.qos_profile(
            history=HistoryPolicy(q.history).name.lower(), depth=q.depth,
            reliability=ReliabilityPolicy(q.reliability).name.lower(),
            durability=DurabilityPolicy(q.durability).name.lower(),
            deadline_ns=q.deadline.nanoseconds, lifespan_ns=q.lifespan.nanoseconds,
            liveliness=LivelinessPolicy(q.liveliness).name.lower(),
            lease_ns=q.liveliness_lease_duration.nanoseconds,
            avoid_ros_namespace_conventions=q.avoid_ros_namespace_conventions))
    return profiles


class RecorderNode(Node):
    def __init__(self):
        super().__init__("recorder", namespace=DEFAULT_NAMESPACE)
        bags_dir = declare_parameter(self, "bags_dir", "", "folder the runs are recorded in (empty: "
                                     "$ROBOTARIUM_ROOT/bags, else ./bags)") or default_bags_dir()
        chunk_seconds = declare_parameter(self, "chunk_seconds", 0.8, "s; a chunk is written to disk at least this "
                                          "often, so a killed recorder loses less", low=0.05, high=60.0)
        if not 0 < chunk_seconds <= 60:
            raise ValueError("parameter chunk_seconds=%r must be in (0, 60] seconds." % chunk_seconds)
        field = FIELDS["node_lease"]
        node_lease = declare_parameter(self, "node_lease", DEFAULT.node_lease, field.description,
                                       low=field.low, high=field.high)
        field = FIELDS["recorder_dedup_window"]
        window = declare_parameter(self, "recorder_dedup_window", DEFAULT.recorder_dedup_window, field.description,
                                   low=field.low, high=field.high)
        self.seen = samples.SeenSamples(window)
        self.readers = {}           # full name -> {(reliable, transient_local)} of the readers it has
        # Clients watch it: a lost recorder is reported as "recording stopped at step k".
        self.presence = presence.Presence(self, presence.alive_topic(presence.RECORDER), node_lease)
        self.ns = self.get_namespace().rstrip("/")
        # Log lines of this namespace's nodes: logger names are the namespace with dots.
        self.logger_prefix = self.ns.strip("/").replace("/", ".") + "." if self.ns else ""
        self.topics = {}            # full name -> type name (None: cannot be recorded)
        restart = restarts.of_this_process()   # (its `at`: when the process before this one ended)
        self.step_layouts = {"%s/%s" % (self.ns, CMD_REQUESTED): cdr.TWIST_ARRAY_STEP,
                             "%s/%s" % (self.ns, CMD_SAFE): cdr.TWIST_ARRAY_STEP,
                             "%s/%s" % (self.ns, SAFETY_REPORT): cdr.SAFETY_REPORT_STEP,
                             "%s/%s" % (self.ns, SENSORS): cdr.SENSOR_READINGS_STEP}
        self.session = RunRecorder(bags_dir, self.describe, self.announce_start, self.announce_end,
                                   self.get_logger().info, chunk_seconds=chunk_seconds,
                                   on_write_error=self.announce_write_error, run_step_of=self.poses_run_step_of,
                                   restarted_ns=None if restart is None else int(restart.at * 1e9),
                                   step_of=self.step_of, step_topics=tuple(self.step_layouts),
                                   followed_topics=("%s/%s" % (self.ns, SENSORS),),
                                   start_topics=("%s/%s" % (self.ns, CONFIG), "%s/%s" % (self.ns, EXPERIMENT)))
        self.session.namespace = self.ns or "/"
        self.recording_pub = self.create_publisher(String, RECORDING, LATCHED)
        self.recording_error_pub = self.create_publisher(String, RECORDING_ERROR, LATCHED)
        self.recorded_runs_pub = self.create_publisher(String, RECORDED_RUNS, RECORDED_RUNS_QOS)
        # Every status comes on the hidden stream (<ns>/status keeps only the newest: robotarium_core.topics);
        # it is recorded under <ns>/status, so bags and their readers see the status topic.
        self.status_topic = "%s/%s" % (self.ns, STATUS)
        self.poses_topic = "%s/%s" % (self.ns, POSES)
        self.topics[self.status_topic] = "robotarium_msgs/msg/TestbedStatus"   # not subscribed itself (discover)
        self.readers_and_callbacks = []   # (subscription, callback(data, info)) of everything recorded
        statuses = self.create_subscription(TestbedStatus, "%s/%s" % (self.ns, STATUS_STREAM), self.on_status,
                                            QoSProfile(depth=SUBSCRIPTION_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                                                       durability=DurabilityPolicy.VOLATILE), raw=True)
        self.readers_and_callbacks.append((statuses, lambda data, info: self.on_status(data)))
        self.subscribe("/rosout", "rcl_interfaces/msg/Log", QoSProfile(depth=SUBSCRIPTION_DEPTH))
        for topics, kind in ((STREAMS, samples.RELIABLE_VOLATILE), (LATCHED_STREAMS, samples.RELIABLE_LATCHED)):
            for topic, type_name in topics.items():
                self.subscribe_kind("%s/%s" % (self.ns, topic), type_name, kind)
        self._sim_missing_since = None
        self.create_subscription(String, "%s/%s" % (self.ns, restarts.topic(presence.SIMULATOR)),
                                 self.on_simulator_restart, restarts.QOS)
        self.tick_timer = self.create_timer(TICK, self.tick)
        self.create_timer(0.5, self.discover)
        self.discover()
        self.get_logger().info("recorder ready: topics of %s to %s" % (self.ns or "/", self.session.bags_dir))

    # -- subscriptions -------------------------------------------------------------------------

    def subscribe(self, topic, type_name, qos):
        try:
            cls = message_class(type_name)
            leading_stamp = schema.has_leading_stamp(schema.message_definition(type_name))
        except (ImportError, AttributeError, FileNotFoundError, ValueError) as error:
            self.get_logger().warning("cannot record %s (%s): %s" % (topic, type_name, error))
            self.topics[topic] = None
            return
        if topic == "/rosout":
            def handle(data, info):
                self.on_rosout(data)
        else:
            def handle(data, info, topic=topic, leading_stamp=leading_stamp):
                recv = time.time_ns()
                # Publish time: the header's stamp, else when the writer wrote it (DDS's source timestamp),
                # never when it came: a sample repaired after a lost packet comes up to a heartbeat later
                # (a run's `experiment` message came after the run's end and was left out of its bag).
                sent = (leading_stamp and schema.stamp_from_cdr(data)) or (info or {}).get("source_timestamp") or recv
                self.session.on_message(topic, data, recv, sent)

        def callback(data, info, topic=topic, handle=handle):
            identity = samples.identity(info, data)
            if identity is None or self.seen.first(topic, identity):   # not a copy another reader of ours heard
                handle(data, info)
        self.readers_and_callbacks.append((self.create_subscription(cls, topic, callback, qos, raw=True), callback))
        self.topics[topic] = type_name

    def discover(self):
        """Subscribe to every topic of the namespace that has publishers, with the QoS they offer
        (a reliable subscription would not hear a best-effort publisher, a transient-local one not
        a volatile publisher)."""
        for name, types in self.get_topic_names_and_types():
            if (not name.startswith(self.ns + "/") or (name in self.topics and self.topics[name] is None) or not types
                    or name == self.status_topic   # recorded from its stream (above)
                    or name[len(self.ns) + 1:] in EXCLUDED_TOPICS or "/_" in name):
                continue
            offers = [(o.qos_profile.reliability == ReliabilityPolicy.RELIABLE,
                       o.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL)
                      for o in self.get_publishers_info_by_topic(name)]
            for kind in sorted(samples.reader_kinds(offers) - self.readers.get(name, set()), reverse=True):
                if not self.subscribe_kind(name, types[0], kind):
                    break   # cannot be recorded

    def subscribe_kind(self, topic, type_name, kind):
        """A reader of `kind` ((reliable, transient_local)) on `topic`; False when it cannot be recorded."""
        reliable, latched = kind
        self.subscribe(topic, type_name, QoSProfile(
            depth=SUBSCRIPTION_DEPTH,
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE))
        if self.topics.get(topic) is None:
            return False
        self.readers.setdefault(topic, set()).add(kind)
        return True

    def describe(self, topic):
        return self.topics[topic], offered_qos(self.get_publishers_info_by_topic(topic))

    # -- callbacks -----------------------------------------------------------------------------

    def on_status(self, data):
        recv = time.time_ns()
        try:
            msg = cdr.TESTBED_STATUS_HEAD.parse(data, max_string=len(data))   # all it needs (one a lockstep step)
        except cdr.CdrError:
            return   # not a TestbedStatus: not the simulator's
        pub = msg.sec * 1_000_000_000 + msg.nanosec or recv
        self.session.on_status(self.status_topic, data, recv, pub,
                               msg.state == TestbedStatus.STATE_RUNNING, msg.run_id, msg.step,
                               msg.started_sec * 1_000_000_000 + msg.started_nanosec, lockstep=msg.mode == "lockstep")
        self.pace_ticks()

    def on_simulator_restart(self, msg):
        restart = restarts.parse(msg.data)
        if restart is not None:
            self.session.simulator_restarted(restart)

    def poses_run_step_of(self, topic, data):
        """(run id, step) of a poses message of this namespace (RunRecorder.run_step_of); None for other topics."""
        if topic != self.poses_topic:
            return None
        try:
            msg = cdr.ROBOT_POSES.parse(data)
            return msg.run_id, msg.step
        except cdr.CdrError:
            return None   # not a RobotPoses (a stray publisher)

    def step_of(self, topic, data):
        """The step a command array, safety report or sensor readings are for (RunRecorder.step_of); None if it
        is not one."""
        try:
            return self.step_layouts[topic].parse(data).step
        except (KeyError, cdr.CdrError):
            return None

    def on_rosout(self, data):
        recv = time.time_ns()
        msg = deserialize_message(data, Log)
        if msg.name.startswith(self.logger_prefix):
            pub = msg.stamp.sec * 1_000_000_000 + msg.stamp.nanosec or recv
            self.session.on_message("/rosout", data, recv, pub, log_line=True)

    def take_waiting_messages(self):
        """Everything the readers hold, handed over now: a closing run's bag gets the messages the
        executor had not come to yet (a busy recorder closed a 2.x run's bag with all its poses but the
        sensor readings of its last 107 steps still waiting in their reader)."""
        for subscription, callback in self.readers_and_callbacks:
            for data, info in take_waiting(subscription, with_info=True):
                callback(data, info)

    def tick(self):
        if self.session.state == "closing":
            self.take_waiting_messages()
        # The simulator is gone when nobody publishes status any more (for 2 s, to ride out discovery).
        present = self.count_publishers(self.status_topic) > 0
        now = time.monotonic()
        if present:
            self._sim_missing_since = None
        elif self._sim_missing_since is None:
            self._sim_missing_since = now
        self.session.tick(time.time_ns(), present or now - self._sim_missing_since < 2.0)
        self.pace_ticks()

    def pace_ticks(self):
        """Ticks every CLOSING_TICK s while a run closes (the first one CLOSING_TICK s after its end came), else
        every TICK s."""
        period_ns = int(1e9 * (CLOSING_TICK if self.session.state == "closing" else TICK))
        if self.tick_timer.timer_period_ns != period_ns:
            self.tick_timer.timer_period_ns = period_ns
            self.tick_timer.reset()   # (a new period counts from the last call otherwise)

    def announce_start(self, path):
        self.recording_pub.publish(String(data=path))
        self.recorded_runs_pub.publish(String(data=json.dumps({"run_id": self.session.run_id, "path": path})))

    def announce_write_error(self, run_id, path, why):
        """The run's client reports "recording stopped at step k: why" (robotarium_client)."""
        self.get_logger().error("recording of run %s stopped: %s; the run goes on unrecorded, the next run gets a "
                                "new bag" % (run_id, why))
        self.recording_error_pub.publish(String(data=json.dumps({
            "run_id": run_id, "path": path, "why": why, "write_errors": self.session.write_errors})))
        self.recording_pub.publish(String(data=""))   # no folder to hand out for this run any more

    def announce_end(self, path, writer):
        # So that the simulator does not hand this path out for a later run that nobody records.
        if self.context.ok():
            self.recording_pub.publish(String(data=""))

    def at_rest(self):
        """No run is being recorded: restarting the node loses nothing (dds_health.SharedMemoryPortWatch)."""
        return self.session.state == "idle"

    def wind_down(self, reason):
        """Stopping: a run still open is closed once the simulator's end of it (winding down, it
        ends the experiment) arrived, or at run_node's limit, whichever is first."""
        return lambda: self.session.state == "idle"

    def close(self):
        self.session.close()


def main(args=None):
    # a run in progress is closed properly on the way out: summary, final metadata.yaml
    return run_node(RecorderNode, "recorder", args, before_destroy=lambda node: node.close(), claim=presence.RECORDER,
                    watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
