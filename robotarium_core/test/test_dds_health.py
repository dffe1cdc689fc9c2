"""dds_health.DdsStallWatch with real threads of this process named as Fast DDS names its event
threads: one blocked for good (as a deadlock blocks it) is told, one that runs is not, and a gap in
the checks themselves (the process stopped) counts for nothing."""
import ctypes
import threading
import time

import pytest

from robotarium_core import dds_health

_PR_SET_NAME = 15


def named_thread(name, target):
    """A daemon thread that names itself `name` (what /proc/self/task/TID/comm shows) and runs target."""
    started = threading.Event()

    def run():
        ctypes.CDLL(None).prctl(_PR_SET_NAME, name.encode(), 0, 0, 0)
        started.set()
        target()
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    started.wait(5)
    return thread


def test_an_event_thread_blocked_for_good_is_told_and_one_that_runs_is_not():
    release = threading.Event()
    named_thread("dds.ev.blocked", release.wait)     # a futex wait nothing ends: no context switch

    def lively():
        while not release.is_set():
            time.sleep(0.02)
    named_thread("dds.ev.lively", lively)
    try:
        watch = dds_health.DdsStallWatch(limit=0.6)
        told = []
        deadline = time.monotonic() + 5
        while not told and time.monotonic() < deadline:
            stuck = watch.check()
            if stuck and "dds.ev.blocked" in stuck:
                told.append(stuck)
            time.sleep(0.1)
        assert told, "a thread blocked for good was never told"
        assert "dds.ev.lively" not in told[0] and "has not run for" in told[0], told
    finally:
        release.set()


def test_a_gap_in_the_checks_counts_for_nothing():
    release = threading.Event()
    named_thread("dds.ev.gap", release.wait)
    try:
        watch = dds_health.DdsStallWatch(limit=0.6, gap=0.5)
        watch.check()
        time.sleep(1.0)   # the loop that checks did not run either (a stopped or starved process)
        first = watch.check()
        assert first is None or "dds.ev.gap" not in first, first
        time.sleep(0.3)
        second = watch.check()
        assert second is None or "dds.ev.gap" not in second, second   # 0.3 s of checks: not yet
    finally:
        release.set()


@pytest.mark.skipif(dds_health._FUTEX is None, reason="the futex syscall's number is known on x86_64 and aarch64 only")
def test_close_unless_stuck_leaves_a_close_that_would_wait_for_a_thread_blocked_for_good():
    """A thread waiting in a lock with no deadline (as Fast DDS's deadlocked event thread waits) is blocked
    for good; one waiting with a deadline (as an idle event thread always does) is not. close_unless_stuck
    does not call a close that would wait for the first (it says so and returns False), and calls it while
    only the second is there."""
    lock, release = threading.Lock(), threading.Event()
    lock.acquire()
    named_thread("dds.ev.timed", lambda: release.wait(30))   # a wait with a deadline
    closed, blocked, tids = [], None, {}
    try:
        assert dds_health.close_unless_stuck(lambda: closed.append(1), "a free close") is True and closed == [1]
        blocked = named_thread("dds.ev.locked", lock.acquire)   # a lock nothing releases: no deadline
        time.sleep(0.1)
        tids = {name: tid for tid, name in dds_health.dds_event_threads().items()}
        assert dds_health._blocked_for_good(tids["dds.ev.locked"]) is not None
        assert dds_health._blocked_for_good(tids["dds.ev.timed"]) is None
        abandoned, registered = list(dds_health.abandoned), []
        real_register = dds_health.atexit.register
        dds_health.atexit.register = registered.append   # (this test process must not exit without its teardown)
        try:
            assert dds_health.close_unless_stuck(lambda: closed.append(2), "a stuck close") is False
        finally:
            dds_health.atexit.register = real_register
        assert closed == [1] and dds_health.abandoned[len(abandoned):] == ["a stuck close"]
        assert registered or abandoned   # the exit without DDS's teardown is arranged once
    finally:
        release.set()
        lock.release()
        if blocked is not None:
            blocked.join(5)
        del dds_health.abandoned[:]
        dds_health._stuck_threads.discard(tids.get("dds.ev.locked"))
