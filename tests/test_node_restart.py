"""A testbed node restarted mid-run (issue 41, item 2), with real processes: one `./robotarium up` on a domain of
its own; a run (`./robotarium run --no-local-testbed`, tests/data/turns_and_saves.py in lockstep) whose recorder,
safety node or simulator gets SIGKILL at a step of its run. `up` restarts the node (its supervisor,
robotarium_bringup.supervisor) and stays up; the run says the true cause (run.json, report.txt's first line, the exit
code): the recorder's run goes on with its recording stopped at the restart, the others end as "testbed node
restarted at step k"; the next run on the same `up` completes. The supervisor's bound (a node that keeps dying
stops `up`, naming it) and the restart record are tested in plain Python, and the bound once more with a run in
progress on an `up` of its own (the run names the node that kept exiting).
"""
import contextlib
import dataclasses
import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from devtools import soak
from devtools.rosutil import node_env, processes_on_domain, unique_domain_id
from robotarium_bringup import supervisor
from robotarium_core import outcomes, restarts

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "turns_and_saves.py")
STEPS = 3000    # lockstep: 10-20 s on the 2-core machine, long enough to be hit mid-run
KILL_AT = 600   # the step of the run at which the node is killed (its recorder has written chunks by then)


# -- plain Python ------------------------------------------------------------------------------------

def test_the_supervisor_restarts_a_node_a_bounded_number_of_times_then_gives_up_naming_it():
    now = [1000.0]
    watcher = supervisor.Supervisor(limit=2, window=60.0, clock=lambda: now[0])
    first = watcher.exited("recorder", -signal.SIGKILL, pid=42)
    assert first.line == "the recorder exited (killed by SIGKILL); restarted it (restart 1)"
    assert first.restart == restarts.Restart("recorder", "exited (killed by SIGKILL)", restarts.BY_UP, 1, 1000.0, 42)
    now[0] += 10
    assert watcher.exited("recorder", 1).restart.count == 2
    now[0] += 10
    given_up = watcher.exited("recorder", -signal.SIGSEGV, pid=44)
    assert given_up.restart is None
    assert given_up.line.startswith("the recorder keeps exiting: killed by SIGSEGV, its 3rd exit within 60 s"), \
        given_up.line
    # what a run in progress hears of it (it names that, not whichever node it missed first: up stops them all)
    told = given_up.announcement
    assert told.gave_up and told.old_pid == 44 and restarts.parse(told.to_json()) == told
    assert restarts.ended_run(told, 12) == (
        "the testbed stopped at step 12: the recorder kept exiting (killed by SIGSEGV, its 3rd exit within 60 s) and "
        "./robotarium up stopped the testbed; the experiment cannot go on")
    assert first.announcement == first.restart
    # another node has its own count; exits older than the window are forgotten
    assert watcher.exited("safety", 0).line == "the safety node exited (exited with code 0); restarted it (restart 1)"
    now[0] += 100
    assert watcher.exited("recorder", -signal.SIGKILL).restart.count == 3


def test_a_restart_record_reads_back_and_says_what_a_run_makes_of_it():
    up = restarts.Restart("safety", "exited (killed by SIGKILL)", restarts.BY_UP, 1, 2000.0, 7)
    assert restarts.parse(up.to_json()) == up
    assert restarts.parse("{") is None and restarts.parse('{"who": 1}') is None
    assert restarts.ended_run(up, 31).startswith(
        "testbed node restarted at step 31: the safety node exited (killed by SIGKILL) and ./robotarium up restarted "
        "it (restart 1)")
    assert up.during(2000.5) and not up.during(2005.0) and not up.during(None)
    # a run begun on the process up started in place of pid 7 was never served by pid 7, however close in time
    assert up.during(2000.5, pid_at_start=7) and not up.during(2000.5, pid_at_start=8)
    stall = restarts.in_place("simulator", "its Fast DDS stopped: dds.ev.0 has not run for 5.0 s", previous=up)
    assert stall.count == 2 and stall.by == restarts.IN_PLACE
    assert stall.describe().startswith("the simulator stopped answering (its Fast DDS stopped")
    # announced once back: a run in progress when it stalled ends; one begun once it was back does not, however
    # close (its latched announcement may come after the run's start)
    announced = stall.back()
    assert announced.back_at >= stall.at and restarts.parse(announced.to_json()) == announced
    back = dataclasses.replace(announced, at=3000.0, back_at=3000.6)
    assert back.during(2990.0) and not back.during(3000.2) and not back.during(3001.0)
    recorder = restarts.Restart("recorder", "exited (killed by SIGKILL)", restarts.BY_UP, 1, 0.0)
    because = restarts.recording_stopped(recorder)
    assert outcomes.recorder_lost(because) and outcomes.recorder_lost(outcomes.RECORDER_GONE)
    assert not outcomes.recorder_lost("disk full")


# -- real processes ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def testbed(tmp_path_factory):
    with own_up(tmp_path_factory) as testbed:
        yield testbed


@contextlib.contextmanager
def own_up(tmp_path_factory):
    """`./robotarium up` in /robotarium on a domain of its own, and a status watch, until the block is done."""
    domain = unique_domain_id()
    root = tmp_path_factory.mktemp("node_restart")
    bags = root / "bags"
    bags.mkdir()
    env = node_env(domain, ROBOTARIUM_NAMESPACE=soak.NAMESPACE, ROBOTARIUM_ROOT=str(root), ROBOTARIUM_PROGRESS="0")
    up = soak.Up(str(root), env)
    watch = None
    try:
        up.start()
        watch = soak.StatusWatch(domain)
        yield {"domain": domain, "root": root, "bags": bags, "env": env, "up": up, "watch": watch}
    finally:
        if watch is not None:
            watch.close()
        up.stop()
        for pid in processes_on_domain(domain):   # only after a failure: never leave them running
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def run(testbed, cwd, kill=None, steps=STEPS, kill_at=KILL_AT, resumed=None, mode="--lockstep"):
    """./robotarium run turns_and_saves.py on the module's testbed, SIGKILL to node `kill` at step `kill_at` of its
    run; (exit code, output, run.json, report.txt's first line, seconds from the kill to the run's exit). `resumed`
    (a list): gets the seconds from the kill to the first new step after the longest pause of the run's steps."""
    command = [sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--no-video", mode,
               "--bags-dir", str(testbed["bags"]), "--results-dir", str(testbed["root"] / "results"), SCRIPT,
               str(steps), "2"]
    began, killed_at = time.monotonic(), None
    process = subprocess.Popen(command, env=testbed["env"], cwd=str(cwd), stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        while kill and killed_at is None and process.poll() is None and time.monotonic() < began + 120:
            run_id, _ = testbed["watch"].started_since(began)
            status = testbed["watch"].get(run_id) if run_id else None
            if status and status["step"] >= kill_at:
                if kill == "script":   # the script's process frozen (SIGSTOP), never continued
                    runner = [p for p in soak.proc_children(process.pid) if "robotarium_cli.runner" in soak.cmdline(p)]
                    os.kill(runner[0], signal.SIGSTOP)
                else:
                    os.kill(testbed["up"].nodes()[kill], signal.SIGKILL)
                killed_at, killed_step = time.monotonic(), status["step"]
            time.sleep(0.01)
        changes = [(killed_at, killed_step)] if killed_at else []   # (when, step) each time the step moved
        while resumed is not None and changes and process.poll() is None and time.monotonic() < killed_at + 120:
            status = testbed["watch"].get(run_id)
            if status and status["step"] != changes[-1][1]:
                changes.append((time.monotonic(), status["step"]))
            time.sleep(0.01)
        if resumed is not None and len(changes) > 1:
            resumed.append(max(zip(changes, changes[1:]), key=lambda pair: pair[1][0] - pair[0][0])[1][0] - killed_at)
        out, _ = process.communicate(timeout=180)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    ended = time.monotonic()
    folder = re.findall(r"results in (\S+) \(open", out)
    folder = os.path.join(str(cwd), folder[-1]) if folder else None
    assert folder, out
    with open(os.path.join(folder, "run.json")) as f:
        info = json.load(f)
    with open(os.path.join(folder, "report.txt")) as f:
        first = f.readline().strip()
    assert os.path.isfile(os.path.join(folder, "index.html")), out   # the results were made
    return process.returncode, out, info, first, (ended - killed_at) if killed_at else None


def back_up(testbed, node, restart):
    """up says it restarted `node` and the node is ready again (its log's " ready" line); up still runs."""
    deadline = time.monotonic() + 60
    log = ""
    while time.monotonic() < deadline:
        log = testbed["up"].log()
        if restart in log and log[log.index(restart):].count(" ready") >= 1:
            break
        time.sleep(0.1)
    assert restart in log and testbed["up"].process.poll() is None, log[-3000:]
    assert testbed["up"].healthy(), log[-3000:]


@pytest.mark.e2e   # whole runs through ./robotarium on an `up` testbed
def test_a_killed_recorder_is_restarted_and_its_run_goes_on_its_recording_stopped(testbed, tmp_path):
    code, out, info, first, took = run(testbed, tmp_path, kill="recorder")
    k = info["recording_stopped_at_step"]
    print("recorder killed: the run exited %.1f s after the kill, code %d\n  run.json: %s / recording stopped at %s: "
          "%s\n  report.txt: %s" % (took, code, info["outcome"], k, info["recording_stopped_because"], first))
    assert info["outcome"] == "completed" and info["exit_code"] == code == 4, out
    assert info["recording_stopped_because"] == ("the recorder was restarted: the recorder exited (killed by SIGKILL) "
                                                 "and ./robotarium up restarted it (restart 1)"), info
    assert 0 < k < STEPS and info["steps"] == STEPS, info
    assert first.startswith("Run completed. Recording stopped at step %d: the recorder was restarted" % k), out
    back_up(testbed, "recorder", "the recorder exited (killed by SIGKILL); restarted it (restart 1)")
    code, out, info, first, _ = run(testbed, tmp_path, steps=30)   # the next run, recorded whole by the new one
    assert code == 0 and info["outcome"] == "completed" and not info.get("recording_stopped_because"), out
    assert info["recording"].startswith(str(testbed["bags"])), info


@pytest.mark.e2e   # whole runs through ./robotarium on an `up` testbed
def test_a_killed_safety_node_is_restarted_armed_again_and_its_run_goes_on_step_for_step(testbed, tmp_path):
    """The run survives its safety node's restart: `up` restarts the killed node, the simulator arms the new
    process with the run's keys and where the robots are, the client sends again the array the old one lost, and
    the lockstep run completes all its steps, recorded whole in one bag, its report naming the restart."""
    from robotarium_recording.bag import Bag
    resumed = []
    code, out, info, first, took = run(testbed, tmp_path, kill="safety", resumed=resumed)
    assert code == info["exit_code"] == 0 and info["outcome"] == "completed", out
    assert info["steps"] == STEPS, info
    (went_on,) = info["safety_restarts"]
    k = int(re.search(r"at step (\d+);", went_on).group(1))
    assert went_on.startswith("the safety node exited (killed by SIGKILL) and ./robotarium up restarted it (restart 1) "
                              "at step %d; the testbed armed it again at step %d and the run went on" % (k, k)), went_on
    assert KILL_AT <= k < STEPS, went_on
    assert first == "Run completed.", first
    assert "the robots stopped; the experiment goes on once the testbed has armed the new safety node" in out, out
    assert "the testbed armed the restarted safety node again at step %d: the experiment goes on" % k in out, out
    with open(os.path.join(str(tmp_path), re.findall(r"results in (\S+) \(open", out)[-1], "report.txt")) as f:
        assert went_on + " (the robots stood still meanwhile; in lockstep the run waited" in f.read()
    bag = Bag(info["recording"])
    counts = {topic.rsplit("/", 1)[-1]: t.count for topic, t in bag.topics.items()}
    steps = sorted(m.step for _, m in bag.decoded([t for t in bag.topics if t.endswith("/poses")]))
    assert steps == list(range(STEPS + 1)), "poses of steps %s missing" % sorted(set(range(STEPS + 1)) - set(steps))
    # One safe array a step, the one the old process lost sent again by the client; the old process's last arrays,
    # applied by the simulator, may be missing: a writer killed before every reader acknowledged its samples takes
    # them along (whole-suite runs: the recorder missed the last one, once the last three). Only those: a run of
    # steps that ends where the restart came.
    safe = {m.step for _, m in bag.decoded([t for t in bag.topics if t.endswith("/cmd_safe")])}
    missing = sorted(set(range(1, STEPS + 1)) - safe)
    assert not missing or (missing == list(range(missing[0], missing[-1] + 1)) and abs(missing[-1] - k) <= 1), \
        (k, missing)
    assert counts["cmd_safe"] == STEPS - len(missing), counts
    print("safety node killed at step %d: the run went on %.1f s after the kill and completed %d steps (%.1f s from "
          "the kill to its exit; steps whose cmd_safe the bag lacks: %s)\n  %s" % (
              k, resumed[0], info["steps"], took, missing, went_on))
    back_up(testbed, "safety", "the safety node exited (killed by SIGKILL); restarted it")


@pytest.mark.e2e   # whole runs through ./robotarium on an `up` testbed
def test_a_real_time_run_goes_on_across_its_safety_nodes_restart_its_robots_still_meanwhile(testbed, tmp_path):
    """In real time the testbed ticks on while the new safety node comes up: the robots stand still (no safe
    commands come; the simulator stopped them when the node's presence lapsed), then move again on the script's
    commands once the simulator armed the new node; the run completes all its steps and says so."""
    code, out, info, first, took = run(testbed, tmp_path, kill="safety", steps=240, kill_at=60, mode="--real-time")
    assert code == info["exit_code"] == 0 and info["outcome"] == "completed" and not info["audit"], out
    assert info["steps"] >= 240 and info["real_time"], info   # (the testbed ticks on while a step waits)
    (went_on,) = info["safety_restarts"]
    assert re.match(r"the safety node exited \(killed by SIGKILL\) and \./robotarium up restarted it \(restart \d+\) at "
                    r"step \d+; the testbed armed it again at step \d+ and the run went on$", went_on), went_on
    k, armed_at = (int(n) for n in re.findall(r"step (\d+)", went_on))
    assert 60 <= k < armed_at < info["steps"], went_on
    dropped = {name: {reason: n for reason, n in counts.items() if n} for name, counts in info["dropped"].items()}
    assert not dropped["cmd_requested"], dropped   # (the new node's drops before its arming are not the run's)
    print("safety node killed in real time: the robots stood still for %d steps (%.1f s); arrays dropped: %s; %s"
          % (armed_at - k, (armed_at - k) / 30.0, dropped, went_on))
    back_up(testbed, "safety", "the safety node exited (killed by SIGKILL); restarted it")


@pytest.mark.e2e   # whole runs through ./robotarium on an `up` testbed
def test_a_killed_simulator_is_restarted_and_its_run_ends_naming_the_restart(testbed, tmp_path):
    code, out, info, first, took = run(testbed, tmp_path, kill="simulator")
    words = "testbed node restarted at step"
    assert info["outcome"] == "testbed_lost" and code == info["exit_code"] == 4, out
    assert info["detail"].startswith(words) and "the simulator exited (killed by SIGKILL) and ./robotarium up " \
        "restarted it" in info["detail"], info
    assert first.startswith("Run did not complete: " + words), first
    assert "SIGINT" not in first and soak.NODE_WORDS["safety"] not in first, first
    assert soak.NODE_WORDS["simulator"] not in first and "the safety node" not in first, first
    print("simulator killed: the run exited %.1f s after the kill\n  run.json: %s / %s\n  report.txt: %s"
          % (took, info["outcome"], info["detail"], first))
    back_up(testbed, "simulator", "the simulator exited (killed by SIGKILL); restarted it")
    code, out, info, first, _ = run(testbed, tmp_path, steps=30)   # the next run on the same up
    assert code == 0 and info["outcome"] == "completed", out


@pytest.mark.e2e   # whole runs through ./robotarium on an `up` testbed
def test_a_script_whose_process_stops_is_ended_by_the_testbed_and_run_does_not_wait_for_it_for_ever(testbed, tmp_path):
    """Item 2's last sentence: a script's process that stops answering (SIGSTOP here: DDS and Python both stand
    still) loses its run to the testbed's client lease, and ./robotarium run, which waited for its exit for ever,
    kills it once it stayed stopped FROZEN_LIMIT s and makes the run's folder with that cause."""
    from robotarium_cli.running import FROZEN_LIMIT
    code, out, info, first, took = run(testbed, tmp_path, kill="script")
    assert code == info["exit_code"] == 128 + signal.SIGKILL and info["outcome"] == "interrupted", out
    assert "stayed stopped (SIGSTOP)" in info["detail"], info
    assert first.startswith("Run did not complete: the testbed ended it at step") and "its client was gone" in first, \
        first
    assert FROZEN_LIMIT <= took < FROZEN_LIMIT + 30, took
    print("script stopped: run exited %.1f s after the SIGSTOP\n  run.json: %s / %s\n  report.txt: %s"
          % (took, info["outcome"], info["detail"], first))
    code, out, info, first, _ = run(testbed, tmp_path, steps=30)   # the next run
    assert code == 0 and info["outcome"] == "completed", out


@pytest.mark.e2e   # whole runs through ./robotarium on an `up` testbed of its own (it stops for good)
def test_a_node_that_keeps_exiting_stops_up_and_the_run_names_it(tmp_path_factory, tmp_path):
    """The supervisor's bound with a run in progress: the simulator killed a fourth time within RESTART_WINDOW is not
    restarted and `up` stops the testbed. The run says so; before, it said "the safety node is gone", the node it
    happened to miss first (up stops every node), which did nothing wrong (a soak of repeated kills)."""
    with own_up(tmp_path_factory) as testbed:
        # Each new process killed as soon as it is there, and the run's early: all four exits well within the
        # window, however slowly a loaded machine starts the node.
        killed = set()
        for _ in range(supervisor.RESTART_LIMIT):
            deadline = time.monotonic() + 60
            while testbed["up"].nodes().get("simulator") in killed | {None}:
                assert time.monotonic() < deadline, testbed["up"].log()[-3000:]
                time.sleep(0.05)
            pid = testbed["up"].nodes()["simulator"]
            os.kill(pid, signal.SIGKILL)
            killed.add(pid)
        back_up(testbed, "simulator", "the simulator exited (killed by SIGKILL); restarted it (restart %d)"
                % supervisor.RESTART_LIMIT)
        code, out, info, first, took = run(testbed, tmp_path, kill="simulator", kill_at=20)
        print("the simulator killed a 4th time: the run exited %.1f s after the kill\n  run.json: %s / %s\n  "
              "report.txt: %s" % (took, info["outcome"], info["detail"], first))
        assert info["outcome"] == "testbed_lost" and code == info["exit_code"] == 4, out
        words = ("the simulator kept exiting (killed by SIGKILL, its 4th exit within %.0f s) and ./robotarium up "
                 "stopped the testbed" % supervisor.RESTART_WINDOW)
        assert info["detail"].startswith("the testbed stopped at step") and words in info["detail"], info
        assert first.startswith("Run did not complete: the testbed stopped at step"), first
        assert soak.NODE_WORDS["safety"] not in first, first
        testbed["up"].process.wait(timeout=60)
        assert "the simulator keeps exiting" in testbed["up"].log()
