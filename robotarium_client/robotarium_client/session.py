"""How a script's Robotarium is to run: the choices of `./robotarium run`, passed explicitly.

`./robotarium run` starts the script through `robotarium_cli.runner`, which sets `options`
before the script's first line; a script started any other way (`python my_script.py`) gets the
defaults below. Three user-facing environment variables are read here and nowhere else:
ROBOTARIUM_NAMESPACE (which testbed: /robotarium by default), ROBOTARIUM_PROGRESS (seconds
between progress lines; 0: none) and ROBOTARIUM_RPS (which Robotarium API: guide, 2 or auto; see
robotarium_client.api_level).
"""
import dataclasses
import json
import os
import re
import sys

from robotarium_client.errors import (
    EndedByTestbed,
    EndedByUnsentRequest,
    NodeRestarted,
    TestbedBusy,
    TestbedIncomplete,
    TestbedLost,
)
from robotarium_core import outcomes
from robotarium_core.model import RobotariumError
from robotarium_core.topics import namespace_from_environment


def progress_from_environment(default):
    value = os.environ.get("ROBOTARIUM_PROGRESS", "")
    try:
        seconds = float(value) if value else default
    except ValueError:
        raise RobotariumError("ROBOTARIUM_PROGRESS must be a number of seconds (0: no progress lines); "
                              "received %r." % value) from None
    return seconds if seconds > 0 and seconds != float("inf") else 0.0


RPS_APIS = ("auto", "guide", "2")


def rps_api_from_environment():
    value = os.environ.get("ROBOTARIUM_RPS", "auto") or "auto"
    if value not in RPS_APIS:
        raise RobotariumError("ROBOTARIUM_RPS must be one of %s (the Robotarium API a script is written against); "
                              "received %r." % (", ".join(RPS_APIS), value))
    return value


def experiment_name_of(path):
    """A run name from a script's file name: letters, digits, '-' and '_' (the simulator's rule)."""
    name = os.path.splitext(os.path.basename(path or "experiment"))[0]
    return re.sub(r"[^A-Za-z0-9_-]", "_", name)[:64] or "experiment"


@dataclasses.dataclass
class RunOptions:
    # True/False forces real time / lockstep whatever the script says; None: as the script says.
    real_time: object = None
    # Start a testbed on this machine when none answers (False: one is up, or coming up: wait for it).
    local_testbed: bool = True
    # Seconds to wait for a testbed to answer before starting one here (or, without local_testbed, giving up).
    connect_wait: float = 3.0
    namespace: str = dataclasses.field(default_factory=namespace_from_environment)
    experiment_name: str = dataclasses.field(default_factory=lambda: experiment_name_of(sys.argv[0] if sys.argv else ""))
    progress_interval: float = dataclasses.field(default_factory=lambda: progress_from_environment(0.0))
    # Seconds of testbed time after which the experiment is ended and the script stopped (None: the
    # testbed configuration's time_limit; 0: no limit).
    time_limit: object = None
    # The testbed configuration file the run was started with (--config), None: the packaged one.
    config_file: object = None
    # Ask for the hardware-like model (latency, noise, wheel dynamics) for this run.
    hardware: bool = False
    # Seed of the hardware-like model (0: the testbed draws one and the report names it).
    seed: int = 0
    # Which Robotarium API the script is written against: "guide", "2" or "auto" (api_level.decide).
    rps_api: str = dataclasses.field(default_factory=rps_api_from_environment)
    # A verification run (./robotarium verify only): the safety node audits and lets the script's own
    # commands through, so the debug report counts what the Robotarium's verification counts.
    audit: bool = False
    # Wait in line for a busy testbed (first come, first served); False: refuse at once (--no-wait).
    wait: bool = True

    def to_json(self):
        return json.dumps(dataclasses.asdict(self))

    @classmethod
    def from_json(cls, text):
        return cls(**json.loads(text))


options = RunOptions()

# The Robotarium objects the script made, newest last (the runner reads how each run ended).
robotaria = []

# Set by the runner (./robotarium run): {"log": the run's log, "started": where note_started writes}.
run_files = None


def note_started(experiment):
    """Under ./robotarium run, keep what is known of the running experiment (a run_record.Experiment:
    run id, recording) in the runner's started.json, so that its run is found even if this process
    is killed outright."""
    path = run_files and run_files.get("started")
    if not path:
        return
    try:
        with open(path + ".tmp", "w") as f:
            json.dump(experiment.to_dict(), f)
        os.replace(path + ".tmp", path)
    except OSError:
        pass   # only a help for the one who finishes the run folder

# The exception that ended a script run with plain python (seen by sys.excepthook before the exit
# handler ends the experiment), so that the recording says how the run ended.
uncaught = None


class Interrupted(BaseException):
    """A signal asked the script to stop (SIGTERM, SIGHUP): raised in it like KeyboardInterrupt."""

    def __init__(self, signal_name):
        super().__init__(signal_name)
        self.signal_name = signal_name


def remember_uncaught_exceptions():
    if getattr(sys.excepthook, "robotarium", False):
        return
    previous = sys.excepthook

    def hook(exc_type, exc, traceback):
        global uncaught
        uncaught = exc
        previous(exc_type, exc, traceback)

    hook.robotarium = True
    sys.excepthook = hook


def describe_exception(exc):
    """'KeyError: 'goal'' - the exception's type and the first line of its message."""
    text = str(exc).strip().splitlines()
    return "%s: %s" % (type(exc).__name__, text[0]) if text else type(exc).__name__


def failure_of(exc, step, where=""):
    """(outcome, detail) of a run that an exception ended at `step` (robotarium_core.outcomes);
    `where` says where in the script, e.g. "line 57 of go.py"."""
    at = "at step %d%s" % (step, " (%s)" % where if where else "")
    if isinstance(exc, EndedByUnsentRequest):   # a process holding the run's token ended it
        return outcomes.ENDED_BY_UNSENT_REQUEST, outcomes.unsent_end(exc.step)
    if isinstance(exc, KeyboardInterrupt):
        return outcomes.INTERRUPTED, "interrupted by Ctrl-C (SIGINT) %s" % at
    if isinstance(exc, Interrupted):
        return outcomes.INTERRUPTED, "interrupted by %s %s" % (exc.signal_name, at)
    if isinstance(exc, EndedByTestbed):   # an operator's end --force, a testbed that was stopped
        return outcomes.INTERRUPTED, "interrupted %s: %s" % (at, str(exc).rstrip("."))
    if isinstance(exc, TestbedBusy):
        return outcomes.TESTBED_BUSY, str(exc).rstrip(".")
    if isinstance(exc, TestbedIncomplete):
        return outcomes.TESTBED_INCOMPLETE, str(exc).split(", and without")[0].rstrip(".")
    if isinstance(exc, NodeRestarted):   # its words name the node, the restart and the step
        return outcomes.TESTBED_LOST, str(exc).rstrip(".")
    if isinstance(exc, TestbedLost):
        return outcomes.TESTBED_LOST, "the testbed was lost %s: %s" % (at, str(exc).split(". ")[0])
    return outcomes.SCRIPT_ERROR, "the script raised %s %s" % (describe_exception(exc), at)


def outcome_of_uncaught(step):
    """(outcome, detail) for an experiment still running when the script's process exits."""
    if uncaught is not None:
        return failure_of(uncaught, step)
    return outcomes.NO_END, "the script ended without calling call_at_scripts_end() (step %d)" % step
