"""The client's link to a testbed over DDS: a node of its own (in a context of its own), the command
and drawing writers, the poses, status, configuration and recording readers, the start and end
services (with the testbed's line), the presence it holds and those it watches. What it hears it
keeps (the newest poses of the run, the testbed's configuration, the recording announced, who ended
the run, which node is gone, why the run cannot go on); robotarium.Robotarium decides what that
means for the rps contract.

The step's round trip is the hot path: commands are published and poses taken as CDR bytes
(robotarium_core.cdr, no Python object per robot), and the node is spun by
robotarium_core.executor.LeanExecutor (rclpy's default executor costs about half a millisecond of
Python per message).
"""
from __future__ import annotations

import getpass
import json
import os
import signal
import socket
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from std_msgs.msg import String

import robotarium_recording as recording
from robotarium_bringup.testbed import LocalTestbed, security_enabled
from robotarium_client.errors import (
    EndedByTestbed,
    EndedByUnsentRequest,
    NodeRestarted,
    TestbedBusy,
    TestbedIncomplete,
    TestbedLost,
)
from robotarium_core import cdr, claim, outcomes, presence, processes, restarts
from robotarium_core.dds_health import DDS_STALL_CHECK, DDS_STALL_LIMIT, DdsStallWatch
from robotarium_core.dds_settings import init_context, profile_is_ours
from robotarium_core.discovery import wait_for_quiet_discovery, wait_for_service
from robotarium_core.executor import LeanExecutor
from robotarium_core.model import RobotariumError
from robotarium_core.subscriptions import take_waiting
from robotarium_core.topics import (
    CMD_REQUESTED,
    CONFIG,
    DRAWING,
    DRAWING_QOS,
    END_EXPERIMENT,
    LATCHED,
    LISTENERS_WAIT,
    OUTPUT_QOS,
    POSES,
    RECORDED_RUNS,
    RECORDED_RUNS_QOS,
    RECORDING,
    RECORDING_ERROR,
    START_EXPERIMENT,
    STATUS,
    STATUS_QOS,
    TESTBED_QOS,
    node_names,
    readers_matched,
)
from robotarium_msgs.msg import RobotPoses, TestbedStatus, TwistArray
from robotarium_msgs.srv import EndExperiment, StartExperiment

if TYPE_CHECKING:
    from rclpy.client import Client

    from robotarium_core.config import TestbedConfig

STARTUP_WAIT = 60.0   # s for a testbed started here to come up
STEP_TIMEOUT = 10.0   # s without poses after a step() before we give up with an explanation
RECORDING_WAIT = 2.0   # s the end waits for a recorder that heard the run to say where it records it
# s a run waits, once a restart of its safety node was announced, for the testbed to arm the new process (the
# simulator does as soon as the node is back: ~1-3 s after a kill under ./robotarium up, at once in place)
REARM_WAIT = 30.0
# s one step() may take under ./robotarium run (HANG_WATCH, the runner's) before its process counts as stuck in a
# call into its own Fast DDS that never came back: a deadlock inside Fast DDS met while a call held the GIL, so
# nothing of Python runs, the watch below included. The kernel's timer ends the process then (SIGALRM's default
# action; arm_hang_watch) and ./robotarium run names the cause (outcomes.OWN_DDS_HUNG). A step gives up by
# itself well within it (STEP_TIMEOUT, then STALL_RESTART_WAIT where a node restarts).
HUNG_STEP = 60.0
HANG_WATCH = False
# what stopped this process's own Fast DDS ("" never), once a wait for poses or leaving DDS found its event thread
# stuck: nothing more is said over it, and the runner exits without waiting for it
DDS_STUCK = ""
# s a start may take: a hardware arena (robotarium_hardware) answers once its drive-on phase brought the robots to
# the initial conditions, which took up to 30 s for the guide's listings on a loaded 2-core machine
START_WAIT = 180.0
CONFIG_WAIT = 2.0     # s for the testbed's latched configuration once its services answer
GRAPH_POLL = 0.01     # s between looks at what only the DDS graph says (a reader matched) while waiting
LINE_POLL = 0.5       # s between a waiting client's asks (well within the testbed's line_lease)
LINE_REPORT = 10.0    # s between lines saying who holds the testbed, when nothing else changed
# s, after its loss was confirmed, to wait for the restart of a node whose process lives on here, deaf to DDS (its
# DdsStallWatch restarts it in place DDS_STALL_LIMIT after its DDS stopped, then it starts: seconds of imports)
STALL_RESTART_WAIT = DDS_STALL_LIMIT + 5.0
BACK_WITHOUT_RESTART = 1.0   # s a node back after its loss has to announce a restart (its presence may come first)


def incomplete_testbed_message(ns: str) -> str:
    """What a client says of a testbed in `ns` whose safety node does not answer (one line)."""
    return ("The testbed in %s on ROS_DOMAIN_ID %s is incomplete: no safety node answers, and without it the robots "
            "cannot move. Start one there (ros2 run robotarium_safety safety --ros-args -r __ns:=%s), or stop this "
            "testbed (./robotarium stop) and start a whole one (./robotarium up)."
            % (ns, os.environ.get("ROS_DOMAIN_ID", "0").strip() or "0", ns))


def holder_of_this_process() -> str:
    """Who asks for the testbed, as those waiting and ./robotarium status show it."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "?"
    return "%s@%s pid %d %s" % (user, socket.gethostname(), os.getpid(), os.path.basename(sys.argv[0] or "python"))


def arm_hang_watch() -> bool:
    """Arm the kernel's timer for HUNG_STEP s (disarm_hang_watch after the step); False, and nothing armed,
    outside ./robotarium run or where the script uses SIGALRM or the timer itself."""
    if not HANG_WATCH or signal.getsignal(signal.SIGALRM) != signal.SIG_DFL or signal.getitimer(signal.ITIMER_REAL)[0]:
        return False
    signal.setitimer(signal.ITIMER_REAL, HUNG_STEP)
    return True


def disarm_hang_watch() -> None:
    signal.setitimer(signal.ITIMER_REAL, 0)


class OwnDdsWatch:
    """Whether this process's own Fast DDS event thread is stuck (dds_health.DdsStallWatch), looked at cheaply:
    look() (in a wait's predicate; always False) samples it every DDS_STALL_CHECK at most; stuck() says what has
    not run for DDS_STALL_LIMIT, or ""; running_or_stuck() settles it before leaving DDS. Only under the
    testbed's Fast DDS profile, whose event thread wakes several times a second; that is known once DDS has
    started (init_context)."""

    def __init__(self) -> None:
        self.watch = None   # a DdsStallWatch from the first look under our profile
        self.next = 0.0

    def look(self) -> bool:
        now = time.monotonic()
        if now >= self.next:
            if self.watch is None and profile_is_ours():
                self.watch = DdsStallWatch(gap=float("inf"))
            if self.watch is not None:
                self.watch.check(now)
            self.next = now + DDS_STALL_CHECK
        return False

    def stuck(self) -> str:
        if self.watch is None or self.watch.last is None:
            return ""
        return self.watch.check() or ""

    def running_or_stuck(self) -> str:
        """"" once the event thread is seen to run (at once, mostly: it ran since the last look), else what has
        not run for DDS_STALL_LIMIT. Leaving DDS waits for that thread, holding the GIL (rclpy's destroy):
        nothing could watch it from here once it began."""
        self.look()
        if self.watch is None or not self.watch.seen:
            return ""
        before = {tid: switches for tid, (switches, _) in self.watch.seen.items()}
        while True:
            stuck = self.watch.check()
            if stuck:
                return stuck
            if any(self.watch.seen.get(tid, (switches,))[0] != switches for tid, switches in before.items()):
                return ""
            time.sleep(0.05)


_early = None   # (pid, context, node): this process's participant, made before its run's options came (join_dds_early)


def join_dds_early(ns: str) -> None:
    """Join DDS now, as the first TestbedLink would: a warm runner waiting for its run's arguments finds the
    testbed's participants meanwhile (each announces itself every 0.2 s), and the first TestbedLink takes this
    participant and node, its constructor's discovery done. A participant is made with a process's first node
    (rmw_fastrtps), so the node is made too, with the link's own name, in `ns` (the namespace expected)."""
    global _early
    if _early is None:
        _early = (os.getpid(), *_join(ns))


def leave_dds_early() -> None:
    """Leave what join_dds_early made if no TestbedLink took it (a script that never made a Robotarium)."""
    global _early
    if _early is not None:
        (pid, context, node), _early = _early, None
        if pid == os.getpid():   # (a fork's copy is its parent's to leave)
            node.destroy_node()
            rclpy.try_shutdown(context=context)


def _join(ns: str) -> tuple[Context, Node]:
    """A participant of this process and the client's node in `ns`."""
    context = Context()
    # With DDS Security (sros2/README.md) a script runs in the client enclave of the policy.
    init_context(context=context, node=False,
                 args=["--ros-args", "--enclave", "/robotarium/client"] if security_enabled() else [])
    return context, Node(_client_node_name(), namespace=ns, context=context)


def _client_node_name() -> str:
    return "robotarium_client_%d" % os.getpid()


def _context_and_node(ns: str) -> tuple[Context, Node]:
    """The participant and node of a new TestbedLink: those join_dds_early made in this process, if any (the
    node made anew where the run's namespace is not the one expected), else new ones (in a process the
    script forked too: its copy of its parent's participant has none of its threads)."""
    global _early
    early, _early = _early, None
    if early is None or early[0] != os.getpid():
        return _join(ns)
    _, context, node = early
    if node.get_namespace() != ns:
        # the new node first: the participant goes with a context's last node
        expected, node = node, Node(_client_node_name(), namespace=ns, context=context)
        expected.destroy_node()
    return context, node


class TestbedLink:
    """One client's DDS link to the testbed in namespace `ns`, for one experiment at a time."""

    __test__ = False   # not a pytest class, whatever its name

    def __init__(self, ns: str, config: TestbedConfig) -> None:
        self.ns = ns
        self.config = config          # the testbed's, once adopted: its node_lease judges lost nodes
        self.run_id = None
        self.real_time = True
        self.token = ""
        self.poses_key = None
        self.latest = None            # the newest poses message of this run (cdr.ROBOT_POSES)
        self.testbed_config = None    # the testbed's configuration, as its latched topic said it
        self.presence = None
        self.watches = {}
        self.failure = None           # why the experiment cannot go on (a node lost, ended by someone else)
        self.failure_kind = TestbedLost
        self.end_sent = False         # this script sent its end request (call_at_scripts_end, or ending as it failed)
        self.unsent_end_at = None     # the step at which an end request with our token ended the run, if not ours
        self.idle_end_reason = ""     # who ended this run, as the simulator's IDLE status says
        self.suspects = {}            # {node: (monotonic time, step)} whose presence lapsed, not yet confirmed lost
        self.recorder_lost_at = None
        self.recording_stopped_because = None   # "the recorder is gone", "disk full", ...
        self.stopped_recording = ""             # the bag of a recording stopped by a write error
        self.on_recording_announced = None      # called when the recorder names this run's folder
        self._recording = ""          # the recorder's folder, from its announcement
        self._recorded_runs = {}      # run id -> folder, from the recorder's recent runs (kept after the close)
        self.local_testbed = None     # one started here for this client (no ./robotarium around it)
        self.started_at = None        # epoch s this client asked to start its run: restarts from then on are its
        self.restarts_heard = set()   # robotarium_core.restarts.Restart records acted on
        self.awaiting_restart = {}    # {node: (monotonic deadline, step)}: lost, its process alive here (a DDS stall)
        # A safety node restarted mid-run: the simulator arms the new process with the run and the run goes on.
        self.safety_rearms = 0        # this run's status: times the testbed armed a restarted safety node again
        self._rearms_paired = 0       # of those, the ones paired with a restart heard
        self.safety_restart = None    # (Restart, step, monotonic deadline): heard, the new node not armed yet
        self.safety_restarts = []     # what the run went on through (restarts.went_on's words)
        self._resend_due = False      # armed again: the array the old process may have lost goes again
        self._last_command = None
        self._own_dds = OwnDdsWatch()   # this process's own Fast DDS: a stuck event thread is named, not the testbed
        self.claims = {}              # {node: its claim's identity (host, pid)}: robotarium_core.claim
        self.pids_at_start = {}       # {node: its process when this run began}: a restart of another is not this run's
        # The testbed's Fast DDS settings for the script's participant too (dds_settings.init_context): UDP
        # only; its writers' heartbeat every 0.1 s, so a lost packet of cmd_requested is sent again at once.
        self._context, self.node = _context_and_node(ns)
        self._executor = LeanExecutor(context=self._context)
        self._executor.add_node(self.node)
        self.command_pub = self.node.create_publisher(TwistArray, CMD_REQUESTED, OUTPUT_QOS)
        self._poses_subscription = self.node.create_subscription(RobotPoses, POSES, self._on_poses, TESTBED_QOS,
                                                                 raw=True)
        # Raw: a status comes every lockstep step and only this run's IDLE one matters (_on_status_bytes).
        self.node.create_subscription(TestbedStatus, STATUS, self._on_status_bytes, STATUS_QOS, raw=True)
        # Made now, not at the first drawing: the recorder discovers it while the experiment starts.
        self._drawing_pub = self.node.create_publisher(String, DRAWING, DRAWING_QOS)
        self._drawing_message = String()
        self.node.create_subscription(String, CONFIG, self._on_config, LATCHED)
        self.node.create_subscription(String, RECORDING, self._on_recording, LATCHED)
        self.node.create_subscription(String, RECORDED_RUNS, self._on_recorded_run, RECORDED_RUNS_QOS)
        self.node.create_subscription(String, RECORDING_ERROR, self._on_recording_error, LATCHED)
        for who in (presence.SIMULATOR, presence.SAFETY, presence.RECORDER):
            self.node.create_subscription(String, restarts.topic(who), self._on_restart, restarts.QOS)
            self.node.create_subscription(String, claim.claim_topic(who), self._on_claim, claim.QOS)
        self._start_client = self.node.create_client(StartExperiment, START_EXPERIMENT)
        self._end_client = self.node.create_client(EndExperiment, END_EXPERIMENT)
        self._number_of_robots = 0
        self._ids = np.arange(0)

    # -- connecting and starting -----------------------------------------------------------------------

    def connect(self, wait: float, local_allowed: bool) -> None:
        """Wait `wait` s for a testbed to answer; none: start one on this machine where allowed."""
        if wait_for_service(self._start_client, wait if local_allowed else max(wait, STARTUP_WAIT)):
            return
        if not local_allowed:
            self.shutdown()
            raise RuntimeError(
                "%s in namespace %s on ROS_DOMAIN_ID %s. Start one with "
                "'./robotarium up' (here or on another machine of the domain)."
                % (outcomes.NO_TESTBED_ANSWERS, self.ns, os.environ.get("ROS_DOMAIN_ID", "0")))
        print("[robotarium] no testbed answers in %s: starting one on this machine" % self.ns, file=sys.stderr)
        self.local_testbed = LocalTestbed(ns=self.ns).start()
        if not wait_for_service(self._start_client, STARTUP_WAIT):
            failed = self.local_testbed.failed()
            self.shutdown()
            raise RuntimeError("The local testbed did not come up (exited: %s); see %s." % (failed, self.local_testbed.log_dir))

    def testbed_configuration(self) -> str | None:
        """The testbed's configuration text (its latched topic), or None where it publishes none."""
        self.spin_until(lambda: self.testbed_config is not None, CONFIG_WAIT)
        return self.testbed_config

    def start(self, request: StartExperiment.Request) -> StartExperiment.Response:
        """Start the experiment `request` asks for (waiting in the testbed's line where it says so) and
        get ready to drive it: the run's secrets, our presence, the readers our first commands need.
        Raises TestbedBusy, TestbedIncomplete or a RobotariumError with the testbed's reason."""
        self._watch_testbed()
        # the streams are volatile: the run's first poses wait for our reader of them
        request.client_node = self.node.get_fully_qualified_name()
        # rmw_fastrtps drops a reply when the service has not matched the caller's reply reader within
        # 100 ms (a testbed found a moment ago, a loaded machine), and a start must not be sent twice:
        # first a start it refuses however often it comes, sent until answered; then the real one.
        self.call(self._start_client, StartExperiment.Request(name="!"), resend=1.0)
        self.started_at = time.time()
        response = self._wait_in_line(request)
        if not response.success:
            self.shutdown()
            if response.incomplete:   # the simulator waited for the safety node in vain: the testbed's problem
                raise TestbedIncomplete(incomplete_testbed_message(self.ns))
            # Any other refusal in its own words, whether or not this client saw the safety node yet (a
            # testbed started a moment ago: its presence may not have reached us).
            raise RobotariumError("The testbed refused to start the experiment: %s" % response.message)
        self.run_id, self.token, self.poses_key = response.run_id, response.token, response.poses_key
        self.real_time = response.real_time
        self.pids_at_start = {who: ident["pid"] for who, ident in self.claims.items()}
        self._number_of_robots = request.number_of_robots
        self._ids = np.arange(request.number_of_robots)
        self.presence = presence.Presence(self.node, response.client_alive_topic, response.client_lease)
        return response

    def get_ready(self) -> None:
        """Before the first command: the safety node's reader of our commands matched (without it
        nothing moves: say so now, not at the first step's timeout), the recorder's where there is one
        (else our first commands would be missing from the bag), our presence followed, and the
        simulator and safety node seen alive (a node is reported lost only once we saw it there)."""
        if not self.spin_until(lambda: readers_matched(self.node, self.command_pub, "safety"), STEP_TIMEOUT):
            raise TestbedIncomplete(incomplete_testbed_message(self.ns))
        if presence.RECORDER in node_names(self.node):
            self.spin_until(lambda: readers_matched(self.node, self.command_pub, presence.RECORDER), LISTENERS_WAIT)
        # Until the simulator follows our presence, a crash of this process would free the testbed
        # only after its discovery wait (10 s) instead of client_lease: wait for it (it takes moments).
        if self.spin_until(lambda: self.presence.publisher.get_subscription_count() > 0, STEP_TIMEOUT):
            self.presence.announce()
        # (their presences assert every 0.17 s)
        self.spin_until(lambda: self.watches["simulator"].seen and self.watches["safety"].seen, STEP_TIMEOUT)

    def _wait_in_line(self, request: StartExperiment.Request) -> StartExperiment.Response:
        """Ask to start until the testbed takes us: a busy testbed puts a waiting client in its line
        (first come, first served; robotarium_core.line), and we say our place and who holds it
        whenever that changes (and every LINE_REPORT s), and when our turn came. Ctrl-C leaves the
        line (the testbed forgets a ticket nobody asks with)."""
        said, said_at = None, 0.0
        while True:
            response = self.call(self._start_client, request, timeout=START_WAIT)
            if not response.busy:
                if said is not None:   # it waited: say that its turn came, not only what it waited for
                    print("[robotarium] your turn: the testbed is free%s" % (
                        ", starting the experiment" if response.success else ""), file=sys.stderr, flush=True)
                return response
            if not request.wait:
                self.shutdown()
                raise TestbedBusy("The testbed in %s is busy: %s. Run again without --no-wait to wait in line for it "
                                  "(./robotarium status shows who holds it)." % (self.ns, response.holding))
            request.ticket = response.ticket
            news = (response.place, response.holding.split(", step")[0])
            if news != said or time.monotonic() - said_at > LINE_REPORT:
                print("[robotarium] waiting for the testbed: number %d in line; it is held by %s (Ctrl-C leaves the "
                      "line)" % (response.place, response.holding), file=sys.stderr, flush=True)
                said, said_at = news, time.monotonic()
            self.spin_until(lambda: False, LINE_POLL)

    # -- the run ---------------------------------------------------------------------------------------

    def send(self, velocities: np.ndarray, step: int) -> None:
        v, w = velocities
        sec, nanosec = self.node.get_clock().now().seconds_nanoseconds()
        self._last_command = cdr.TWIST_ARRAY.build(sec=sec, nanosec=nanosec, frame_id="arena", token=self.token,
                                                   step=step, ids=self._ids, twists=cdr.twists(v, w))
        self._resend_due = False   # (this one reaches a safety node armed again already)
        self.command_pub.publish(self._last_command)

    def publish_drawing(self, message: dict[str, object]) -> None:
        self._drawing_message.data = recording.encode_drawing(message)
        self._drawing_pub.publish(self._drawing_message)

    def take_newest_poses(self) -> None:
        """Take every poses message the reader holds now (this run's newest ends up in `latest`)."""
        for data in take_waiting(self._poses_subscription):
            self._on_poses(data)

    def wait_for_step(self, target: int) -> np.ndarray:
        """The newest poses once those of step `target` came (3 x N); raises what stopped the run. Across a
        restart of the safety node: until the testbed armed the new process (REARM_WAIT), then the array the
        old one may have lost goes again (in lockstep the testbed waits for it)."""
        global DDS_STUCK
        own = self._own_dds

        def came():
            return self.latest is not None and self.latest.step >= target

        deadline = time.monotonic() + STEP_TIMEOUT
        while True:
            self.spin_until(lambda: self.confirm_losses() or self._resend_due or came() or own.look(),
                            deadline - time.monotonic())
            self.check()
            if came():
                break
            if self._resend_due:
                self._resend_due = False
                if self._last_command is not None and not self.real_time:   # (real time: the next tick's comes)
                    self.command_pub.publish(self._last_command)
                deadline = time.monotonic() + STEP_TIMEOUT
            elif time.monotonic() >= deadline and self.safety_restart is not None:
                restart, step, until = self.safety_restart
                if time.monotonic() >= until:
                    self.failure_kind, self.failure = NodeRestarted, restarts.not_armed_again(restart, step, REARM_WAIT)
                    self.check()
                deadline = until
            elif time.monotonic() >= deadline:
                break
        arrived = came()
        if not arrived:
            stuck = own.stuck()
            if stuck:   # this process heard nothing because its own DDS stopped, not the testbed
                DDS_STUCK = stuck
                raise TestbedLost(
                    "This script's own Fast DDS stopped (%s: a deadlock inside Fast DDS, docs/faults.md), so it heard "
                    "nothing of the testbed for %.0f s after step %d; the testbed ends its run when it stops hearing "
                    "the script. Run the script again." % (stuck, STEP_TIMEOUT, target - 1))
            raise TestbedLost(
                "The testbed sent no poses for step %d within %.0f s. Is the safety node running (robots cannot "
                "move without it)? Node logs are in log/testbed/<namespace>_<domain>_<pid>/ when ./robotarium started "
                "the testbed (./robotarium status lists the testbeds of this machine)."
                % (target, STEP_TIMEOUT))
        self.take_newest_poses()   # a still newer one may have come meanwhile
        msg = self.latest
        return np.array([msg.x, msg.y, msg.theta])   # a copy: the message's arrays are views of its bytes

    @property
    def step(self) -> int:
        """The newest step heard of this run (0: none yet)."""
        return self.latest.step if self.latest is not None else 0

    def end(self, outcome: int, detail: str) -> EndExperiment.Response:
        """End the experiment saying how; raises what ended it first where the testbed refuses."""
        self.end_sent = True   # an IDLE status of this run from now on may be this request's
        if "recorder" in self.suspects:   # a lapse just before the end: settle whether the recorder is gone
            self.spin_until(lambda: self.confirm_losses() or "recorder" not in self.suspects, 2 * self.config.node_lease)
        self.check()
        # A testbed that was lost is asked briefly: it may be back, but nobody should wait for it.
        response = self.call(self._end_client, EndExperiment.Request(token=self.token, outcome=outcome, detail=detail),
                             timeout=3.0 if outcome == outcomes.TESTBED_LOST else 30.0)
        if not response.success:
            # Refused: if the testbed says its client ended the run, that end request was not ours (ours
            # was in flight when one with our token came first).
            if self.unsent_end_at is None and self.idle_end_reason.startswith(outcomes.ENDED_BY_ITS_CLIENT):
                self.unsent_end_at = outcomes.step_of_end_reason(self.idle_end_reason)
            if self.unsent_end_at is not None:
                self.failure_kind, self.failure = EndedByUnsentRequest, self.unsent_end_at
            self.check()   # ended meanwhile (lost, or by an operator): say so rather than "no experiment"
            raise RuntimeError("The testbed could not end the experiment: %s" % response.message)
        if not response.recording and not self.announced_recording() and self.recorder_lost_at is None \
                and readers_matched(self.node, self.command_pub, presence.RECORDER):
            # A recorder heard this run, but where it records it has not reached us yet (a recorder matched
            # late, one just restarted in place): its recent runs come once matched; a little wait for them.
            self.spin_until(self.announced_recording, RECORDING_WAIT)
        return response

    def end_quietly(self, outcome: int, detail: str) -> None:
        """Free the testbed for the next run, saying how the run ended, without waiting long or
        raising: at exit, a script that never called call_at_scripts_end()."""
        simulator = self.watches.get("simulator")
        # (a testbed whose service is gone has ended the experiment itself, or is gone with it)
        if self.token and not (simulator is not None and simulator.lost) and self._end_client.service_is_ready():
            self.end_sent = True
            try:
                self.call(self._end_client, EndExperiment.Request(token=self.token, outcome=outcome, detail=detail),
                          timeout=5.0)
            except Exception:   # noqa: BLE001 - at exit nothing is left to say it to
                pass

    def announced_recording(self) -> str:
        """The recorder's folder for this run if it announced one (its name starts with the run id). `recording`
        keeps only the newest, "" once the run's bag closed: a short run on a recorder this process matched late
        (one just restarted in place) ended "not recorded" though it was (a whole suite, 2026-11-30), so the
        recorder's recent runs count too."""
        if not self.run_id:
            return ""
        if os.path.basename(self._recording).startswith(self.run_id):
            return self._recording
        return self._recorded_runs.get(self.run_id, "")

    # -- what it hears ---------------------------------------------------------------------------------

    def _on_poses(self, data: bytes) -> None:
        try:
            msg = cdr.ROBOT_POSES.parse(data, max_elements=self._number_of_robots)
        except cdr.CdrError:
            return   # not poses of this run's size: not this run's poses
        # Only the simulator's poses of this run carry its key (not a replay's, not a stray publisher's).
        if msg.run_id == self.run_id and msg.key == self.poses_key:
            self.latest = msg

    def _on_config(self, msg: String) -> None:
        self.testbed_config = msg.data

    def _on_recording(self, msg: String) -> None:
        self._recording = msg.data   # the recorder announces each run's folder, and "" when it closed it
        if self.on_recording_announced is not None and self.announced_recording():
            self.on_recording_announced()

    def _on_recorded_run(self, msg: String) -> None:
        try:
            run = json.loads(msg.data)
            self._recorded_runs[str(run["run_id"])] = str(run["path"])
        except (ValueError, KeyError, TypeError):
            return   # not the recorder's
        if self.on_recording_announced is not None and run["run_id"] == self.run_id:
            self.on_recording_announced()

    def _on_recording_error(self, msg: String) -> None:
        """The recorder could not write this run's bag (a full disk): the run goes on, its recording
        stopped here; the report says so and gives no acceptance estimate."""
        try:
            error = json.loads(msg.data)
            run_id, why, path = str(error["run_id"]), str(error["why"]), str(error.get("path") or "")
        except (ValueError, TypeError, KeyError):
            return
        if run_id != self.run_id or self.end_sent or self.recorder_lost_at is not None:
            return   # another run's (latched), or known already
        self.recorder_lost_at = self.step
        self.recording_stopped_because, self.stopped_recording = why, path
        print("[robotarium] the recorder stopped recording this run: %s (heard at step %d). The experiment goes on; "
              "what was recorded until then stays readable%s." % (why, self.recorder_lost_at,
                                                                 " in %s" % path if path else ""), file=sys.stderr)

    def _on_claim(self, msg: String) -> None:
        ident = claim.parse(msg.data)
        if ident is not None:
            self.claims[ident["who"]] = ident

    def _on_restart(self, msg: String) -> None:
        """A node of the testbed was restarted (robotarium_core.restarts): during this run, the recorder's restart
        stops its recording (the run goes on); the safety node's stops the robots until the testbed arms the new
        process with the run, and the run goes on; the simulator's ends the run, named so, as does any node's
        give-up (`up` stopped the testbed: the node kept exiting)."""
        restart = restarts.parse(msg.data)
        if restart is not None and self.started_at is None:
            # The latched announcement of a restart before this run (heard as the topic matched): never this
            # run's, however close its time (a client started within CLOCK_SLACK of a restart in place took it
            # for its own and ended at step 0).
            self.restarts_heard.add(restart)
            return
        if (restart is None or self.run_id is None or self.end_sent or restart in self.restarts_heard
                or not restart.during(self.started_at, self.pids_at_start.get(restart.who))):
            return
        self.restarts_heard.add(restart)
        # where its presence lapsed, if it did
        step = (self.suspects.get(restart.who) or self.awaiting_restart.get(restart.who) or (None, self.step))[1]
        if restart.who == presence.RECORDER and not restart.gave_up:   # (a give-up stops the whole testbed)
            if self.recorder_lost_at is not None and not outcomes.recorder_lost(self.recording_stopped_because):
                return   # its recording stopped already, for a cause it named (a full disk): keep that one
            self.suspects.pop(presence.RECORDER, None)
            said = self.recorder_lost_at is not None
            self.recorder_lost_at = step if self.recorder_lost_at is None else self.recorder_lost_at
            self.recording_stopped_because = restarts.recording_stopped(restart)
            print("[robotarium] %s: recording %s at step %d. The experiment goes on; what was recorded until then "
                  "stays readable." % (restart.describe(), "stopped" if not said else "had stopped",
                                       self.recorder_lost_at), file=sys.stderr)
            return
        self.awaiting_restart.pop(restart.who, None)
        if restart.who == presence.SAFETY and not restart.gave_up:
            self.suspects.pop(presence.SAFETY, None)
            if self.safety_rearms > self._rearms_paired:   # armed again before the news of its restart came
                self._rearms_paired = self.safety_rearms
                self._went_on(restart, step)
                return
            self.safety_restart = (restart, step, time.monotonic() + REARM_WAIT)
            print("[robotarium] %s at step %d: the robots stopped; the experiment goes on once the testbed has armed "
                  "the new safety node." % (restart.describe(), step), file=sys.stderr)
            return
        if self.failure is None:
            self.failure_kind, self.failure = NodeRestarted, restarts.ended_run(restart, step)

    def _went_on(self, restart: restarts.Restart, step: int) -> None:
        self.safety_restarts.append(restarts.went_on(restart, step, self.step))
        print("[robotarium] the testbed armed the restarted safety node again at step %d: the experiment goes on."
              % self.step, file=sys.stderr)

    def _on_safety_rearmed(self, rearms: int) -> None:
        """This run's status says the testbed armed a restarted safety node again: it is back and guards the run."""
        self.safety_rearms = rearms
        self._resend_due = True
        self.suspects.pop(presence.SAFETY, None)
        self.awaiting_restart.pop(presence.SAFETY, None)
        if self.safety_restart is not None:
            restart, step, _ = self.safety_restart
            self.safety_restart, self._rearms_paired = None, rearms
            self._went_on(restart, step)

    def safety_restarts_said(self) -> list[str]:
        """What the run's record says of its safety node's restarts, one still waiting to be armed again included."""
        if self.safety_restart is None:
            return list(self.safety_restarts)
        restart, step, _ = self.safety_restart
        return self.safety_restarts + [restarts.not_armed_before_end(restart, step)]

    def _alive_here(self, who: str) -> bool:
        """Whether the process of node `who` (its claim) runs on this machine, neither stopped nor a zombie: a
        node alive but deaf to DDS, which its DdsStallWatch restarts in place."""
        return processes.runs_here(self.claims.get(who))

    def _on_status_bytes(self, data: bytes) -> None:
        """A status as its bytes: its head (state, run_id) read with cdr, the whole message
        deserialised only for an IDLE status of this run, the one _on_status acts on."""
        try:
            head = cdr.TESTBED_STATUS_HEAD.parse(data, max_string=len(data))
        except cdr.CdrError:
            return   # not a TestbedStatus: not the simulator's
        if head.run_id != self.run_id:
            return
        if head.safety_rearms > self.safety_rearms:
            self._on_safety_rearmed(head.safety_rearms)
        if head.state == TestbedStatus.STATE_IDLE:
            self._on_status(deserialize_message(data, TestbedStatus))

    def _on_status(self, msg: TestbedStatus) -> None:
        if msg.run_id != self.run_id or msg.state != TestbedStatus.STATE_IDLE:
            return
        self.idle_end_reason = msg.end_reason
        if msg.end_reason.startswith(outcomes.ENDED_BY_ITS_CLIENT) and not self.end_sent and self.unsent_end_at is None:
            # Ended by a request with our token that we did not send: a process holding the token.
            step = outcomes.step_of_end_reason(msg.end_reason, self.step)
            self.unsent_end_at = step
            print("[robotarium] %s." % outcomes.unsent_end(step), file=sys.stderr)
            if not (self.failure is not None and self.failure_kind is TestbedLost):
                self.failure_kind, self.failure = EndedByUnsentRequest, step
            return
        if not self.end_sent:
            self.failure_kind = self.failure_kind if self.failure is not None else EndedByTestbed
            reason = msg.end_reason or "no reason given"
            self.failure = self.failure if self.failure is not None else (
                "The experiment was %s." % reason if reason.startswith(outcomes.ENDED_BY_ITS_USER)
                else "%s%s." % (outcomes.ENDED_BY_TESTBED, reason))

    def _watch_testbed(self) -> None:
        """Follow the presence of the testbed's nodes (robotarium_core.presence), with the testbed's lease."""
        lease = self.config.node_lease
        for who in (presence.SIMULATOR, presence.SAFETY, presence.RECORDER):
            self.watches[who] = presence.Watch(self.node, presence.alive_topic(who), lease,
                                               on_lost=lambda who=who: self._on_node_lost(who))

    def _on_node_lost(self, who: str) -> None:
        if self.run_id is None or self.end_sent:
            return
        if who == presence.SAFETY and self.safety_restart is not None:
            return   # its restart was announced: the new process is awaited
        if who == "recorder" and self.recorder_lost_at is not None:
            return
        self.suspects.setdefault(who, (time.monotonic(), self.step))

    def confirm_losses(self) -> bool:
        """A node whose presence lapsed is lost once it stayed away another node_lease: on a loaded
        2-core machine a presence lapsed now and then for a moment (a burst of discovery or a flood
        starved the process's DDS threads) while the node went on working, and ended a run that was
        fine (a recorder then "stopped" recording a run it recorded whole). A lost recorder is reported
        as "recording stopped at step k" (k: where its presence lapsed). True when the experiment
        cannot go on."""
        for who, (since, step) in list(self.suspects.items()):
            watch = self.watches.get(who)
            if watch is not None and watch.alive:
                del self.suspects[who]   # it was there all along
            elif time.monotonic() - since < self.config.node_lease:
                continue
            elif who == "recorder":
                del self.suspects[who]
                if self.recorder_lost_at is not None:
                    continue   # its recording stopped already, for a cause it named (a full disk): keep that one
                self.recorder_lost_at = step
                self.recording_stopped_because = outcomes.RECORDER_GONE
                print("[robotarium] the recorder is gone: recording stopped at step %d. The experiment goes on; "
                      "what was recorded until then stays readable." % step, file=sys.stderr)
            elif self.failure is None and who not in self.awaiting_restart:
                del self.suspects[who]
                if self._alive_here(who):   # deaf, not dead: its restart in place will say so
                    self.awaiting_restart[who] = (time.monotonic() + STALL_RESTART_WAIT, step)
                else:
                    self._lost(who, step)
        for who, (deadline, step) in list(self.awaiting_restart.items()):
            watch = self.watches.get(who)
            if watch is not None and watch.alive:   # back: a restart it announces comes at once, if it was one
                deadline = min(deadline, time.monotonic() + BACK_WITHOUT_RESTART)
                self.awaiting_restart[who] = (deadline, step)
            if self.failure is None and time.monotonic() >= deadline:
                del self.awaiting_restart[who]
                self._lost(who, step)
        return self.failure is not None or bool(self.awaiting_restart)

    def _lost(self, who: str, step: int) -> None:
        what = {"simulator": "The simulator", "safety": "The safety node"}[who]
        self.failure_kind = TestbedLost
        self.failure = (
            "%s is gone (no sign of it for %g s) at step %d: the experiment cannot go on%s. Node logs are in "
            "log/testbed/ when ./robotarium started the testbed." % (
                what, 2 * self.config.node_lease, step,
                ", and the simulator stopped every robot" if who == "safety" else ""))

    def check(self) -> None:
        """Raise what ended the run (a node lost, ended by someone else) where it cannot go on."""
        if self.confirm_losses():
            if self.failure is None:   # a node deaf to DDS: its restart in place names the cause, or its wait ends
                self.spin_until(lambda: not self.confirm_losses() or self.failure is not None, STALL_RESTART_WAIT + 1.0)
            if self.failure is not None:
                raise self.failure_kind(self.failure)

    # -- plumbing --------------------------------------------------------------------------------------

    def spin_until(self, predicate: Callable[[], object], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not predicate():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            # (messages wake it at once; the graph - a reader matched - is looked at every GRAPH_POLL)
            self._executor.spin_once(timeout_sec=min(remaining, GRAPH_POLL))
        return True

    def call(self, client: Client, request: StartExperiment.Request | EndExperiment.Request, timeout: float = 30.0,
             resend: float | None = None) -> StartExperiment.Response | EndExperiment.Response:
        """The answer to `request`; with `resend` (s; only for a request answered the same however
        often it comes) sent again while unanswered."""
        if not wait_for_service(client, timeout):
            raise TestbedLost("The testbed's %s service is gone." % client.srv_name)
        deadline = time.monotonic() + timeout
        while True:
            future = client.call_async(request)
            if self.spin_until(future.done, min(resend or timeout, max(0.0, deadline - time.monotonic()))):
                return future.result()
            client.remove_pending_request(future)
            if time.monotonic() >= deadline:
                raise TestbedLost("The testbed's %s service did not answer within %.0f s."
                                  % (client.srv_name, timeout))

    def shutdown(self) -> None:
        """Leave DDS (the participant goes with the node) and stop a testbed started here. Leaving waits
        for Fast DDS's event thread: where that thread is stuck (a deadlock inside Fast DDS) the script goes
        on without DDS rather than hang at its end for ever (DDS_STUCK says so to the runner)."""
        global DDS_STUCK
        if self.node is not None:
            node, self.node = self.node, None
            stuck = DDS_STUCK or self._own_dds.running_or_stuck()
            if stuck and not DDS_STUCK:
                DDS_STUCK = stuck
                print("[robotarium] this script's Fast DDS could not be left: %s (a deadlock inside Fast DDS, "
                      "docs/faults.md); the script goes on without it" % stuck, file=sys.stderr, flush=True)
            if not stuck:   # else left as it is: the process ends without it (runner)
                self._executor.shutdown()
                wait_for_quiet_discovery(node)
                node.destroy_node()
                rclpy.try_shutdown(context=self._context)
        if self.local_testbed is not None:
            self.local_testbed.stop()
            self.local_testbed = None

