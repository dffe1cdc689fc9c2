"""The script's process starts warm (issue 40): `./robotarium run` starts it (robotarium_cli.runner --gated) while it
still looks for the testbed, so its Python and imports overlap that look; it waits at its start gate and runs the
script only once the testbed answered; it joins DDS meanwhile, and the script's Robotarium takes that participant
and node. A run that never gets there (Ctrl-C while it waits for a testbed) stops
waiting at once, runs nothing and leaves no process behind.
Real processes: `./robotarium run` and `./robotarium up` on a domain of the test's own."""
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from devtools.rosutil import node_env, processes_on_domain, unique_domain_id
from robotarium_core import lifeline

# How long its process had lived when the script's first line ran (its start time in /proc, against the uptime).
AGE = """import os
ticks = int(open("/proc/self/stat").read().rsplit(")", 1)[1].split()[19])
print("AGE AT FIRST LINE %.2f" % (float(open("/proc/uptime").read().split()[0]) - ticks / os.sysconf("SC_CLK_TCK")),
      flush=True)
"""
# Whether its participant and node were made while it waited (testbed_link.join_dds_early). (What that participant
# already knows of the testbed by then depends on the machine's load: the benefit is measured by bench
# wall_to_prompt's constructor column, not asserted here.)
KNEW = """from robotarium_client import testbed_link
early = testbed_link._early[2] if testbed_link._early else None
print("JOINED DDS BEFORE THE FIRST LINE", early is not None, flush=True)
"""
RUN = AGE + KNEW + """import numpy as np
import rps.robotarium as robotarium
r = robotarium.Robotarium(number_of_robots=2, show_figure=False, sim_in_real_time=False)
print("THE CLIENT'S NODE IS THE ONE MADE EARLY", r._link.node is early, flush=True)
for _ in range(5):
    r.get_poses()
    r.set_velocities(np.arange(2), np.zeros((2, 2)))
    r.step()
r.call_at_scripts_end()
"""
MARKS = """open("ran.txt", "w").write("the script ran")
""" + RUN
LATE = 4.0   # s the testbed comes up after `run` started


def test_the_gate_hands_over_what_its_starter_gives_and_nothing_when_closed(monkeypatch):
    for message, opened in ((b'["a", "b"]', True), (b"", True), (b"", False)):
        gate = lifeline.StartGate()
        env, _ = gate.for_child({}, ())
        monkeypatch.setenv(lifeline.GATE_ENV, str(os.dup(int(env[lifeline.GATE_ENV]))))   # the child's end
        gate.close_read_end()
        if opened:
            gate.open(1, message)
        else:
            gate.close()   # the starter gave up (or died): no byte at all
        assert lifeline.read_start_gate() == (message if opened else None)
        assert lifeline.GATE_ENV not in os.environ   # taken: the script's own children never see it


def run(env, cwd, script):
    with open(os.path.join(cwd, "script.py"), "w") as f:
        f.write(script)
    return subprocess.Popen([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--no-video",
                             "--results-dir", os.path.join(cwd, "results"), "script.py"], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


@pytest.mark.e2e
def test_the_scripts_process_waits_warm_for_the_testbed_and_runs_the_script_only_once_it_answers(tmp_path):
    domain = unique_domain_id()
    env = node_env(domain)
    process = run(env, str(tmp_path), RUN)
    up = None
    try:
        time.sleep(LATE)   # `run` waits for a testbed to answer (--no-local-testbed); its script's process is up
        assert process.poll() is None
        up = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "up", "--no-record"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, start_new_session=True)
        out, _ = process.communicate(timeout=120)
        assert process.returncode == 0, out
        # its process was started before the testbed was there, and ran the script's first line only after `run`
        # found it: the script's own code never runs ahead of the testbed
        age = float(re.search(r"AGE AT FIRST LINE ([\d.]+)", out).group(1))
        assert age >= LATE - 1.0, out
        assert out.index("using the testbed that answers") < out.index("AGE AT FIRST LINE"), out
        # and it had joined DDS meanwhile, and the script's Robotarium took that participant and node
        assert "JOINED DDS BEFORE THE FIRST LINE True" in out, out
        assert "THE CLIENT'S NODE IS THE ONE MADE EARLY True" in out, out
    finally:
        for p in (process, up):
            if p is not None and p.poll() is None:
                os.killpg(p.pid, signal.SIGINT)
                p.wait(timeout=60)
    assert processes_on_domain(domain) == {}


@pytest.mark.e2e
def test_a_run_that_never_finds_its_testbed_runs_nothing_and_leaves_no_process(tmp_path):
    domain = unique_domain_id()
    env = node_env(domain)
    process = run(env, str(tmp_path), MARKS)
    try:
        time.sleep(3.0)   # waiting for a testbed that never comes, its script's process warm beside it
        os.killpg(process.pid, signal.SIGINT)
        out, _ = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, out   # Ctrl-C while it waited for a testbed: it stops waiting, as a shell says
    assert not (tmp_path / "ran.txt").exists(), out
    assert "AGE AT FIRST LINE" not in out, out
    deadline = time.monotonic() + 10
    while processes_on_domain(domain) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert processes_on_domain(domain) == {}
