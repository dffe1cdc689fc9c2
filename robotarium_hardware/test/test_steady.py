"""steady.real_time_scheduling: every thread of the process, those made before and after, at SCHED_FIFO where
the process may; where it may not, nothing changed and said so.
Each case runs in a process of its own (the test's own must keep its scheduling)."""
import json
import os
import subprocess
import sys

import pytest

from robotarium_hardware.steady import REAL_TIME_PRIORITY

PROBE = r"""
import json, os, sys, threading
from robotarium_hardware.steady import real_time_scheduling

if sys.argv[1:] == ["nobody"]:   # (after the imports: that user may not read the interpreter's files)
    os.setgid(65534)
    os.setuid(65534)

def policy(tid):
    return os.sched_getscheduler(tid) & ~os.SCHED_RESET_ON_FORK

release = threading.Event()
before = threading.Thread(target=release.wait)
before.start()
said = real_time_scheduling()
seen = {}
after = threading.Thread(target=lambda: seen.update(after=policy(threading.get_native_id())))
after.start(); after.join()
threads = {tid: policy(int(tid)) for tid in os.listdir("/proc/self/task")}
release.set(); before.join()
print(json.dumps(dict(said=said, threads=threads, after=seen["after"],
                      priority=os.sched_getparam(0).sched_priority)))
"""


def probe(*args):
    completed = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, timeout=60)
    assert completed.returncode == 0, completed.stderr
    return json.loads(completed.stdout)


@pytest.mark.skipif(os.geteuid() != 0, reason="only root may give real-time priority here")
def test_every_thread_runs_at_real_time_priority():
    seen = probe()
    assert seen["said"] == "real-time scheduling (SCHED_FIFO %d)" % REAL_TIME_PRIORITY
    assert len(seen["threads"]) >= 2 and set(seen["threads"].values()) == {os.SCHED_FIFO}, seen
    assert seen["after"] == os.SCHED_FIFO and seen["priority"] == REAL_TIME_PRIORITY


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to become a user that may not")
def test_where_it_may_not_nothing_changes_and_it_says_so():
    seen = probe("nobody")
    assert seen["said"] == "ordinary scheduling (real-time priority not permitted)"
    assert set(seen["threads"].values()) == {os.SCHED_OTHER} and seen["after"] == os.SCHED_OTHER, seen
