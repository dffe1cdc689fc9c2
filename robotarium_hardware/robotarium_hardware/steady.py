"""Keeping a real-time node from pausing: the nodes that stop or are real robots (the arena, the tag tracker,
and the simulated fleet's robots and stand-ins) answer within tens of milliseconds.

Two things pause them. A full garbage collection walks every object the imports made (rclpy, numpy, OpenCV:
about 40 000, 10 ms here, several times that on a loaded machine): never, once set up. And the scheduler: on a
machine shared with the script, the safety node, the recorder and whatever else runs, a woken node waits its
turn behind them (at nice -10 still 19-56 ms for a camera frame to be tracked, 2026-11-30). Where the machine
is theirs (a lab's arena computer, a robot's own), ROBOTARIUM_REAL_TIME_PRIORITY=N puts them at SCHED_FIFO N;
on a machine shared with other work it would take their CPU first, so it is asked for, never the default
(docs/own-robots.md)."""
import gc
import os

# The variable that asks for real-time scheduling: a SCHED_FIFO priority, 1-99 (10 is low among real-time
# threads: the kernel's own run at 50); unset or 0, ordinary scheduling.
PRIORITY_VARIABLE = "ROBOTARIUM_REAL_TIME_PRIORITY"


def steady():
    """Once set up: what exists now is never collected (gc.freeze), so a collection walks only what the node
    makes while it runs; and every thread at real-time priority where ROBOTARIUM_REAL_TIME_PRIORITY asks for it.
    Returns the scheduling in words, for the node's ready line."""
    gc.collect()
    gc.freeze()
    priority = os.environ.get(PRIORITY_VARIABLE, "").strip()
    if priority in ("", "0"):
        return "ordinary scheduling"
    try:
        value = int(priority)
    except ValueError:
        value = -1
    if not 1 <= value <= 99:
        return "ordinary scheduling (%s=%r is no SCHED_FIFO priority: give 1-99)" % (PRIORITY_VARIABLE, priority)
    return real_time_scheduling(value)


def real_time_scheduling(priority):
    """Every thread of this process, Fast DDS's included (threads made later inherit it), to SCHED_FIFO at
    `priority`, where this process may (root, or CAP_SYS_NICE, or an RLIMIT_RTPRIO that allows it). Done after
    the set-up, so that a node's imports never hold a core from the others; the kernel's real-time throttling
    still leaves ordinary processes 5 % of each second. (No SCHED_RESET_ON_FORK: it resets threads made later
    too; these nodes start no processes.) Returns the scheduling in words."""
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return "ordinary scheduling (no /proc/self/task)"
    for tid in tasks:
        try:
            os.sched_setscheduler(int(tid), os.SCHED_FIFO, os.sched_param(priority))
        except ProcessLookupError:
            continue   # a thread that ended meanwhile
        except (PermissionError, AttributeError):
            return "ordinary scheduling (real-time priority %d not permitted)" % priority
    return "real-time scheduling (SCHED_FIFO %d)" % priority
