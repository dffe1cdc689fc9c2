"""A test process whose own DDS participant deadlocks (Fast DDS 2.14's eProsima/Fast-DDS#6502, seen in
a test's probe as it closed, 2026-11-30: the pytest worker, and the suite, waited for ever) goes on.

Real processes: a child process makes a probe (RosProbe, with a writer, whose destroy waits for the
participant's event thread), and this test stops that event thread for real (ptrace, as the deadlock
stops it: devtools.rosutil.FrozenThread). The probe's close must come back, say what it left, and the
child must exit with the status it meant (without Fast DDS's teardown, which would wait too).
"""
import subprocess
import sys
import time

import pytest

from devtools.rosutil import REPO, FrozenThread, node_env, unique_domain_id

pytestmark = pytest.mark.node   # a DDS participant in a process of its own

CHILD = """
import sys, time
from std_msgs.msg import String
from devtools.rosutil import RosProbe
from robotarium_core import dds_health
probe = RosProbe(int(sys.argv[1]), "stuck_probe")
probe.node.create_publisher(String, "stuck_probe_topic", 10)
print("READY", *dds_health.dds_event_threads(), flush=True)
sys.stdin.readline()
began = time.monotonic()
closed = probe.close()
print("CLOSED", closed, round(time.monotonic() - began, 1), flush=True)
dds_health.exit_status = 3
sys.exit(3)
"""


def test_a_probe_whose_fast_dds_deadlocked_is_left_and_its_process_goes_on_and_exits():
    domain = unique_domain_id()
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(domain)], env=node_env(domain), cwd=REPO,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    frozen = []
    try:
        ready = child.stdout.readline().split()
        assert ready[:1] == ["READY"] and len(ready) > 1, ready + [child.stderr.read() if child.poll() is not None else ""]
        frozen = [FrozenThread(int(tid)) for tid in ready[1:]]
        child.stdin.write("\n")
        child.stdin.flush()
        closed = child.stdout.readline().split()
        deadline = time.monotonic() + 30
        while child.poll() is None and time.monotonic() < deadline:
            for thread in frozen:
                thread.gone()   # a traced thread that ended waits for us: its process cannot end before
            time.sleep(0.05)
        code = child.poll()
        err = child.stderr.read() if code is not None else "(still running)"
        assert closed[:2] == ["CLOSED", "False"], (closed, err)
        assert "Fast DDS stopped in this process" in err and "the test's probe stuck_probe is left" in err, err
        assert code == 3, (code, err)   # the child's own status, not a hang nor a crash
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        for thread in frozen:
            thread.gone()


def test_a_probe_closes_as_before_when_nothing_is_stuck():
    code = ("import sys\nfrom devtools.rosutil import RosProbe\nprobe = RosProbe(int(sys.argv[1]), 'free_probe')\n"
            "print(probe.close())\n")
    domain = unique_domain_id()
    done = subprocess.run([sys.executable, "-c", code, str(domain)], env=node_env(domain), cwd=REPO,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.split() == ["True"], (done.stdout, done.stderr)
    assert "Fast DDS stopped" not in done.stderr
