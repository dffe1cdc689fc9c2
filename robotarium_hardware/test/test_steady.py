"""steady(): ROBOTARIUM_REAL_TIME_PRIORITY puts every thread of the process, those made before and after, at
SCHED_FIFO where the process may; where it may not, or without it, nothing changes and the node says so.
Each case runs in a process of its own (the test's own must keep its scheduling)."""
import json
import os
import subprocess
import sys

import pytest

from robotarium_hardware.steady import PRIORITY_VARIABLE

PROBE = r"""
import json, os, sys, threading
from robotarium_hardware.steady import steady

if sys.argv[1:] == ["nobody"]:   # (after the imports: that user may not read the interpreter's files)
    os.setgid(65534)
    os.setuid(65534)

def policy(tid):
    try:
        return os.sched_getscheduler(tid) & ~os.SCHED_RESET_ON_FORK
    except ProcessLookupError:   # a thread listed a moment ago that has ended since (`after`, joined, leaving)
        return None

release = threading.Event()
before = threading.Thread(target=release.wait, daemon=True)   # (daemon: a failure below never waits for it)
before.start()
said = steady()
seen = {}
after = threading.Thread(target=lambda: seen.update(after=policy(threading.get_native_id())))
after.start(); after.join()
threads = {tid: p for tid, p in ((tid, policy(int(tid))) for tid in os.listdir("/proc/self/task")) if p is not None}
release.set(); before.join()
print(json.dumps(dict(said=said, threads=threads, after=seen["after"],
                      priority=os.sched_getparam(0).sched_priority)))
"""


def probe(priority, *args):
    env = {k: v for k, v in os.environ.items() if k != PRIORITY_VARIABLE}
    if priority is not None:
        env[PRIORITY_VARIABLE] = priority
    completed = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, timeout=60,
                               env=env)
    assert completed.returncode == 0, completed.stderr
    return json.loads(completed.stdout)


@pytest.mark.skipif(os.geteuid() != 0, reason="only root may give real-time priority here")
def test_asked_for_every_thread_runs_at_real_time_priority():
    seen = probe("12")
    assert seen["said"] == "real-time scheduling (SCHED_FIFO 12)"
    assert len(seen["threads"]) >= 2 and set(seen["threads"].values()) == {os.SCHED_FIFO}, seen
    assert seen["after"] == os.SCHED_FIFO and seen["priority"] == 12


@pytest.mark.parametrize("priority, said", [(None, "ordinary scheduling"), ("0", "ordinary scheduling"),
                                            ("high", "ordinary scheduling (%s='high' is no SCHED_FIFO priority: "
                                                     "give 1-99)" % PRIORITY_VARIABLE)])
def test_not_asked_for_nothing_changes(priority, said):
    seen = probe(priority)
    assert seen["said"] == said
    assert set(seen["threads"].values()) == {os.SCHED_OTHER} and seen["after"] == os.SCHED_OTHER, seen


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to become a user that may not")
def test_where_it_may_not_nothing_changes_and_it_says_so():
    seen = probe("10", "nobody")
    assert seen["said"] == "ordinary scheduling (real-time priority 10 not permitted)"
    assert set(seen["threads"].values()) == {os.SCHED_OTHER} and seen["after"] == os.SCHED_OTHER, seen
