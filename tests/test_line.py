"""A class on one testbed (issue 23): a run that finds the testbed busy waits in line, first come
first served, saying its place and who holds the testbed; --no-wait refuses at once with exit 4
and one readable line. Real nodes (one LocalTestbed, as `./robotarium up`), real clients
(`./robotarium run` in subprocesses)."""
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from devtools.rosutil import REPO, node_env, unique_domain_id

# imported under another name: pytest would collect a module-level test_* function as a test
from robotarium_bringup.testbed import LocalTestbed
from robotarium_bringup.testbed import testbed_answers as answers_in_namespace
from robotarium_core.line import Line

DATA = os.path.join(REPO, "tests", "data")


def test_the_line_is_first_come_first_served_and_forgets_who_stops_asking():
    line = Line(lease=3.0)
    a = line.join("", "alice", now=0.0)
    b = line.join("", "bob", now=1.0)
    assert (line.place(a), line.place(b), line.first()) == (1, 2, a)
    assert line.join(a, "alice", now=2.0) == a and line.place(a) == 1   # asking again keeps the place
    line.prune(now=4.5)   # bob last asked at 1.0: gone; alice at 2.0: still there
    assert line.holders() == ["alice"] and line.place(b) == 0
    line.leave(a)
    assert line.first() is None


@pytest.fixture(scope="module")
def testbed(tmp_path_factory):
    domain = unique_domain_id()
    env = node_env(domain)
    saved = dict(os.environ)
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    tb = LocalTestbed(log_dir=str(tmp_path_factory.mktemp("logs")), record=False).start()
    try:
        assert answers_in_namespace(timeout=60), "the testbed did not come up: %s" % tb.failed()
    finally:
        os.environ.clear()
        os.environ.update(saved)
    try:
        yield env
    finally:
        tb.stop()


def start_run(env, tmp_path, *args):
    """./robotarium run in a subprocess; its output is read as it comes (process.lines), so a
    chatty script never blocks on a full pipe."""
    process = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed",
                                "--no-video", "--results-dir", str(tmp_path / "results"), *args], env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=str(tmp_path),
                               start_new_session=True)
    process.lines = []
    threading.Thread(target=lambda: process.lines.extend(iter(process.stdout.readline, "")), daemon=True).start()
    return process


def wait_for_line(process, words, timeout=60):
    """Wait until a line of the process's output holds `words`; returns its output so far."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if any(words in line for line in list(process.lines)):
            return "".join(process.lines)
        if process.poll() is not None and not any(words in line for line in list(process.lines)):
            time.sleep(0.5)   # the reader may still be taking the last lines
            if process.poll() is not None and not any(words in line for line in list(process.lines)):
                break
        time.sleep(0.05)
    raise AssertionError("no line with %r in:\n%s" % (words, "".join(process.lines)))


def output_when_done(process, timeout):
    process.wait(timeout=timeout)
    time.sleep(0.5)   # the reader takes the last lines
    return "".join(process.lines)


@pytest.mark.e2e   # whole runs through ./robotarium on one testbed
def test_a_second_student_waits_in_line_and_a_third_is_refused_with_no_wait(testbed, tmp_path):
    env = testbed
    dave = start_run(env, tmp_path, "--lockstep", os.path.join(DATA, "steps_forever.py"), "lockstep")
    erin = frank = None
    try:
        wait_for_line(dave, "step 5")
        assert dave.poll() is None, "".join(dave.lines)
        # --no-wait: exit 4, one readable line naming who holds the testbed, no traceback, nothing cut
        refused = subprocess.run([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed",
                                  "--no-video", "--no-wait", "--results-dir", str(tmp_path / "results"),
                                  os.path.join(DATA, "two_robots_to_goals.py")], env=env, capture_output=True,
                                 text=True, cwd=str(tmp_path), timeout=120)
        out = refused.stdout + refused.stderr
        assert refused.returncode == 4, out
        assert "Traceback" not in out and "fix it" not in out, out
        # one line, and no results folder for a run that never ran (issue 36)
        assert out.count("\n") == 1 and out.count("busy") == 1, out
        assert "is busy: " in out and "steps_forever.py: run steps_forever_" in out
        assert "Run again without --no-wait to wait in line for it (./robotarium status shows who holds it)." in out
        results = tmp_path / "results"   # (its scratch space, .unfinished, is no run folder)
        assert not results.exists() or not [n for n in os.listdir(results) if not n.startswith(".")], os.listdir(results)
        # two waiting students: first come, first served, each told its place and the holder
        erin = start_run(env, tmp_path, os.path.join(DATA, "two_robots_to_goals.py"))
        wait_for_line(erin, "waiting for the testbed: number 1 in line; it is held by ")
        assert dave.poll() is None, "".join(dave.lines)
        frank = start_run(env, tmp_path, os.path.join(DATA, "two_robots_to_goals.py"))
        said = wait_for_line(frank, "waiting for the testbed: number 2 in line")
        assert "steps_forever.py: run steps_forever_" in said, said
        status = subprocess.run([sys.executable, "-m", "robotarium_cli", "status"], env=env,
                                capture_output=True, text=True, timeout=60).stdout
        assert "held by " in status and "steps_forever.py" in status, status
        assert "waiting in line: 1. " in status and "2. " in status and "two_robots_to_goals.py" in status, status
        # dave ends (Ctrl-C): erin, then frank, run to completion
        os.killpg(dave.pid, signal.SIGINT)
        assert dave.wait(timeout=60) == 130
        erin_out, frank_out = output_when_done(erin, 180), output_when_done(frank, 180)
        assert erin.returncode == 0 and frank.returncode == 0, erin_out + frank_out
        for out in (erin_out, frank_out):   # each is told when its turn comes
            assert "your turn: the testbed is free, starting the experiment" in out, out
        started = [int(out.split("results/two_robots_to_goals_")[1][9:15]) for out in (erin_out, frank_out)]
        assert started[0] <= started[1], (erin_out, frank_out)   # erin came first
    finally:
        for process in (dave, erin, frank):
            if process is not None and process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()


@pytest.mark.e2e   # whole runs through ./robotarium on one testbed
def test_a_student_who_ends_their_run_from_another_shell_reads_who_ended_it_once(testbed, tmp_path):
    """./robotarium end from another shell of the same user on the same host (issue 36): the run's
    console and its report say it was ended by its user with ./robotarium end, once, and nothing of
    an operator or --force."""
    from robotarium_client.testbed_link import holder_of_this_process
    env = testbed
    me = holder_of_this_process().split()[0]
    run = start_run(env, tmp_path, "--lockstep", os.path.join(DATA, "steps_forever.py"), "lockstep")
    try:
        wait_for_line(run, "step 5")
        ended = subprocess.run([sys.executable, "-m", "robotarium_cli", "end"], env=env, capture_output=True,
                               text=True, timeout=60)
        assert ended.returncode == 0, ended.stdout + ended.stderr
        assert "ended by its user (%s) with ./robotarium end at step" % me in ended.stdout, ended.stdout
        out = output_when_done(run, 60)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert run.returncode == 4, out
    said = [line for line in out.splitlines() if "ended by" in line]
    assert len(said) == 1 and "ended by its user (%s) with ./robotarium end" % me in said[0], out
    assert "operator" not in out and "--force" not in out and "hint:" not in out, out
    folder = [line.split("results in ")[1].split(" (open")[0] for line in out.splitlines() if "results in " in line][0]
    with open(os.path.join(tmp_path, folder, "report.txt")) as f:
        report = f.read()
    first = report.splitlines()[0]
    assert "ended by its user (%s) with ./robotarium end" % me in first and "operator" not in first, first
    # This testbed records nothing: the report says what is known of the recording, not where it must be.
    assert "(the testbed's recorder did not say where it recorded this run" in report, report
    assert "recorded on the testbed's machine" not in report, report
