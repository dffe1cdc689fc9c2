"""Keeping a real-time node from pausing: the nodes that stop or are real robots (the arena, the tag tracker,
and the simulated fleet's robots and stand-ins) answer within tens of milliseconds.

Two things paused them. A full garbage collection walks every object the imports made (rclpy, numpy, OpenCV:
about 40 000, 10 ms here, several times that on a loaded machine). And the scheduler: on a machine shared with
the script, the safety node, the recorder and whatever else runs, a woken node waited its turn behind them
(with nice -10 still 19-56 ms for a camera frame to be tracked, 2026-11-30), and those waits are most of what
the 0.2 s to stop every robot is made of (docs/own-robots.md)."""
import gc
import os

# SCHED_FIFO priority of these nodes: above every ordinary process (which the kernel's real-time throttling still
# leaves 5 % of the CPUs), low among real-time ones (the kernel's own threads run at 50).
REAL_TIME_PRIORITY = 10


def steady():
    """Once set up: what exists now is never collected (gc.freeze), so a collection walks only what the node
    makes while it runs; and every thread of the process runs at real-time priority where it may. Returns
    the scheduling in words, for the node's ready line."""
    gc.collect()
    gc.freeze()
    return real_time_scheduling()


def real_time_scheduling(priority=REAL_TIME_PRIORITY):
    """Every thread of this process, Fast DDS's included (threads made later inherit it), to SCHED_FIFO at
    `priority`, where this process may (root, or CAP_SYS_NICE, or an RLIMIT_RTPRIO that allows it). Done after
    the set-up, so that a node's imports never hold a core from the others. (No SCHED_RESET_ON_FORK: it resets
    threads made later too; these nodes start no processes.) Returns the scheduling in words."""
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
            return "ordinary scheduling (real-time priority not permitted)"
    return "real-time scheduling (SCHED_FIFO %d)" % priority
