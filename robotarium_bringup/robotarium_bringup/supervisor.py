"""`./robotarium up` as a supervisor: what to do when one of its nodes exits on its own. Plain Python.

A node that exits while `up` runs (a crash, SIGKILL, the OOM killer) is started again, as a new process
with the same command line, rather than the whole testbed stopped: the testbed serves the next runs, and
the run in progress is told through the restart's announcement (robotarium_core.restarts). A node that
keeps exiting is not started for ever: more than RESTART_LIMIT exits of one node within RESTART_WINDOW
seconds and `up` stops, saying which node keeps dying and how it ended. The shell around this is up's loop
(robotarium_cli.verb.up) and LocalTestbed.restart (robotarium_bringup.testbed).
"""
import collections
import dataclasses
import time

from robotarium_core import restarts

RESTART_LIMIT = 3       # restarts of one node within RESTART_WINDOW; its next exit stops up
RESTART_WINDOW = 60.0   # s


@dataclasses.dataclass(frozen=True)
class Decision:
    """What up does about one node's exit: restart it (with `restart`, the record to announce), or stop."""
    who: str
    returncode: int
    restart: restarts.Restart | None   # None: give up (the node keeps dying)
    line: str                          # what up says on its console
    announcement: restarts.Restart     # what the run in progress hears: the restart, or the give-up (gave_up)


class Supervisor:
    """The restarts of each node of one testbed: `exited(who, returncode, pid)` decides, remembering each."""

    def __init__(self, limit=RESTART_LIMIT, window=RESTART_WINDOW, clock=time.time):
        self.limit, self.window, self.clock = limit, window, clock
        self.exits = collections.defaultdict(list)   # who: epoch seconds of its exits within the window
        self.count = collections.Counter()           # who: restarts so far (all time)

    def exited(self, who, returncode, pid=0):
        now = self.clock()
        recent = [t for t in self.exits[who] if now - t < self.window] + [now]
        self.exits[who] = recent
        how = restarts.exit_cause(returncode)
        if len(recent) > self.limit:
            which = "%s, its %d%s exit within %.0f s" % (how, len(recent), _ordinal(len(recent)), self.window)
            # The run in progress hears it: without it, it named whichever node it missed first (up stops them all)
            gave_up = restarts.Restart(who=who, cause="kept exiting (%s)" % which, by=restarts.BY_UP,
                                       count=self.count[who], at=now, old_pid=pid, gave_up=True)
            return Decision(who, returncode, None, "%s keeps exiting: %s; not restarting it again: stopping the "
                            "testbed" % (restarts.node_name(who), which), gave_up)
        self.count[who] += 1
        restart = restarts.Restart(who=who, cause="exited (%s)" % how, by=restarts.BY_UP, count=self.count[who],
                                   at=now, old_pid=pid)
        return Decision(who, returncode, restart, "%s exited (%s); restarted it (restart %d)" % (
            restarts.node_name(who), how, restart.count), restart)


def _ordinal(n):
    return {1: "st", 2: "nd", 3: "rd"}.get(n if n < 20 else n % 10, "th")
