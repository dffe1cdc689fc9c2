"""The Robotarium Python API (rps.robotarium.Robotarium) over ROS 2 topics: the DDS backend.

The contract (argument checks, constants, call order) is robotarium_abc.RobotariumABC; this
class talks to a testbed: the constructor starts an experiment (the start_experiment service),
each step() publishes the requested commands to the safety node and waits for the simulator's
next poses, and call_at_scripts_end() ends the experiment and prints the simulator's debug report.

The experiment belongs to this client: the start returns a secret token that goes on every command
and on the end request (nobody else's commands move the robots, nobody else ends the run but an
operator with ./robotarium end --force), and a poses key: poses without it (a replay, a stray
publisher) are ignored. The client holds a presence the testbed watches (a killed script frees the
testbed within client_lease seconds) and watches the simulator's, the safety node's and the
recorder's: step() raises within twice node_lease (0.75 s, then as long again to confirm: a presence
that lapsed on a loaded machine and comes back is no loss) naming the node that is gone, or saying
who ended the experiment, and a lost recorder is reported as "recording stopped at step k".

Modes: sim_in_real_time=True paces the loop at the testbed's 30 Hz (the simulator's timer;
a robot stops when its command is older than 0.5 s, as on the real testbed); False runs in
lockstep, one simulator step per step() call, as fast as the nodes allow, deterministically.
How to run (which testbed, a forced mode, progress lines) comes from robotarium_client.session.

The step's round trip is the hot path: commands are published and poses taken as CDR bytes
(robotarium_core.cdr, no Python object per robot), and the node is spun by
robotarium_core.executor.LeanExecutor (rclpy's default executor costs about half a millisecond
of Python per message).

Fresh poses in real time, as the real testbed's tracker gives them: step() returns the newest
poses the testbed published after the command was sent, however long the script's loop took.
step() takes every poses message its reader holds before sending (node_tools.take_waiting: the newest
step known then), waits for a later one and again takes all that came: a script whose loop takes
60 ms gets poses one tick old, not the 50 ticks (1.7 s) that reading the queued history one
message per step handed it. Lockstep is untouched: one command, one step, the poses of exactly
that step.
"""
from __future__ import annotations

import atexit
import os
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, NoReturn

import numpy as np

import robotarium_recording as recording
from robotarium_client import session
from robotarium_client.errors import (  # noqa: F401 - also robotarium_client.robotarium's, as before
    EXIT_TIME_LIMIT,
    EndedByTestbed,
    EndedByUnsentRequest,
    TestbedBusy,
    TestbedIncomplete,
    TestbedLost,
    TimeLimitReached,
)
from robotarium_client.progress import StepProgress
from robotarium_client.robotarium_abc import RobotariumABC
from robotarium_core import cdr, model, outcomes, run_record
from robotarium_core.config import DEFAULT, TestbedConfig
from robotarium_core.model import RobotariumError

if TYPE_CHECKING:
    from rclpy.client import Client
    from std_msgs.msg import String

    from robotarium_msgs.msg import TestbedStatus
    from robotarium_msgs.srv import EndExperiment, StartExperiment

STARTUP_WAIT = 60.0   # s for a testbed started here to come up
STEP_TIMEOUT = 10.0   # s without poses after a step() before we give up with an explanation
# s a start may take: a hardware arena (robotarium_hardware) answers once its drive-on phase brought the robots to
# the initial conditions, which took up to 30 s for the guide's listings on a loaded 2-core machine
START_WAIT = 180.0
CONFIG_WAIT = 2.0     # s for the testbed's latched configuration once its services answer
GRAPH_POLL = 0.01     # s between looks at what only the DDS graph says (a reader matched) while waiting


def incomplete_testbed_message(ns: str) -> str:
    """What a client says of a testbed in `ns` whose safety node does not answer (one line)."""
    return ("The testbed in %s on ROS_DOMAIN_ID %s is incomplete: no safety node answers, and without it the robots "
            "cannot move. Start one there (ros2 run robotarium_safety safety --ros-args -r __ns:=%s), or stop this "
            "testbed (./robotarium stop) and start a whole one (./robotarium up)."
            % (ns, os.environ.get("ROS_DOMAIN_ID", "0").strip() or "0", ns))


LINE_POLL = 0.5         # s between a waiting client's asks (well within the testbed's line_lease)
LINE_REPORT = 10.0      # s between lines saying who holds the testbed, when nothing else changed


def holder_of_this_process() -> str:
    """Who asks for the testbed, as those waiting and ./robotarium status show it."""
    import getpass
    import socket
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "?"
    return "%s@%s pid %d %s" % (user, socket.gethostname(), os.getpid(), os.path.basename(sys.argv[0] or "python"))


class Robotarium(RobotariumABC):
    """The Robotarium of the guide, on the ROS 2 testbed."""

    def __init__(self, number_of_robots: int = -1, show_figure: bool = True, sim_in_real_time: bool = True,
                 initial_conditions: np.ndarray = np.array([])) -> None:
        options = session.options
        # The testbed's own configuration replaces this once connected; a run's --config file
        # (e.g. more robots than the packaged 50) is what the arguments are checked against first.
        config = TestbedConfig.load(options.config_file) if options.config_file else DEFAULT
        super().__init__(number_of_robots, show_figure, sim_in_real_time, initial_conditions, config)
        if options.real_time is not None:
            self.sim_in_real_time = bool(options.real_time)
        self._options = options
        self._node = None
        self._local_testbed = None
        self._recording = ""   # the recorder's folder for this run, from its announcement
        self.run_info = None   # run_record.Experiment, once the experiment ended: run id, recording, report, counters
        self._progress = StepProgress(options.progress_interval, self.time_step,
                                      "real time" if self.sim_in_real_time else "lockstep")
        self._connect()
        self._adopt_testbed_config()
        limit = options.time_limit if options.time_limit is not None else self.config.time_limit
        self._time_limit = float(limit) if limit and float(limit) > 0 else None
        self._start_experiment()
        session.robotaria.append(self)
        session.remember_uncaught_exceptions()
        atexit.register(self._end_quietly)
        self._make_figure()

    # -- the backend -----------------------------------------------------------------------------

    def _advance(self, velocities: np.ndarray) -> np.ndarray:
        if self.sim_in_real_time:
            self._take_newest_poses()   # the newest step published before this command
            known = max(self._last_step, self._latest.step if self._latest is not None else 0)
            self._send(velocities, 0)  # unnumbered: the simulator's 30 Hz timer applies it at its next tick
            target = known + 1
        else:
            self._send(velocities, self._iterations)
            target = self._iterations
        poses = self._wait_for_step(target)
        self._progress(self._iterations)
        if self._time_limit is not None and self._latest.sim_time >= self._time_limit - 1e-9:
            self._stop_at_time_limit()
        return poses

    def _stop_at_time_limit(self) -> NoReturn:
        """End the experiment at its time limit as call_at_scripts_end() would, with the reason as
        the report's first line, and stop the script (TimeLimitReached)."""
        step, sim_time = self._latest.step, self._latest.sim_time
        note = ("Stopped at the time limit: %g s of testbed time (step %d, %.2f s); the rest of the script "
                "did not run." % (self._time_limit, step, sim_time))
        self._ended = True
        self._record_drawing(self._iterations)
        self._report = note + "\n" + self._end(outcomes.TIME_LIMIT, note)
        self.run_info.time_limit = {"limit": self._time_limit, "step": step, "sim_time": sim_time, "note": note}
        print(self._report, end="")
        self._after_report()
        raise TimeLimitReached(note)

    def _end(self, outcome: int = outcomes.COMPLETED, detail: str = "") -> str:
        from robotarium_msgs.srv import EndExperiment
        self._end_sent = True   # an IDLE status of this run from now on may be this request's
        if "recorder" in self._suspects:   # a lapse just before the end: settle whether the recorder is gone
            self._spin_until(lambda: self._confirm_losses() or "recorder" not in self._suspects, 2 * self.config.node_lease)
        self._check_testbed()
        # A testbed that was lost is asked briefly: it may be back, but nobody should wait for it.
        response = self._call(self._end_client, EndExperiment.Request(token=self._token, outcome=outcome, detail=detail),
                              timeout=3.0 if outcome == outcomes.TESTBED_LOST else 30.0)
        if not response.success:
            # Refused: if the testbed says its client ended the run, that end request was not ours (ours
            # was in flight when one with our token came first).
            if self._unsent_end_at is None and self._idle_end_reason.startswith(outcomes.ENDED_BY_ITS_CLIENT):
                self._unsent_end_at = outcomes.step_of_end_reason(self._idle_end_reason)
            if self._unsent_end_at is not None:
                self._failure_kind, self._failure = EndedByUnsentRequest, self._unsent_end_at
            self._check_testbed()   # ended meanwhile (lost, or by an operator): say so rather than "no experiment"
            raise RuntimeError("The testbed could not end the experiment: %s" % response.message)
        dropped = {name: {reason: int(getattr(counts, reason)) for reason in model.DROP_REASONS}
                   for name, counts in (("cmd_requested", response.dropped_cmd_requested),
                                        ("cmd_safe", response.dropped_cmd_safe))}
        report = response.report
        if self._recorder_lost_at is not None:   # no verdict on a run whose recording is incomplete
            report = report.replace(model.ACCEPTANCE_LIKELY, model.RECORDING_INCOMPLETE)
        self.run_info = run_record.Experiment(
            run_id=response.run_id, report=report, outcome=outcomes.NAMES[outcome], detail=detail, ended=True,
            recording=response.recording or self._announced_recording() or self._stopped_recording,
            steps=response.steps, collisions=response.collisions, boundary_violations=response.boundary_violations,
            actuator_limit_iterations=response.actuator_limit_iterations, command_timeouts=response.command_timeouts,
            real_time=self.sim_in_real_time, number_of_robots=self.number_of_robots, end_reason=response.end_reason,
            dropped=dropped, recording_stopped_at_step=self._recorder_lost_at,
            recording_stopped_because=self._recording_stopped_because, stale_pose_stops=response.stale_pose_stops,
            hardware=response.hardware, hardware_seed=response.hardware_seed, audit=response.audit,
            first_collision_step=response.first_collision_step or None,
            first_boundary_step=response.first_boundary_step or None,
            safety_interventions=response.safety_interventions, ideal_interventions=response.ideal_interventions)
        self._errors = {k: v for k, v in (("boundary", response.boundary_violations), ("collision", response.collisions),
                                          ("actuator", response.actuator_limit_iterations)) if v}
        return report

    def _finish(self, outcome: int, detail: str = "") -> str | None:
        """As RobotariumABC._finish; but an experiment that the testbed ended itself (an operator, a
        stopped testbed) or whose simulator or safety node is gone has nothing left to end here: the
        script was stopped with that cause, which was printed, and a second line ("could not end the
        experiment") would only repeat it as if something else had failed. ./robotarium run makes the
        results from the recording."""
        if self._failure is not None:
            self._ended = True
            return None
        return super()._finish(outcome, detail)

    def _announced_recording(self) -> str:
        """The recorder's folder for this run if it announced one (its name starts with the run id)."""
        ok = self._run_id and os.path.basename(self._recording).startswith(self._run_id)
        return self._recording if ok else ""

    def partial_run_info(self) -> run_record.Experiment:
        """What is known of a run whose end the testbed never confirmed (a lost testbed)."""
        info = run_record.Experiment(run_id=self._run_id or "", recording=self._announced_recording(),
                                     steps=self._latest.step if self._latest is not None else 0,
                                     real_time=self.sim_in_real_time, number_of_robots=self.number_of_robots)
        if getattr(self, "_unsent_end_at", None) is not None:
            info.ended, info.ended_by_unsent_request_at_step = True, self._unsent_end_at
        return info

    def _after_report(self) -> None:
        info = self.run_info
        for name, counts in info.dropped.items():
            if any(counts.values()):
                print("[robotarium] the testbed dropped command arrays on %s that were not this script's or not "
                      "valid: %s" % (name, ", ".join("%d %s" % (n, reason) for reason, n in counts.items() if n)),
                      file=sys.stderr)
        if info.stale_pose_stops:
            print("The safety node stopped the robots %d time(s) because the testbed's newest poses were older than "
                  "its pose_timeout (an overloaded testbed machine?)." % info.stale_pose_stops)
        if self._recorder_lost_at is not None:
            print("Run %s: recording stopped at step %d (%s)%s" % (
                info.run_id, self._recorder_lost_at, self._recording_stopped_because,
                "; what it recorded until then is in %s" % info.recording if info.recording else ""))
        elif info.recording:
            print("Run %s recorded in %s" % (info.run_id, info.recording))
        else:
            print("Run %s ended (no recorder was running, so it was not recorded)." % info.run_id)
        self._shutdown()

    # -- talking to the testbed ------------------------------------------------------------------

    def _connect(self) -> None:
        from rclpy.context import Context
        from rclpy.node import Node
        from std_msgs.msg import String

        from robotarium_bringup.testbed import LocalTestbed, security_enabled
        from robotarium_core.executor import LeanExecutor
        from robotarium_core.node_tools import init_context
        from robotarium_core.topics import (
            CMD_REQUESTED,
            CONFIG,
            DRAWING,
            DRAWING_QOS,
            END_EXPERIMENT,
            LATCHED,
            OUTPUT_QOS,
            POSES,
            RECORDING,
            RECORDING_ERROR,
            START_EXPERIMENT,
            STATUS,
            STATUS_QOS,
            TESTBED_QOS,
        )
        from robotarium_msgs.msg import RobotPoses, TestbedStatus, TwistArray
        from robotarium_msgs.srv import EndExperiment, StartExperiment

        self._ns = self._options.namespace
        self._token = ""
        self._poses_key = None
        self._presence = None
        self._watches = {}
        self._failure = None          # why the experiment cannot go on (a node lost, ended by someone else)
        self._failure_kind = TestbedLost
        self._end_sent = False        # this script sent its end request (call_at_scripts_end, or ending as it failed)
        self._unsent_end_at = None    # the step at which an end request with our token ended the run, if not ours
        self._idle_end_reason = ""    # who ended this run, as the simulator's IDLE status says
        self._suspects = {}           # {node: (monotonic time, step)} whose presence lapsed, not yet confirmed lost
        self._recorder_lost_at = None
        self._recording_stopped_because = None   # "the recorder is gone", "disk full", ...
        self._stopped_recording = ""             # the bag of a recording stopped by a write error
        # The testbed's Fast DDS settings for the script's participant too (node_tools.init_context): UDP
        # only; its writers' heartbeat every 0.1 s, so a lost packet of cmd_requested is sent again at once.
        self._context = Context()
        # With DDS Security (sros2/README.md) a script runs in the client enclave of the policy.
        init_context(context=self._context, node=False,
                     args=["--ros-args", "--enclave", "/robotarium/client"] if security_enabled() else [])
        self._node = Node("robotarium_client_%d" % os.getpid(), namespace=self._ns, context=self._context)
        self._executor = LeanExecutor(context=self._context)
        self._executor.add_node(self._node)
        self._latest = None
        self._run_id = None
        self._command_pub = self._node.create_publisher(TwistArray, CMD_REQUESTED, OUTPUT_QOS)
        self._poses_subscription = self._node.create_subscription(RobotPoses, POSES, self._on_poses, TESTBED_QOS,
                                                                  raw=True)
        self._node.create_subscription(TestbedStatus, STATUS, self._on_status, STATUS_QOS)
        # Made now, not at the first drawing: the recorder discovers it while the experiment starts.
        self._drawing_pub = self._node.create_publisher(String, DRAWING, DRAWING_QOS)
        self._drawing_message = String()
        self._testbed_config = None
        self._node.create_subscription(String, CONFIG, self._on_config, LATCHED)
        self._node.create_subscription(String, RECORDING, self._on_recording, LATCHED)
        self._node.create_subscription(String, RECORDING_ERROR, self._on_recording_error, LATCHED)
        self._start_client = self._node.create_client(StartExperiment, START_EXPERIMENT)
        self._end_client = self._node.create_client(EndExperiment, END_EXPERIMENT)

        local_allowed = self._options.local_testbed
        wait = self._options.connect_wait if local_allowed else max(self._options.connect_wait, STARTUP_WAIT)
        from robotarium_core.node_tools import wait_for_service
        if not wait_for_service(self._start_client, wait):
            if not local_allowed:
                self._shutdown()
                raise RuntimeError(
                    "No Robotarium testbed answers in namespace %s on ROS_DOMAIN_ID %s. Start one with "
                    "'./robotarium up' (here or on another machine of the domain)."
                    % (self._ns, os.environ.get("ROS_DOMAIN_ID", "0")))
            print("[robotarium] no testbed answers in %s: starting one on this machine" % self._ns, file=sys.stderr)
            self._local_testbed = LocalTestbed(ns=self._ns).start()
            if not wait_for_service(self._start_client, STARTUP_WAIT):
                failed = self._local_testbed.failed()
                self._shutdown()
                raise RuntimeError("The local testbed did not come up (exited: %s); see %s."
                                   % (failed, self._local_testbed.log_dir))

        self._ids = np.arange(self.number_of_robots)

    def _on_config(self, msg: String) -> None:
        self._testbed_config = msg.data

    def _on_recording(self, msg: String) -> None:
        self._recording = msg.data   # the recorder announces each run's folder, and "" when it closed it
        if self._run_id and not self._ended and self._announced_recording():
            session.note_started(self.partial_run_info())

    def _on_recording_error(self, msg: String) -> None:
        """The recorder could not write this run's bag (a full disk): the run goes on, its recording
        stopped here; the report says so and gives no acceptance estimate."""
        import json
        try:
            error = json.loads(msg.data)
            run_id, why, path = str(error["run_id"]), str(error["why"]), str(error.get("path") or "")
        except (ValueError, TypeError, KeyError):
            return
        if run_id != self._run_id or self._ended or self._recorder_lost_at is not None:
            return   # another run's (latched), or known already
        self._recorder_lost_at = self._latest.step if self._latest is not None else 0
        self._recording_stopped_because, self._stopped_recording = why, path
        print("[robotarium] the recorder stopped recording this run: %s (heard at step %d). The experiment goes on; "
              "what was recorded until then stays readable%s." % (why, self._recorder_lost_at,
                                                                 " in %s" % path if path else ""), file=sys.stderr)

    def _adopt_testbed_config(self) -> None:
        """Take the testbed's configuration (its latched `config` topic) for the constants and the
        checks of the initial conditions: a testbed run with another arena or time step is
        described by its own numbers. A testbed that publishes none uses the packaged default."""
        self._spin_until(lambda: self._testbed_config is not None, CONFIG_WAIT)
        if self._testbed_config is None:
            return
        config = TestbedConfig.from_yaml(self._testbed_config)
        if config != self.config:
            self._use_config(config)
            model.validate_number_of_robots(self.number_of_robots, config.max_robots)
            model.validate_initial_conditions(self.initial_conditions, self.number_of_robots,
                                              config.robot_diameter, config.arena)

    def _start_experiment(self) -> None:
        from robotarium_msgs.srv import StartExperiment
        self._watch_testbed()
        request = StartExperiment.Request(name=self._options.experiment_name, number_of_robots=self.number_of_robots,
                                          real_time=self.sim_in_real_time, hardware=bool(self._options.hardware),
                                          seed=int(self._options.seed), audit=bool(self._options.audit))
        request.x, request.y, request.theta = (row.tolist() for row in self.initial_conditions)
        self._complete_start_request(request)
        request.wait, request.holder = bool(self._options.wait), holder_of_this_process()
        # the streams are volatile: the run's first poses wait for our reader of them
        request.client_node = self._node.get_fully_qualified_name()
        # rmw_fastrtps drops a reply when the service has not matched the caller's reply reader within
        # 100 ms (a testbed found a moment ago, a loaded machine), and a start must not be sent twice:
        # first a start it refuses however often it comes, sent until answered; then the real one.
        self._call(self._start_client, StartExperiment.Request(name="!"), resend=1.0)
        response = self._wait_in_line(request)
        if not response.success:
            incomplete = not self._watches["safety"].seen   # the testbed's fault, not the request's
            self._shutdown()
            if incomplete:   # the simulator waited for the safety node in vain: say so, as the testbed's problem
                raise TestbedIncomplete(incomplete_testbed_message(self._ns))
            raise RobotariumError("The testbed refused to start the experiment: %s" % response.message)
        self._run_id = response.run_id
        if response.real_time and not self.sim_in_real_time:
            # An arena of real robots (robotarium_hardware) runs every experiment in real time, as the
            # Robotarium does: sim_in_real_time=False is the simulator's speed-up only.
            print("[robotarium] the testbed moves real robots: the experiment runs in real time (30 Hz), not in "
                  "lockstep", file=sys.stderr)
            self.sim_in_real_time = True
            self._progress = StepProgress(self._options.progress_interval, self.time_step, "real time")
        self._token = response.token
        session.note_started(self.partial_run_info())
        self._poses_key = response.poses_key
        from robotarium_core.presence import Presence
        self._presence = Presence(self._node, response.client_alive_topic, response.client_lease)
        self._last_step = 0
        self.poses = np.array([response.x, response.y, response.theta])
        # The safety node's cmd_requested reader is volatile (any reliable publisher may drive the
        # testbed): what we publish before our writer matched it would be lost, so the first command
        # waits for that match (robotarium_core.topics). Without a safety node nothing can move: say
        # so now rather than at the first step's timeout.
        if not self._spin_until(self._safety_node_matched, STEP_TIMEOUT):
            self._end_quietly()
            raise TestbedIncomplete(incomplete_testbed_message(self._ns))
        # The recorder's too, where there is one: else our first commands would be missing from the bag.
        from robotarium_core.presence import RECORDER
        from robotarium_core.topics import LISTENERS_WAIT, node_names, readers_matched
        if RECORDER in node_names(self._node):
            self._spin_until(lambda: readers_matched(self._node, self._command_pub, RECORDER), LISTENERS_WAIT)
        # Until the simulator follows our presence, a crash of this process would free the testbed
        # only after its discovery wait (10 s) instead of client_lease: wait for it (it takes moments).
        if self._spin_until(lambda: self._presence.publisher.get_subscription_count() > 0, STEP_TIMEOUT):
            self._presence.announce()
        # Likewise a node is reported lost only once we saw it there: wait for the simulator's and
        # the safety node's first sign of life (moments; their presences assert every 0.17 s).
        self._spin_until(lambda: self._watches["simulator"].seen and self._watches["safety"].seen, STEP_TIMEOUT)

    def _wait_in_line(self, request: StartExperiment.Request) -> StartExperiment.Response:
        """Ask to start until the testbed takes us: a busy testbed puts a waiting client in its line
        (first come, first served; robotarium_core.line), and we say our place and who holds it
        whenever that changes (and every LINE_REPORT s). Ctrl-C leaves the line (the testbed forgets
        a ticket nobody asks with)."""
        said, said_at = None, 0.0
        while True:
            response = self._call(self._start_client, request, timeout=START_WAIT)
            if not response.busy:
                if said is not None:   # it waited: say that its turn came, not only what it waited for
                    print("[robotarium] your turn: the testbed is free%s" % (
                        ", starting the experiment" if response.success else ""), file=sys.stderr, flush=True)
                return response
            if not request.wait:
                self._shutdown()
                raise TestbedBusy("The testbed in %s is busy: %s. Run again without --no-wait to wait in line for it "
                                  "(./robotarium status shows who holds it)." % (self._ns, response.holding))
            request.ticket = response.ticket
            news = (response.place, response.holding.split(", step")[0])
            if news != said or time.monotonic() - said_at > LINE_REPORT:
                print("[robotarium] waiting for the testbed: number %d in line; it is held by %s (Ctrl-C leaves the "
                      "line)" % (response.place, response.holding), file=sys.stderr, flush=True)
                said, said_at = news, time.monotonic()
            self._spin_until(lambda: False, LINE_POLL)

    def _complete_start_request(self, request: StartExperiment.Request) -> None:
        """What a subclass adds to the StartExperiment request (robotarium2: the 2.x API's fields)."""

    def _watch_testbed(self) -> None:
        """Follow the presence of the testbed's nodes (robotarium_core.presence), with the testbed's lease."""
        from robotarium_core import presence
        lease = self.config.node_lease
        for who in (presence.SIMULATOR, presence.SAFETY, presence.RECORDER):
            self._watches[who] = presence.Watch(self._node, presence.alive_topic(who), lease,
                                                on_lost=lambda who=who: self._on_node_lost(who))

    def _on_node_lost(self, who: str) -> None:
        if self._run_id is None or self._ended:
            return
        step = self._latest.step if self._latest is not None else 0
        if who == "recorder" and self._recorder_lost_at is not None:
            return
        self._suspects.setdefault(who, (time.monotonic(), step))

    def _confirm_losses(self) -> bool:
        """A node whose presence lapsed is lost once it stayed away another node_lease: on a loaded
        2-core machine a presence lapsed now and then for a moment (a burst of discovery or a flood
        starved the process's DDS threads) while the node went on working, and ended a run that was
        fine (a recorder then "stopped" recording a run it recorded whole). A lost recorder is reported
        as "recording stopped at step k" (k: where its presence lapsed). True when the experiment
        cannot go on."""
        for who, (since, step) in list(self._suspects.items()):
            watch = self._watches.get(who)
            if watch is not None and watch.alive:
                del self._suspects[who]   # it was there all along
            elif time.monotonic() - since < self.config.node_lease:
                continue
            elif who == "recorder":
                del self._suspects[who]
                if self._recorder_lost_at is not None:
                    continue   # its recording stopped already, for a cause it named (a full disk): keep that one
                self._recorder_lost_at = step
                self._recording_stopped_because = outcomes.RECORDER_GONE
                print("[robotarium] the recorder is gone: recording stopped at step %d. The experiment goes on; "
                      "what was recorded until then stays readable." % step, file=sys.stderr)
            elif self._failure is None:
                what = {"simulator": "The simulator", "safety": "The safety node"}[who]
                self._failure_kind = TestbedLost
                self._failure = (
                    "%s is gone (no sign of it for %g s) at step %d: the experiment cannot go on%s. Node logs are in "
                    "log/testbed/ when ./robotarium started the testbed." % (
                        what, 2 * self.config.node_lease, step,
                        ", and the simulator stopped every robot" if who == "safety" else ""))
        return self._failure is not None

    def _on_status(self, msg: TestbedStatus) -> None:
        from robotarium_msgs.msg import TestbedStatus
        if msg.run_id != self._run_id or msg.state != TestbedStatus.STATE_IDLE:
            return
        self._idle_end_reason = msg.end_reason
        if msg.end_reason.startswith(outcomes.ENDED_BY_ITS_CLIENT) and not self._end_sent and self._unsent_end_at is None:
            # Ended by a request with our token that we did not send: a process holding the token.
            step = outcomes.step_of_end_reason(msg.end_reason, self._latest.step if self._latest is not None else 0)
            self._unsent_end_at = step
            print("[robotarium] %s." % outcomes.unsent_end(step), file=sys.stderr)
            if not (self._failure is not None and self._failure_kind is TestbedLost):
                self._failure_kind, self._failure = EndedByUnsentRequest, step
            return
        if not self._ended:
            self._failure_kind = self._failure_kind if self._failure is not None else EndedByTestbed
            reason = msg.end_reason or "no reason given"
            self._failure = self._failure if self._failure is not None else (
                "The experiment was %s." % reason if reason.startswith(outcomes.ENDED_BY_ITS_USER)
                else "%s%s." % (outcomes.ENDED_BY_TESTBED, reason))

    def _check_testbed(self) -> None:
        """Raise RuntimeError when the experiment cannot go on (a node lost, ended by someone else)."""
        if self._confirm_losses():
            raise self._failure_kind(self._failure)

    def _safety_node_matched(self) -> bool:
        from robotarium_core.topics import readers_matched
        return readers_matched(self._node, self._command_pub, "safety")

    def _on_poses(self, data: bytes) -> None:
        try:
            msg = cdr.ROBOT_POSES.parse(data, max_elements=self.number_of_robots)
        except cdr.CdrError:
            return   # not poses of this run's size: not this run's poses
        # Only the simulator's poses of this run carry its key (not a replay's, not a stray publisher's).
        if msg.run_id == self._run_id and msg.key == self._poses_key:
            self._latest = msg

    def _take_newest_poses(self) -> None:
        """Take every poses message the reader holds now (this run's newest ends up in _latest)."""
        from robotarium_core.node_tools import take_waiting
        for data in take_waiting(self._poses_subscription):
            self._on_poses(data)

    def _send(self, velocities: np.ndarray, step: int) -> None:
        v, w = velocities
        sec, nanosec = self._node.get_clock().now().seconds_nanoseconds()
        self._command_pub.publish(cdr.TWIST_ARRAY.build(sec=sec, nanosec=nanosec, frame_id="arena", token=self._token,
                                                        step=step, ids=self._ids, twists=cdr.twists(v, w)))

    def _publish_drawing(self, message: dict[str, object]) -> None:
        if self._node is not None:
            self._drawing_message.data = recording.encode_drawing(message)
            self._drawing_pub.publish(self._drawing_message)

    def _wait_for_step(self, target: int) -> np.ndarray:
        arrived = self._spin_until(lambda: self._confirm_losses() or (
            self._latest is not None and self._latest.step >= target), STEP_TIMEOUT)
        self._check_testbed()
        if not arrived:
            raise TestbedLost(
                "The testbed sent no poses for step %d within %.0f s. Is the safety node running (robots cannot "
                "move without it)? Node logs are in log/testbed/<namespace>_<domain>_<pid>/ when ./robotarium started "
                "the testbed (./robotarium status lists the testbeds of this machine)."
                % (target, STEP_TIMEOUT))
        self._take_newest_poses()   # a still newer one may have come meanwhile
        msg = self._latest
        self._last_step = msg.step
        return np.array([msg.x, msg.y, msg.theta])   # a copy: the message's arrays are views of its bytes

    def _spin_until(self, predicate: Callable[[], object], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not predicate():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            # (messages wake it at once; the graph - a reader matched - is looked at every GRAPH_POLL)
            self._executor.spin_once(timeout_sec=min(remaining, GRAPH_POLL))
        return True

    def _call(self, client: Client, request: StartExperiment.Request | EndExperiment.Request, timeout: float = 30.0,
              resend: float | None = None) -> StartExperiment.Response | EndExperiment.Response:
        """The answer to `request`; with `resend` (s; only for a request answered the same however
        often it comes) sent again while unanswered."""
        from robotarium_core.node_tools import wait_for_service
        if not wait_for_service(client, timeout):
            raise TestbedLost("The testbed's %s service is gone." % client.srv_name)
        deadline = time.monotonic() + timeout
        while True:
            future = client.call_async(request)
            if self._spin_until(future.done, min(resend or timeout, max(0.0, deadline - time.monotonic()))):
                return future.result()
            client.remove_pending_request(future)
            if time.monotonic() >= deadline:
                raise TestbedLost("The testbed's %s service did not answer within %.0f s."
                                  % (client.srv_name, timeout))

    def _end_quietly(self) -> None:
        """At exit without call_at_scripts_end (a script run with plain python that raised or just
        ended; ./robotarium run ends it before, saying how): free the testbed for the next run,
        saying how the run ended."""
        if not self._ended and self._node is not None:
            self._ended = True
            simulator = self._watches.get("simulator")
            # (a testbed whose service is gone has ended the experiment itself, or is gone with it)
            if self._token and not (simulator is not None and simulator.lost) and self._end_client.service_is_ready():
                outcome, detail = session.outcome_of_uncaught(self._iterations)
                self._end_sent = True
                try:
                    from robotarium_msgs.srv import EndExperiment
                    self._call(self._end_client, EndExperiment.Request(token=self._token, outcome=outcome,
                                                                       detail=detail), timeout=5.0)
                except Exception:
                    pass
        self._shutdown()

    def _shutdown(self) -> None:
        import rclpy

        from robotarium_core.node_tools import wait_for_quiet_discovery
        if self._node is not None:
            self._executor.shutdown()
            wait_for_quiet_discovery(self._node)   # the participant goes with the node
            self._node.destroy_node()
            self._node = None
            rclpy.try_shutdown(context=self._context)
        if self._local_testbed is not None:
            self._local_testbed.stop()
            self._local_testbed = None
