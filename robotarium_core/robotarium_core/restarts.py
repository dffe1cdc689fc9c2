"""A testbed node restarted while the testbed runs: the record of it, who announces it, and what a run in
progress makes of it. Plain Python, but for announce() (an rclpy publisher).

Two things restart a node: `./robotarium up`, whose supervisor (robotarium_bringup.supervisor) starts a node
that exited (a crash, SIGKILL) again as a new process, and the node itself, which starts afresh in the same
process when its Fast DDS participant deadlocked (robotarium_core.dds_health.DdsStallWatch, node_main's
restart_in_place). Either way a `Restart` is announced on the hidden, latched `<ns>/_restarted/<who>`: `up`
at once (it saw the exit), a node restarted in place once it is back (its DDS was stuck until then). A
client whose run that node served reads it and names the restart as its run's cause ("testbed node
restarted at step k: the safety node exited (killed by SIGKILL) and ./robotarium up restarted it"), where it
would otherwise only have seen the node go; a run whose recorder restarted goes on, its recording stopped. A node
that keeps exiting is not restarted: `up` announces that it gave up (`gave_up`) and stops the whole testbed, and the
run in progress ends naming that node.
The record travels to the restarted process in ENV (a recorder restarted mid-run leaves that run alone: its
bag is the one the old recorder wrote). Measured: docs/faults.md.
"""
import dataclasses
import json
import os
import signal
import time

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from robotarium_core import outcomes

ENV = "ROBOTARIUM_RESTARTED"   # the Restart that started this process (JSON), for the restarted node

BY_UP = "./robotarium up"      # `by`: who restarted the node
IN_PLACE = "in place"

# Keyless: `up` and the node restarted in place write the same topic; each writer's last few are kept.
QOS = QoSProfile(depth=4, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
NAMES = {"safety": "safety node"}   # the kinds for people ("the simulator", "the safety node", "the recorder")
# s a restart's time may precede a run's start (clocks of two machines, a run started in the same moment)
# and still count as one during the run
CLOCK_SLACK = 1.0


def topic(who):
    """The hidden topic a restart of `who` (simulator, safety, recorder) is announced on."""
    return "_restarted/" + who


def node_name(who):
    """"the safety node", "the simulator": the node `who` for people."""
    return "the " + NAMES.get(who, who)


def exit_cause(returncode):
    """How a process ended, from its Popen returncode: "killed by SIGKILL", "exited with code 1"."""
    if returncode is None:
        return "still running"
    if returncode < 0:
        try:
            return "killed by %s" % signal.Signals(-returncode).name
        except ValueError:
            return "killed by signal %d" % -returncode
    return "exited with code %d" % returncode


@dataclasses.dataclass(frozen=True)
class Restart:
    """One restart of a testbed node."""
    who: str          # simulator, safety, recorder (robotarium_core.presence's kinds)
    cause: str        # why its last process ended: "exited (killed by SIGKILL)", "Fast DDS stopped in it"
    by: str           # BY_UP or IN_PLACE
    count: int        # the node's restarts so far, this one included
    at: float         # epoch seconds the old process was found gone (or stuck)
    old_pid: int = 0  # the process that ended (in place: the same pid goes on)
    back_at: float = 0.0   # in place: epoch seconds the node was back, announcing it (0: not known)
    gave_up: bool = False  # not restarted: it kept exiting and `up` stopped the whole testbed (Supervisor)

    def to_json(self):
        return json.dumps(dataclasses.asdict(self))

    def describe(self):
        """"the safety node exited (killed by SIGKILL) and ./robotarium up restarted it (restart 1)"."""
        if self.gave_up:
            return "%s %s and %s stopped the testbed" % (node_name(self.who), self.cause, self.by)
        if self.by == IN_PLACE:
            return "%s stopped answering (%s) and restarted in place (restart %d)" % (
                node_name(self.who), self.cause, self.count)
        return "%s %s and %s restarted it (restart %d)" % (node_name(self.who), self.cause, self.by, self.count)

    def during(self, started_at, pid_at_start=None):
        """Whether it happened during a run started at epoch `started_at`. A node restarted in place that was
        back before the run began (within CLOCK_SLACK) served the run afresh: a client that started right
        after such a restart heard its latched announcement late, and ended at step 0 (a whole-suite run).
        `pid_at_start`: the node's process when the run began (its claim), if known: a run begun on the
        process `up` started in place of the old one was never served by the old one, however close in time."""
        if started_at is None or (self.back_at and self.back_at < started_at + CLOCK_SLACK):
            return False
        if self.by == BY_UP and self.old_pid and pid_at_start and pid_at_start != self.old_pid:
            return False
        return self.at >= started_at - CLOCK_SLACK

    def back(self):
        """This restart, its node back now (what the node restarted in place announces)."""
        return dataclasses.replace(self, back_at=time.time())


def parse(text):
    """A Restart from its JSON, or None for anything malformed (never raises)."""
    try:
        value = json.loads(text)
        return Restart(who=str(value["who"]), cause=str(value["cause"]), by=str(value["by"]),
                       count=int(value["count"]), at=float(value["at"]), old_pid=int(value.get("old_pid", 0)),
                       back_at=float(value.get("back_at", 0.0)), gave_up=bool(value.get("gave_up", False)))
    except (ValueError, TypeError, KeyError, AttributeError):
        return None


def of_this_process():
    """The Restart that started this process (ENV), or None."""
    return parse(os.environ.get(ENV, "")) if os.environ.get(ENV) else None


def in_place(who, cause, previous=None):
    """The Restart of a node of kind `who` starting afresh in this process for `cause`; `previous`: the
    restart that started this process, if any (its count goes on)."""
    return Restart(who=who, cause=cause, by=IN_PLACE, count=(previous.count if previous else 0) + 1,
                   at=time.time(), old_pid=os.getpid())


def not_armed_again(restart, step, wait):
    """What ended a run whose safety node was restarted at `step` and not armed again within `wait` s."""
    return ("testbed node restarted at step %d: %s, and the testbed did not arm it again within %.0f s; the experiment "
            "cannot go on" % (step, restart.describe(), wait))


def went_on(restart, step, armed_at):
    """What a run says of a safety node restarted at `step` that the testbed armed again at `armed_at`."""
    return "%s at step %d; the testbed armed it again at step %d and the run went on" % (restart.describe(), step,
                                                                                         armed_at)


def not_armed_before_end(restart, step):
    """What a run says of a safety node restarted at `step` that the run ended before the testbed armed it again."""
    return ("%s at step %d; the run ended before the testbed armed it again (the robots stood still from then on)"
            % (restart.describe(), step))


def ended_run(restart, step):
    """What ended a run that the restart of its simulator or safety node hit at `step` (or any node's give-up:
    `up` then stopped the whole testbed)."""
    if restart.gave_up:
        return "the testbed stopped at step %d: %s; the experiment cannot go on" % (step, restart.describe())
    return ("testbed node restarted at step %d: %s; the experiment cannot go on (the run's state on that node was "
            "lost with its process)" % (step, restart.describe()))


def recording_stopped(restart):
    """Why a run's recording stopped when its recorder restarted (run.json's recording_stopped_because)."""
    return "%s: %s" % (outcomes.RECORDER_RESTARTED, restart.describe())


def announce(node, restart):
    """Publish `restart` (latched) from rclpy `node`; returns the publisher (keep it: it holds the message)."""
    from std_msgs.msg import String
    publisher = node.create_publisher(String, topic(restart.who), QOS)
    publisher.publish(String(data=restart.to_json()))
    return publisher
