"""One experiment on the simulated testbed, without ROS: what a start asks for (validated into a
model), the run's id and secrets, and the bookkeeping its report and status are made of. The
simulator node (simulator_node.py) is the I/O around it: it makes a new Experiment at each start,
so nothing of one run leaks into the next, and keeps the last one after the end, for the IDLE
status that says how it ended.
"""
import dataclasses
import hashlib
import math
import re
import secrets
import time

import numpy as np

from robotarium_core import model, outcomes, rps2
from robotarium_sim import rps2_io
from robotarium_sim.hardware import HardwareTestbed

NAME = re.compile(r"[A-Za-z0-9_-]{1,64}")


def sha256(text):
    return hashlib.sha256(text.encode()).hexdigest()


def build_testbed(request, config):
    """The model a StartExperiment `request` asks for (model.Testbed, rps2.Testbed2 or
    HardwareTestbed) and the experiment's name; raises model.RobotariumError saying what is wrong."""
    name = request.name or "experiment"
    if not NAME.fullmatch(name):
        raise model.RobotariumError("name %r must be 1 to 64 letters, digits, '-' or '_'." % name)
    model.validate_number_of_robots(int(request.number_of_robots), config.max_robots)
    n = int(request.number_of_robots)
    given = (len(request.x), len(request.y), len(request.theta))
    if given == (0, 0, 0):
        poses = model.random_initial_conditions(n, np.random.default_rng(request.seed or None))
    elif given == (n, n, n):
        poses = np.array([request.x, request.y, request.theta], dtype=float)
    else:
        raise model.RobotariumError(
            "initial conditions need x, y and theta of length %d each, or all empty for random ones; "
            "received lengths %s." % (n, given))
    if request.api and request.api != rps2.API:
        raise model.RobotariumError("api must be '' (the guide's) or '%s' (2.x); received %r." % (rps2.API, request.api))
    if request.api == rps2.API and (request.hardware or config.hardware):
        raise model.RobotariumError(
            "the hardware-like mode models the guide's API only, not the 2.x sensors and drive-on phase: "
            "run this 2.x script without --hardware, on a testbed started without --hardware.")
    if request.api == rps2.API:
        return name, rps2_io.testbed_for(request, poses, config)
    if request.hardware or config.hardware:
        return name, HardwareTestbed(poses, config, seed=request.seed or None)
    return name, model.Testbed(poses, config)


class RunIds:
    """Run ids <name>_<YYYYmmdd-HHMMSS>, never one given before: two runs of one name started within a
    second get <...>_2, <...>_3 (a client must never take the end of an earlier run for its own, nor
    the recorder write both to one folder)."""

    def __init__(self):
        self.given = set()

    def new(self, name, now=None):
        base = run_id = "%s_%s" % (name, time.strftime("%Y%m%d-%H%M%S", time.localtime(now)))
        copies = 1
        while run_id in self.given:
            copies += 1
            run_id = "%s_%d" % (base, copies)
        self.given.add(run_id)
        return run_id


def new_secret():
    return secrets.token_hex(16)


@dataclasses.dataclass
class Experiment:
    """The current (or last) experiment's id, secrets and counters. The node's `testbed` is its model
    while it runs. The empty one (no run yet) says so in the status: no run id, nothing counted."""
    run_id: str = ""
    name: str = ""
    real_time: bool = True
    audit: bool = False            # a verification run: the safety node lets the script's commands through
    holder: str = ""               # who holds it (StartExperiment.holder)
    started_at: str = ""           # local time of day it started
    started_ns: int = 0            # epoch ns of its first RUNNING status (TestbedStatus.started); 0 until then
    # The client's token, the safety node's key on cmd_safe, the key on every poses message.
    token: str = ""
    safety_key: str = ""
    poses_key: str = ""
    tally: model.RunTally = dataclasses.field(default_factory=model.RunTally)   # first error steps, safety figures
    safety_interventions: int = 0
    ideal_interventions: int = 0   # of those, the ones a verification's certificate would have made too
    stale_pose_stops: int = 0
    commands_accepted: int = 0
    safe_arrays_heard: int = 0     # arrays with the safety key (each comes with a SafetyReport)
    reports_heard: int = 0         # SafetyReports of arrays (not STATUS_COUNTS_ONLY)
    last_command_step: int = 0     # the testbed's step when the last command was applied
    last_command_at: float = -math.inf   # time.monotonic() when it came (the client's sign of life too)
    dropped: dict = dataclasses.field(default_factory=lambda: dict.fromkeys(model.DROP_REASONS, 0))   # on cmd_safe
    dropped_requested: object = None   # the safety node's drop counts (robotarium_msgs DropCounts), from its reports
    requested_drops_before: dict = dataclasses.field(default_factory=dict)   # ... of its processes before a re-arm
    safety_rearms: int = 0         # times the safety node was restarted mid-run and armed again (the run went on)
    logged_drops: set = dataclasses.field(default_factory=set)   # drop reasons said in the log already
    last_tick: float = 0.0         # time.monotonic() of the last real-time tick (at first: the start)
    end_reason: str = ""           # who ended it ("ended by its client at step k", ...)
    outcome: int = outcomes.NONE   # how it ended (robotarium_core.outcomes), NONE while it runs
    outcome_detail: str = ""
    gate: model.StepGate = dataclasses.field(init=False)

    def __post_init__(self):
        self.gate = model.StepGate(self.real_time)

    @classmethod
    def started(cls, run_id, name, real_time, audit=False, holder="", now=None):
        """A new experiment with fresh secrets, started now."""
        now = time.monotonic() if now is None else now
        return cls(run_id=run_id, name=name, real_time=bool(real_time), audit=bool(audit), holder=holder,
                   started_at=time.strftime("%H:%M:%S"), token=new_secret(), safety_key=new_secret(),
                   poses_key=new_secret(), last_tick=now)

    @property
    def key_hashes(self):
        """SHA-256 of the poses key and the safety key (in status: a replay's messages are told apart)."""
        return sha256(self.poses_key), sha256(self.safety_key)

    def count_drop(self, reason):
        """Count an array dropped on cmd_safe; True the first time for `reason` (then the log says so)."""
        self.dropped[reason] += 1
        first = reason not in self.logged_drops
        self.logged_drops.add(reason)
        return first

    def count_safety_report(self, intervention, max_change, of_an_array=True, stale_stop=False, dropped=None,
                            ideal=False):
        """Count one of the safety node's reports (SafetyReport): of an array it sent unless it only
        carries drop counts; an intervention and how much it changed, a stop for want of fresh
        poses, and its drop counts."""
        if of_an_array:
            self.reports_heard += 1
        if intervention:
            self.safety_interventions += 1
            self.ideal_interventions += bool(ideal)
        self.tally.add_safety_report(intervention, max_change)
        if stale_stop:
            self.stale_pose_stops += 1
        self.dropped_requested = dropped

    def safety_rearmed(self):
        """The safety node was restarted mid-run and armed again: its process counts its drops afresh (those of
        the one before are kept), and the reports of the last arrays the one before sent will never come."""
        self.safety_rearms += 1
        self.requested_drops_before = self.requested_drop_counts()
        self.dropped_requested = None
        self.reports_heard = self.safe_arrays_heard

    def requested_drop_counts(self):
        """{reason: count} of the arrays the safety node dropped during this run, over its restarts."""
        return {reason: self.requested_drops_before.get(reason, 0) + getattr(self.dropped_requested, reason, 0)
                for reason in model.DROP_REASONS}

    @property
    def reports_missing(self):
        """Arrays of the safety node whose report has not come (yet)."""
        return max(0, self.safe_arrays_heard - self.reports_heard)
