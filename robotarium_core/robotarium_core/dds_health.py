"""Watchdogs for two Fast DDS 2.14 faults that leave a node alive but deaf to newcomers: a
shared-memory port Fast DDS deleted under its listener (SharedMemoryPortWatch, under a user's own
profile), and a participant deadlocked inside (DdsStallWatch, under ours). Each is read from /proc
and handed to node_main.run_node by the node (fast_dds_watchdogs()); a node that finds one starts
afresh in the same process. A process that is no node (the tests, with their probes) closes its DDS
entities with close_unless_stuck, which leaves a deadlocked participant where it is rather than wait
for it for ever. The faults, as seen and as tested: docs/faults.md.
"""
import atexit
import faulthandler
import os
import platform
import re
import sys
import time

from robotarium_core.dds_settings import profile_is_ours

# -- a shared-memory port Fast DDS took away ------------------------------------------------------
# A process that opens another's shared-memory port (to send to it, or while looking for a free
# one) first checks that its listeners answer; when they do not within healthy_check_timeout
# (1 s, which rmw_fastrtps does not let a profile change under ROS_AUTOMATIC_DISCOVERY_RANGE=
# LOCALHOST), Fast DDS deletes the port's file and makes a new one. A listener that was only slow
# (a machine stalled for a second, a busy 2-core CI box) keeps reading the deleted one: whoever
# joins later writes into the new file and is never heard ("no testbed answers" for a minute, then
# for every later run), while everyone it already knew still reaches it. The node cannot reopen its
# port inside rmw, so it starts afresh once it holds no run (node_main.restart_in_place). Our profile
# keeps the testbed off shared memory altogether; this is for a user's own profile (fast_dds_watchdogs).

PORT_CHECK_PERIOD = 1.0   # s between looks at this process's shared-memory ports
_PORT_LOCK = re.compile(r"^/dev/shm/fastrtps_port(\d+)_el(?: \(deleted\))?$")   # held while listening
_PORT_MAP = re.compile(r"/dev/shm/fastrtps_port(\d+) \(deleted\)$")


def shared_memory_ports(pid="self"):
    """(listening, lost): the Fast DDS shared-memory ports process `pid` listens on, and those of
    them whose file was deleted under it (no process that opens the port from now on reaches it);
    read from /proc, so (set(), set()) where there is none."""
    listening = set()
    try:
        for fd in os.listdir("/proc/%s/fd" % pid):
            try:
                found = _PORT_LOCK.match(os.readlink("/proc/%s/fd/%s" % (pid, fd)))
            except OSError:
                continue   # closed meanwhile
            if found:
                listening.add(int(found.group(1)))
        if not listening:
            return set(), set()
        with open("/proc/%s/maps" % pid) as maps:
            deleted = {int(found.group(1)) for found in map(_PORT_MAP.search, maps.read().splitlines()) if found}
    except OSError:
        return set(), set()
    return listening, listening & deleted


class SharedMemoryPortWatch:
    """A watchdog (node_main.run_node): looks at this process's shared-memory ports every
    PORT_CHECK_PERIOD; one that Fast DDS took away is said once, and the node asks to restart as soon
    as it is at rest (node.at_rest(): no run to lose; a node without at_rest only says so)."""

    period = PORT_CHECK_PERIOD

    def __init__(self):
        self.noticed = False

    def __call__(self, node, stop):
        lost = sorted(shared_memory_ports()[1])
        if not lost:
            return
        at_rest = getattr(node, "at_rest", None)
        if not self.noticed:
            node.get_logger().error(
                "Fast DDS deleted this node's shared-memory port %s (another process found it unresponsive "
                "for over a second, as when the machine stalls): processes that start from now on cannot "
                "reach this node; %s" % (", ".join(map(str, lost)), "it restarts as soon as it holds no run"
                                         if at_rest is not None else "restart it"))
        self.noticed = True
        if at_rest is not None and at_rest():
            stop.request("restarting: its shared-memory port %s was deleted" % ", ".join(map(str, lost)), restart=True)


# -- a Fast DDS participant deadlocked inside --------------------------------------------------------
# Fast DDS 2.14 can deadlock a participant for good (gdb on a stuck simulator, 2026-11-28, load 6 on
# 2 cores; eProsima/Fast-DDS#6502 is the same cycle): a receive thread that removes a remote
# endpoint (a client leaving) holds the discovery (PDP) mutex while it waits, in
# ResourceEvent::unregister_timer, for the event thread to finish its timers, and the event thread's
# timer (WLP::automatic_liveliness_assertion: our presence writers' liveliness) waits for that mutex.
# The node's Python goes on, DDS does not: no announcements, no liveliness, no discovery; the other
# receive threads queue on the same mutex. Processes that start later never find the node, and its
# peers lose it once its lease ends ("no safety node answers", run after run). The event thread
# wakes several times a second (our profile's announcements every 0.2 s, presence liveliness every
# 0.17-0.25 s), so one that has not run for DDS_STALL_LIMIT while the node's own loop has is stuck:
# the node says so and starts afresh (node_main.restart_in_place) without touching DDS, which would
# wait for ever. Under a user's own profile (announcements maybe rarer) it is not watched (fast_dds_watchdogs).

DDS_STALL_LIMIT = 5.0   # s an event thread may go without running before its participant counts as stuck
DDS_STALL_CHECK = 0.5   # s between looks


def _task_file(tid, name, pid="self"):
    try:
        with open("/proc/%s/task/%d/%s" % (pid, tid, name)) as f:
            return f.read()
    except OSError:
        return None   # the thread ended


def dds_event_threads(pid="self"):
    """{thread id: name} of process `pid`'s Fast DDS event threads ("dds.ev.N", one per participant)."""
    threads = {}
    for entry in os.listdir("/proc/%s/task" % pid):
        comm = _task_file(int(entry), "comm", pid)
        if comm is not None and comm.startswith("dds.ev."):
            threads[int(entry)] = comm.strip()
    return threads


def context_switches(tid):
    """How often thread `tid` of this process gave up or lost the processor (it changes each time the
    thread runs), or None when it ended."""
    status = _task_file(tid, "status")
    if status is None:
        return None
    return sum(int(line.split()[1]) for line in status.splitlines() if "ctxt_switches:" in line)


class DdsStallWatch:
    """Tells when a Fast DDS event thread of this process has stopped running: check() (every
    DDS_STALL_CHECK or so) returns what is stuck, or None. A gap in the checks themselves (the whole
    process stopped or starved) starts the count again. As a watchdog (node_main.run_node) it makes
    the node start afresh at once when a thread is stuck."""

    period = DDS_STALL_CHECK

    def __init__(self, limit=DDS_STALL_LIMIT, gap=4 * DDS_STALL_CHECK):
        self.limit = limit
        self.gap = gap    # s between two checks that makes a gap
        self.seen = {}    # thread id -> (context switches, since when unchanged)
        self.last = None  # time of the previous check

    def check(self, now=None):
        now = time.monotonic() if now is None else now
        if self.last is not None and now - self.last > self.gap:
            self.seen.clear()   # this loop did not run either: nothing can be said of the gap
        self.last = now
        stuck = []
        for tid, name in dds_event_threads().items():
            switches = context_switches(tid)
            if switches is None:
                continue
            switched, since = self.seen.get(tid, (None, now))
            if switches != switched:
                self.seen[tid] = (switches, now)
            elif now - since >= self.limit:
                stuck.append("%s (thread %d) has not run for %.1f s" % (name, tid, now - since))
        return "; ".join(stuck) or None

    def __call__(self, node, stop):
        stuck = self.check()
        if stuck is not None:
            # At once and without touching DDS: winding down would wait for the stuck threads.
            stop.restart_now("Fast DDS stopped in this process: %s (a deadlock inside Fast DDS, docs/faults.md); "
                             "starting afresh in the same process; a run it held is lost" % stuck,
                             cause="its Fast DDS stopped: %s" % stuck)


def fast_dds_watchdogs():
    """The watchdogs of a testbed node (run_node's `watchdogs`) under the Fast DDS profile in force.
    Only a user's own profile brings the shared-memory transport back (ours has no port to lose);
    ours has the event thread announce every 0.2 s, and only then is 5 s without it running a stall."""
    return [DdsStallWatch()] if profile_is_ours() else [SharedMemoryPortWatch()]


# -- closing where Fast DDS may be deadlocked -------------------------------------------------------
# Destroying a node, a publisher or a context waits for the participant's event thread (every timer
# is unregistered there), inside rclpy's C++ and holding the GIL. When that thread is caught in Fast DDS
# 2.14's own deadlock (a receive thread removing a leaving participant's writer holds the discovery
# mutex and waits for the event thread, which waits for that mutex: eProsima/Fast-DDS#6502), the destroy
# waits for ever, and nothing else of the process's Python runs: a test whose probe closed just after a
# testbed stopped hung its pytest worker, and with it the whole suite (2026-11-30). A node starts afresh
# (node_main); a process that is no node looks first, and leaves a stuck participant where it is.

SETTLED_AT_LEAST = 0.1   # s an event thread must stay blocked, unmoved, to count as stuck
CLOSE_LIMIT = 120.0      # s a close that got stuck after the look may take before the process ends itself
# the futex syscall's number, as /proc/<pid>/task/<tid>/syscall shows it (elsewhere only a stopped thread is seen)
_FUTEX = {"x86_64": "202", "aarch64": "98"}.get(platform.machine())

abandoned = []      # what close_unless_stuck left stuck: this process leaves without DDS's teardown
exit_status = 1     # what it then exits with (os._exit skips sys.exit's); the tests' conftest sets pytest's
_stuck_threads = set()


def _blocked_for_good(tid):
    """(how, context switches) where this process's thread `tid` cannot run by itself: waiting in a futex
    with no deadline (a lock, or a condition with no timeout: an idle event thread always has one), or
    stopped (a debugger, ptrace); None where it runs or waits with a deadline."""
    state = _task_file(tid, "stat")
    syscall = (_task_file(tid, "syscall") or "").split()
    if state is None:
        return None
    stopped = state.rsplit(")", 1)[-1].split()[:1] in (["t"], ["T"])
    if not stopped and not (syscall[:1] == [_FUTEX] and len(syscall) > 4 and int(syscall[4], 16) == 0):
        return None
    return ("stopped" if stopped else "futex %s" % syscall[1]), context_switches(tid)


def close_unless_stuck(close, what, settle=None):
    """settle() (e.g. a wait for quiet discovery), then close() (it destroys DDS entities: nodes, a
    context), unless a Fast DDS event thread of this process stayed blocked for good all the while
    (_blocked_for_good, unmoved: a deadlock inside Fast DDS), for which close() would wait for ever:
    then close() is not called, a line on stderr names `what`, and the process will exit without
    tearing DDS down (which would wait for the same thread). A deadlock that begins during close()
    itself ends the process after CLOSE_LIMIT, its threads' tracebacks on stderr (faulthandler), rather
    than hang it. Returns True when closed, False when left."""
    began = time.monotonic()
    before = {tid: _blocked_for_good(tid) for tid in dds_event_threads()}
    if settle is not None:
        settle()
    time.sleep(max(0.0, SETTLED_AT_LEAST - (time.monotonic() - began)))
    stuck = [(tid, name) for tid, name in dds_event_threads().items()
             if tid not in _stuck_threads and before.get(tid) is not None and _blocked_for_good(tid) == before[tid]]
    if stuck:
        _stuck_threads.update(tid for tid, _ in stuck)
        if not abandoned:
            atexit.register(_exit_without_dds_teardown)
        abandoned.append(what)
        print("[robotarium] Fast DDS stopped in this process (%s blocked for good: a deadlock inside Fast DDS, "
              "docs/faults.md): %s is left as it is, and the process will exit without tearing DDS down" % (
                  ", ".join("%s (thread %d)" % (name, tid) for tid, name in stuck), what), file=sys.stderr, flush=True)
        return False
    try:   # (a file descriptor it can write to: a test's capsys gives stderr none)
        faulthandler.dump_traceback_later(CLOSE_LIMIT, exit=True, file=sys.__stderr__)
        armed = True
    except (AttributeError, ValueError, OSError):
        armed = False
    try:
        close()
    finally:
        if armed:
            faulthandler.cancel_dump_traceback_later()
    return True


def _exit_without_dds_teardown():
    """At exit (atexit runs before Python tears objects down and before the C++ destructors): leave
    at once, as a participant that is stuck would hold either for ever."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(exit_status)
