"""Faults of a whole testbed, through ./robotarium with real processes (issue 22): a second testbed
in a namespace that has one, a full disk under the recorder, a script's data files over the run
folder's cap.

One `./robotarium up` on a domain and namespace of its own serves the module; each test runs real
scripts on it with `./robotarium run --no-local-testbed` (tests/data/turns_and_saves.py: robots
turning on the spot, far apart, so a completed run would say "Acceptance likely").
"""
import glob
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time

import pytest
import yaml

from devtools.rosutil import NodeProcess, node_env, processes_on_domain, unique_domain_id
from robotarium_core import outcomes
from robotarium_core.config import DEFAULT_FILE

pytestmark = pytest.mark.e2e   # whole runs through ./robotarium

NAMESPACE = "/faults"
SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "turns_and_saves.py")
ACCEPTANCE = "Acceptance of your experiment is likely"


def cli(*args, env, cwd, timeout=180):
    return subprocess.run([sys.executable, "-m", "robotarium_cli", *args], env=env, cwd=cwd, timeout=timeout,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


@pytest.fixture(scope="module")
def testbed(tmp_path_factory):
    """`./robotarium up` in NAMESPACE on a domain of its own, until the module is done."""
    domain = unique_domain_id()
    root = tmp_path_factory.mktemp("testbed_faults")
    bags = root / "bags"
    bags.mkdir()
    env = node_env(domain, ROBOTARIUM_NAMESPACE=NAMESPACE, ROBOTARIUM_ROOT=str(root), ROBOTARIUM_PROGRESS="0")
    log = open(root / "up.log", "wb")
    up = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "up", "--bags-dir", str(bags)], env=env,
                          cwd=str(root), stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 120   # its three nodes say they are ready
        while (up.poll() is None and time.monotonic() < deadline
               and (root / "up.log").read_text(errors="replace").count(" ready") < 3):
            time.sleep(0.1)
        yield {"domain": domain, "root": root, "bags": bags, "env": env, "up": up, "log": root / "up.log"}
    finally:
        if up.poll() is None:
            os.killpg(up.pid, signal.SIGINT)
            try:
                up.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(up.pid, signal.SIGKILL)
                up.wait()
        log.close()
        for pid in processes_on_domain(domain):   # only after a failure: never leave them running
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def run(testbed, cwd, *args, steps=30, robots=2, files=()):
    """./robotarium run turns_and_saves.py on the module's testbed; (exit code, output, run folder)."""
    done = cli("run", "--no-local-testbed", "--no-video", "--bags-dir", str(testbed["bags"]), "--results-dir",
               str(testbed["root"] / "results"), *args, SCRIPT, str(steps), str(robots), *files,
               env=testbed["env"], cwd=str(cwd))
    folder = re.findall(r"results in (\S+) \(open", done.stdout)
    return done.returncode, done.stdout, os.path.join(str(cwd), folder[-1]) if folder else None


def test_a_second_testbed_in_the_namespace_refuses_naming_the_first(testbed, tmp_path):
    # The same command again: one line naming the testbed that runs (host, pid, since), exit code 4.
    second = cli("up", "--bags-dir", str(tmp_path), env=testbed["env"], cwd=str(tmp_path))
    lines = second.stdout.strip().splitlines()
    assert second.returncode == 4 and len(lines) == 1, second.stdout
    assert "not starting a second testbed: a simulator already runs in %s" % NAMESPACE in lines[0], lines[0]
    assert "host %s" % socket.gethostname() in lines[0] and "since " in lines[0], lines[0]
    assert "started by ./robotarium up --bags-dir %s (pid %d)" % (testbed["bags"], testbed["up"].pid) in lines[0]
    # A node started as ros2 run or a launch file starts it (no starter that looked first) refuses too.
    log = tmp_path / "safety.log"
    stray = NodeProcess("robotarium_safety.safety_node", testbed["domain"], ros_args=["-r", "__ns:=%s" % NAMESPACE],
                        log_path=str(log), env=testbed["env"])
    try:
        assert stray.proc.wait(timeout=60) == 4, stray.output()
    finally:
        stray.close()
    assert "a safety node already runs in %s" % NAMESPACE in stray.output(), stray.output()
    # The first testbed never noticed: a run completes on it, recorded by its recorder.
    code, out, folder = run(testbed, tmp_path)
    assert code == 0 and "Run completed." in out, out
    assert folder.startswith(str(testbed["bags"])) and os.path.isfile(os.path.join(folder, "report.txt")), out
    assert testbed["up"].poll() is None, testbed["log"].read_text()


def test_data_files_over_the_cap_are_left_out_and_named(testbed, tmp_path):
    config = yaml.safe_load(open(DEFAULT_FILE))
    config["/**"]["ros__parameters"]["run_data_limit"] = 0.05   # MB
    with open(tmp_path / "capped.yaml", "w") as f:
        yaml.safe_dump(config, f)
    # small.dat (10 kB) is written first, big.dat (80 kB) last: the newest first, each that fits.
    code, out, folder = run(testbed, tmp_path, "--config", str(tmp_path / "capped.yaml"),
                            files=("small.dat:10", "big.dat:80"))
    assert code == 0 and "Run completed." in out, out
    assert "1 data file(s) of 0.08 MB left out of the run folder (run_data_limit 0.05 MB" in out, out
    assert os.listdir(os.path.join(folder, "data")) == ["small.dat"]
    with open(os.path.join(folder, "run.json")) as f:
        assert list(json.load(f)["data_not_saved"]) == ["big.dat"]
    with open(os.path.join(folder, "report.txt")) as f:
        assert "data file big.dat not saved in the run folder: left out: 0.08 MB over" in f.read()


def _mount_small_disk(bags, size):
    """A tmpfs of `size` over the recorder's bags folder (root only: else the test skips)."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs under the recorder needs root")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=%s" % size, "tmpfs", bags], stderr=subprocess.PIPE,
                             text=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here: %s" % mounted.stderr.strip())


def _unmount(bags):
    for _ in range(50):   # the recorder may still hold the bag it wrote: lazily, then wait
        if subprocess.run(["umount", "-l", bags], stderr=subprocess.DEVNULL).returncode == 0:
            return
        time.sleep(0.1)


def test_a_full_disk_stops_the_recording_not_the_run_nor_the_testbed(testbed, tmp_path):
    bags = str(testbed["bags"])
    _mount_small_disk(bags, "256k")
    try:
        # 10 robots, 2000 steps: a bag of ~600 kB, so the disk fills during the run (near step 820; with
        # 1000 steps, ~300 kB, it filled only at the last chunk on a loaded machine, after the run had ended)
        code, out, folder = run(testbed, tmp_path, steps=2000, robots=10)
        assert code == 4 and ACCEPTANCE not in out, out
        assert "the experiment completed, but recording stopped at step" in out and "disk full" in out, out
        # The run folder is beside the full disk; it says where the recording stopped and why.
        assert folder.startswith(str(testbed["root"] / "results")), out
        with open(os.path.join(folder, "run.json")) as f:
            info = json.load(f)
        k = info["recording_stopped_at_step"]
        assert info["recording_stopped_because"] == "disk full" and info["exit_code"] == 4, info
        assert info["outcome"] == "completed" and 0 < k < 2000, info
        assert info["collisions"] == 0 and info["boundary_violations"] == 0, info   # the robots were unharmed
        with open(os.path.join(folder, "report.txt")) as f:
            report = f.read()
        assert report.startswith("Run completed. Recording stopped at step %d: disk full" % k), report
        assert ACCEPTANCE not in report and "recording is incomplete" in report, report
        with open(os.path.join(folder, "index.html")) as f:
            assert "Recording stopped at step %d: disk full" % k in f.read()
        # What was recorded reads back with an independent reader, up to step k.
        from pathlib import Path

        from rosbags.highlevel import AnyReader
        with AnyReader([Path(info["recording"])]) as reader:
            poses = [c for c in reader.connections if c.topic == NAMESPACE + "/poses"]
            steps = [reader.deserialize(raw, c.msgtype).step for c, _, raw in reader.messages(connections=poses)]
        assert steps and max(steps) == k
        assert testbed["up"].poll() is None, testbed["log"].read_text()
        assert "Traceback" not in testbed["log"].read_text()
        # The testbed survives: with room again, the next run is recorded in full.
        shutil.rmtree(info["recording"])
        code, out, folder = run(testbed, tmp_path)
        assert code == 0 and "Run completed." in out and ACCEPTANCE in out, out
        assert folder.startswith(bags) and glob.glob(os.path.join(folder, "*.mcap")), out
    finally:
        _unmount(bags)


def test_a_disk_full_before_the_first_step_is_recorded_says_so_first(testbed, tmp_path):
    """A disk with room for the bag's header but not its first chunk: the bag holds no step. The run
    completes; its report's first line names the full disk (it read "Run completed." and the cause only
    in its last line, after "the results could not be made": a soak's lost run)."""
    bags = str(testbed["bags"])
    _mount_small_disk(bags, "12k")
    try:
        code, out, folder = run(testbed, tmp_path, steps=600, robots=10)
        assert code == 4 and ACCEPTANCE not in out, out
        assert "holds no step of the run, so there are no results of it" in out, out
        assert folder.startswith(str(testbed["root"] / "results")), out
        with open(os.path.join(folder, "run.json")) as f:
            info = json.load(f)
        assert info["recording_stopped_because"] == "disk full" and info["outcome"] == "completed", info
        with open(os.path.join(folder, "report.txt")) as f:
            report = f.read()
        assert report.startswith("Run completed. Recording stopped at step %d: disk full: the recording is "
                                 "incomplete." % info["recording_stopped_at_step"]), report
        assert "holds no step of the run" in report and os.path.isfile(os.path.join(folder, "index.html")), report
        assert testbed["up"].poll() is None, testbed["log"].read_text()
    finally:
        _unmount(bags)


def _room(path):
    """The room a file takes on a tmpfs (whole pages)."""
    return -(-os.path.getsize(path) // 4096) * 4096


def _bag_and_results_room(folder):
    """(room the bag in `folder` took, counting metadata.yaml twice as its rewrite needs, room its results took)."""
    names = os.listdir(folder)
    bag = sum(_room(os.path.join(folder, n)) for n in names if n.endswith(".mcap"))
    bag += 2 * _room(os.path.join(folder, "metadata.yaml"))
    results = sum(_room(os.path.join(folder, n)) for n in names if not n.endswith(".mcap") and n != "metadata.yaml")
    return bag, results


def _leave_free(bags, room):
    """Fill the disk under `bags` to leave `room` bytes free."""
    stats = os.statvfs(bags)
    free = stats.f_bavail * stats.f_frsize
    assert free > room, (free, room)
    with open(os.path.join(bags, "filler"), "wb") as f:
        f.write(b"\0" * (free - room))


def _steps_in(bag):
    from pathlib import Path

    from rosbags.highlevel import AnyReader
    with AnyReader([Path(bag)]) as reader:
        poses = [c for c in reader.connections if c.topic == NAMESPACE + "/poses"]
        return [reader.deserialize(raw, c.msgtype).step for c, _, raw in reader.messages(connections=poses)]


def test_results_with_no_room_beside_the_bag_go_to_the_results_folder(testbed, tmp_path):
    """The bag's disk takes the whole recording, not the results beside it: the run folder is
    results/<run id>/ with every result, the bag stays whole where it was, nothing of the results is left
    on the full disk (the results were attempted there and lost with the disk's folder: a soak's run)."""
    bags = str(testbed["bags"])
    code, out, folder = run(testbed, tmp_path)   # the same run on a roomy disk: the room its bag and results take
    assert code == 0, out
    bag_room, results_room = _bag_and_results_room(folder)
    _mount_small_disk(bags, "2m")
    try:
        _leave_free(bags, bag_room + results_room // 2)
        code, out, folder = run(testbed, tmp_path)
        assert code == 0 and "Run completed." in out and ACCEPTANCE in out, out
        assert re.search(r"the disk of %s/\S+ is full: the run's folder is \S+ \(the recording holds the whole run\)"
                         % re.escape(bags), out), out
        assert folder.startswith(str(testbed["root"] / "results")), out
        with open(os.path.join(folder, "run.json")) as f:
            info = json.load(f)
        assert info["recording"].startswith(bags) and info.get("recording_stopped_at_step") is None, info
        for name in ("report.txt", "index.html", "trajectories.png", "log.txt", os.path.basename(SCRIPT)):
            assert os.path.isfile(os.path.join(folder, name)), (name, os.listdir(folder))
        with open(os.path.join(folder, "report.txt")) as f:
            assert f.readline().startswith("Run completed."), out
        left = sorted(os.listdir(info["recording"]))
        assert len(left) == 2 and left[0] == "metadata.yaml" and left[1].endswith(".mcap"), left
        assert _steps_in(info["recording"]) == list(range(31)), info["recording"]
    finally:
        _unmount(bags)


def test_a_disk_that_fills_as_the_bag_closes_gives_the_same_run_folder(testbed, tmp_path):
    """Room for half the bag of a short run: the disk fills as the recorder writes its last chunk, during
    the run or after its end as the bag is closed (the client then hears nothing of it: `run` finds it out
    by its own write). Either way: the run completed, its recording stopped at step k for a full disk, the
    run folder in results/<run id>/."""
    bags = str(testbed["bags"])
    code, out, folder = run(testbed, tmp_path)
    assert code == 0, out
    bag_room, _ = _bag_and_results_room(folder)
    _mount_small_disk(bags, "2m")
    try:
        _leave_free(bags, bag_room // 5)
        code, out, folder = run(testbed, tmp_path)
        # (the script's own debug report may say acceptance is likely: it ends before the bag is closed)
        assert code == 4 and "the experiment completed, but recording stopped at step" in out, out
        assert folder.startswith(str(testbed["root"] / "results")), out
        assert "see %s" % folder in out or "holds no step" not in out, out   # never the folder on the full disk
        with open(os.path.join(folder, "run.json")) as f:
            info = json.load(f)
        k = info["recording_stopped_at_step"]
        assert info["recording_stopped_because"] == "disk full" and info["outcome"] == "completed", info
        assert info["exit_code"] == 4 and k is not None and k < 30, info
        with open(os.path.join(folder, "report.txt")) as f:
            report = f.read()
        assert report.startswith("Run completed. Recording stopped at step %d: disk full: the recording is "
                                 "incomplete." % k) and ACCEPTANCE not in report, report
        assert os.path.isfile(os.path.join(folder, "index.html")), os.listdir(folder)
        assert testbed["up"].poll() is None, testbed["log"].read_text()
    finally:
        _unmount(bags)


def test_an_end_request_the_script_did_not_send_is_never_run_completed(testbed, tmp_path):
    """A process that copied the run's token off the wire ends the experiment at step ~115 (it used to
    be "Run completed. Acceptance ... likely!" with run.json saying interrupted)."""
    forger = subprocess.Popen([sys.executable, "-m", "devtools.forged_end", "--namespace", NAMESPACE, "--at-step",
                               "115", "--wait", "150"], env=testbed["env"], cwd=str(tmp_path),
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        code, out, folder = run(testbed, tmp_path, steps=3000)   # lockstep: it ends long before step 3000
        forged = forger.communicate(timeout=60)[0]
    finally:
        if forger.poll() is None:
            forger.kill()
            forger.wait()
    assert '"success": true' in forged, forged
    assert "Run completed" not in out and ACCEPTANCE not in out and code == 4, out
    with open(os.path.join(folder, "run.json")) as f:
        info = json.load(f)
    k = info["ended_by_unsent_request_at_step"]
    assert 110 <= k < 3000, info   # (the simulator may not have applied the array of step 115 yet)
    assert info["outcome"] == "ended_by_unsent_request" and info["exit_code"] == 4 and code == 4, (info, out)
    cause = "the experiment was ended at step %d by an end request this script did not send (a process holding " \
            "its token)" % k
    assert "EndedByUnsentRequest: T%s" % cause[1:] in out and "could not end" not in out, out   # the script's step() raised it
    assert "Run did not complete: %s." % cause in out, out
    with open(os.path.join(folder, "report.txt")) as f:
        report = f.read()
    assert report.startswith("Run did not complete: %s." % cause) and ACCEPTANCE not in report, report
    with open(os.path.join(folder, "index.html")) as f:
        assert cause in f.read()
    assert testbed["up"].poll() is None, testbed["log"].read_text()


# Stuck mid-run in a call that holds the GIL and never returns, as a deadlock inside Fast DDS met in a publish or a
# take leaves a script: nothing of Python runs, its own watches included (ctypes.PyDLL keeps the GIL over pause()).
STUCK_IN_C = """import ctypes
import numpy as np
import rps.robotarium as robotarium
from robotarium_client import testbed_link
testbed_link.HUNG_STEP = 3.0   # (60 s by default)
N = 2
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=False)
for k in range(60):
    r.get_poses()
    r.set_velocities(np.arange(N), np.zeros((2, N)))
    if k == 30:
        r._link.send = lambda *args: ctypes.PyDLL(None).pause()
    r.step()
r.call_at_scripts_end()
"""


def test_a_script_stuck_for_good_in_a_call_into_dds_is_ended_and_run_names_the_cause(testbed, tmp_path):
    """A step() that never comes back from a call holding the GIL ends within HUNG_STEP: the kernel's timer ends
    the process (SIGALRM), ./robotarium run names its own Fast DDS as the cause, exit code 4, the recorded steps
    kept; the testbed goes on."""
    script = tmp_path / "stuck.py"
    script.write_text(STUCK_IN_C)
    completed = subprocess.run([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--no-video",
                                "--lockstep", "--bags-dir", str(testbed["bags"]), "--results-dir",
                                str(testbed["root"] / "results"), str(script)], env=testbed["env"], cwd=str(tmp_path),
                               capture_output=True, text=True, timeout=120)
    out = completed.stdout + completed.stderr
    assert completed.returncode == 4 and outcomes.OWN_DDS_HUNG in out, out
    folder = re.findall(r"results in (\S+) \(open", out)
    with open(os.path.join(str(tmp_path), folder[-1], "run.json")) as f:
        info = json.load(f)
    assert info["outcome"] == "testbed_lost" and info["detail"].startswith(outcomes.OWN_DDS_HUNG), info
    assert info["steps"] >= 30, info
    assert testbed["up"].poll() is None, testbed["log"].read_text()


@pytest.mark.parametrize("stopped", ["all", "event"])
def test_a_script_whose_own_fast_dds_stops_says_so_and_ends(testbed, tmp_path, stopped):
    """Fast DDS 2.14 can deadlock a participant inside (docs/faults.md: alive but deaf), the script's as well
    as a node's. Here Fast DDS threads of the script's process are stopped for real (ptrace) mid-run.
    all: its step() hears no poses for 10 s and says its own DDS stopped (it blamed the safety node);
    event (its event thread alone: the run goes on): the run completes, and the script does not hang for ever
    as it leaves DDS at its end (it did: destroy_node waits for the event thread); or, where the thread stopped
    holding a lock a publish needs, the step hangs and is ended as in `all`."""
    from devtools.rosutil import FrozenThread
    from devtools.soak import proc_children
    from robotarium_core import dds_health
    steps = "100000" if stopped == "all" else "3000"
    process = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--no-video",
                                "--lockstep", "--bags-dir", str(testbed["bags"]), "--results-dir",
                                str(testbed["root"] / "results"), SCRIPT, steps, "2"],
                               env=testbed["env"], cwd=str(tmp_path), stdout=open(tmp_path / "run.out", "wb"),
                               stderr=subprocess.STDOUT, start_new_session=True)
    frozen = []
    try:
        deadline = time.monotonic() + 120
        runner, threads = None, {}
        while not threads and time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.2)
            try:
                runner = next((pid for pid in proc_children(process.pid)
                               if b"robotarium_cli.runner" in open("/proc/%d/cmdline" % pid, "rb").read()), None)
                threads = runner and dds_health.dds_event_threads(runner)
            except OSError:
                threads = {}
        assert threads, "the script's process never started its Fast DDS"
        time.sleep(2)   # its run under way
        for tid in sorted(int(t) for t in os.listdir("/proc/%d/task" % runner)):
            try:
                with open("/proc/%d/task/%d/comm" % (runner, tid)) as f:
                    name = f.read()
            except OSError:
                continue
            if name.startswith("dds.ev." if stopped == "event" else "dds."):
                frozen.append(FrozenThread(tid))
        deadline = time.monotonic() + 90
        while process.poll() is None and time.monotonic() < deadline:
            # A stopped thread whose process exits waits for its tracer: reaped here, as a deadlocked one needs not
            for thread in frozen:
                thread.gone()
            time.sleep(0.2)
        out = (tmp_path / "run.out").read_text(errors="replace")
        assert process.poll() is not None, "run did not end within 90 s of the freeze:\n%s" % out[-4000:]
    finally:
        for thread in frozen:
            thread.release()
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    folder = re.findall(r"results in (\S+) \(open", out)
    with open(os.path.join(str(tmp_path), folder[-1], "run.json")) as f:
        info = json.load(f)
    if stopped == "all":
        # its step() heard nothing for STEP_TIMEOUT and said why; or, where the freeze caught a call into Fast DDS
        # that held the GIL (nothing of Python runs then: the run hung here once), the kernel's timer ended it
        assert "This script's own Fast DDS stopped (dds.ev.0 (thread" in out or outcomes.OWN_DDS_HUNG in out, out
        assert info["outcome"] == "testbed_lost" and "own Fast DDS stopped" in info["detail"], info
        assert process.returncode == 4, out
    elif outcomes.OWN_DDS_HUNG in out or "This script's own Fast DDS stopped (dds.ev.0 (thread" in out:
        # the freeze caught the event thread inside a lock that a publish or a take needs too (a writer's, which its
        # heartbeats take every 0.1 s): the step() hung in Fast DDS and the kernel's timer ended it, as it says (a
        # whole-suite run under load, 2026-11-30); or a poses sample lost on the wire waits for a repair that the
        # stopped thread's timed events would ask for: no poses for STEP_TIMEOUT, and step() names its own DDS, as
        # in `all` (a whole-suite run, 2026-11-30: at step 2652 of 3000)
        assert info["outcome"] == "testbed_lost" and "own Fast DDS stopped" in info["detail"], info
        assert process.returncode == 4, out
    else:
        assert "this script's Fast DDS could not be left: dds.ev.0 (thread" in out, out
        assert info["outcome"] == "completed" and info["steps"] == 3000 and process.returncode == 0, out
    assert testbed["up"].poll() is None, testbed["log"].read_text()
