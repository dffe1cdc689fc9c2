"""Which requested arrays the safety node filters, at which poses, and how it marks them (issue 22).
Plain Python, no ROS: the safety node calls it, and robotarium_safety/test/test_safety_guarantee.py
runs it on adversarial streams together with the simulator's rule (robotarium_core.model.StepGate).

Invariant: whoever sends arrays with the experiment's token, in whatever order and with whatever
step numbers, every array forwarded was filtered at the poses of the step it moves the robots from,
and is marked with that step plus one (cmd_safe `step`); lockstep forwards at most one per step,
real time the newest at the newest poses, filtered again at every new poses while it is in force.
What waits is bounded (WAITING_STEPS). The rules and why: docs/safety.md#the-safety-node.
"""
from typing import NamedTuple

import numpy as np

from robotarium_core import model, rps2

WAITING_STEPS = 2   # lockstep: a client's array may come before the poses it was computed from (see above)


class Guard:
    """The safety node's decisions for one experiment. Feed it the run's poses steps
    (`on_poses`) and the client's parsed arrays (`on_request`, `expire`); each returns
    (forward, drops): forward, a list of (request, step) to filter now at the newest poses and
    send marked `step` (request None: the commands in force); drops, a list of (reason, words) to count."""

    def __init__(self, real_time, lockstep_wait, command_timeout=0.5):
        self.real_time = real_time
        self.lockstep_wait = lockstep_wait
        self.command_timeout = command_timeout
        self.requested_at = None  # real time: when the client's newest array came (None: none yet)
        self.poses_step = -1      # the newest poses' step (-1: none yet)
        self.forwarded = 0        # lockstep: the last step forwarded
        self.waiting = {}         # lockstep: step -> (request, received) waiting for the poses of step - 1

    def on_poses(self, step, now=0.0):
        if step <= self.poses_step:
            return [], []         # older or the same (a reordering): the newest stay
        self.poses_step = step
        if self.real_time:
            if self.requested_at is not None and now - self.requested_at <= self.command_timeout:
                return [(None, step + 1)], []   # the commands in force, filtered again at these poses
            return [], []
        drops = [("stale", "step %d: the testbed is past it" % k) for k in sorted(self.waiting) if k <= step]
        for k in [k for k in self.waiting if k <= step]:
            del self.waiting[k]
        waiting = self.waiting.pop(step + 1, None)
        if waiting is None:
            return [], drops
        self.forwarded = step + 1
        return [(waiting[0], step + 1)], drops

    def on_request(self, request, now):
        if self.real_time:
            self.requested_at = now
            return [(request, self.poses_step + 1)], []
        step = request.step or self.poses_step + 1   # unnumbered: the next step
        if step == 0:
            return [(request, 0)], []   # unnumbered before any poses: the node sends a stop (it moves nothing)
        if step <= self.forwarded:
            return [], [("stale", "step %d was forwarded already" % step)]
        if step <= self.poses_step:
            return [], [("stale", "step %d: the testbed is past it (at step %d)" % (step, self.poses_step))]
        if step == self.poses_step + 1 and self.poses_step >= 0:
            self.forwarded = step
            return [(request, step)], []
        if step > self.poses_step + WAITING_STEPS or step < 1:
            return [], [("stale", "step %d: the testbed is at step %d" % (step, self.poses_step))]
        if step in self.waiting:
            return [], [("stale", "step %d is waiting for its poses already" % step)]
        self.waiting[step] = (request, now)
        return [], []

    def expire(self, now):
        """Arrays that waited longer than lockstep_wait for their poses: dropped."""
        late = [k for k, (_, received) in self.waiting.items() if now - received > self.lockstep_wait]
        for k in late:
            del self.waiting[k]
        return [("stale", "the poses of step %d did not come within lockstep_wait" % (k - 1)) for k in late]


class Filtered(NamedTuple):
    """What filter_commands made of one request."""
    safe: np.ndarray          # 2 x N, what the safety node sends
    requested: np.ndarray     # 2 x N, the request scaled to the wheel limits along its arc
    change: np.ndarray        # N, the largest change the certificate made to each robot's (v, omega); 0: untouched
    over_limits: bool         # the script's own commands exceed the actuator limits (2.x's rule for 2.x)
    fell_back: bool           # the certificate failed: `safe` is a stop


def filter_commands(certificate, commands, poses, config, api=""):
    """What the safety node sends for the requested `commands` (2 x N) at `poses`: the commands
    scaled to the wheel limits along their arc go through the certificate; a robot whose command it
    left alone gets the script's own command (the simulator scales it as the Robotarium would, once:
    scaling it here as well moved robots by 1e-16 m from the Robotarium's path), one it changed
    gets the change scaled to the wheel limits (keeping its arc); a stop if the certificate failed.
    Scaling to the limits is no change: the Robotarium scales too."""
    if api == rps2.API:
        over_limits = rps2.exceeds_wheel_limit(commands, config)
    else:
        over_limits = model.exceeds_actuator_limits(commands, **config.limits)
    requested = model.threshold_keeping_arc(commands, **config.limits)
    answer = certificate(requested, poses)
    if certificate.info["fallback"]:
        stop = np.zeros_like(requested)
        return Filtered(stop, requested, np.abs(requested).max(axis=0, initial=0.0), over_limits, True)
    changed = np.any(answer != requested, axis=0)
    safe = np.array(commands, dtype=float)
    if np.any(changed):
        safe[:, changed] = model.threshold_keeping_arc(answer[:, changed], **config.limits)
    change = np.where(changed, np.abs(safe - requested).max(axis=0, initial=0.0), 0.0)
    return Filtered(safe, requested, change, over_limits, False)
