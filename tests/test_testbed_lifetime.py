"""A testbed that `./robotarium run` starts never outlives the run (issue 17).

Real processes throughout: `./robotarium run` starts a real local testbed (simulator, safety node,
recorder) for a real-time script that would run forever, and the test sends one signal to the
`run` process alone, as `kill`, `timeout`, a CI runner or a closed terminal does. SIGTERM, SIGHUP
and SIGINT are caught by `run` (it stops the script, which ends its experiment, then the nodes);
SIGKILL cannot be, and the script and the nodes notice through their lifeline that `run` is gone.
Either way, within seconds:
- no process of that run remains (every process whose environment has the test's own
  ROS_DOMAIN_ID is counted, so an orphan cannot hide);
- the bag reads back with two independent readers (rosbags; mcap with mcap-ros2-support), was
  closed properly (metadata says complete, the MCAP file has its summary) and records the end of
  the experiment (its last status is IDLE);
- the next run in the same namespace works: every run here starts in the namespace the previous
  test's run was stopped in, and must find no testbed there and start its own experiment (an
  orphaned testbed would answer, and refuse the experiment as "still running"). The time-limit
  test runs last, after SIGKILL.
The bounds (how fast) are measured by `./robotarium bench testbed_lifetime`, not asserted here.
"""
import glob
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

from devtools.rosutil import CliRun, NodeProcess, RosProbe, node_env, processes_on_domain, unique_domain_id

pytestmark = pytest.mark.e2e   # whole runs through ./robotarium

NAMESPACE = "/lifetime"
# Real time, two robots, forever (a goal loop that never converges); prints RUNNING once it runs.
FOREVER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "run_forever.py")
# A 2.x example: the simulator refuses it hardware-like, in these words.
RPS2_EXAMPLE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples", "rps2",
                            "barrier_certificates", "si_barriers.py")
REFUSED_2X = "The testbed refused to start the experiment: the hardware-like mode models the guide's API only"


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """One domain and namespace for the module's runs; its own checkout root (log/testbed/ there)."""
    domain = unique_domain_id()
    root = tmp_path_factory.mktemp("lifetime")
    script = root / "forever.py"
    shutil.copy(FOREVER, script)
    env = node_env(domain, ROBOTARIUM_NAMESPACE=NAMESPACE, ROBOTARIUM_ROOT=str(root), ROBOTARIUM_PROGRESS="0")
    try:
        yield {"domain": domain, "root": root, "script": str(script), "bags": str(root / "bags"), "env": env}
    finally:
        leftovers = processes_on_domain(domain)   # only after a failure: never leave them running
        for pid in leftovers:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def run_folders(bags):
    return set(glob.glob(os.path.join(bags, "forever_*")))


def start_run(lab, *flags):
    """./robotarium run FLAGS forever.py, until the script's loop runs; checks that it started
    its own testbed (none was left answering in the namespace)."""
    run = CliRun(["--bags-dir", lab["bags"], *flags, lab["script"]], lab["env"], cwd=str(lab["root"]))
    try:
        assert run.wait_for("RUNNING", timeout=90), run.output()
    except BaseException:
        run.close()
        raise
    assert "started one on this machine" in run.output(), run.output()
    return run


def wait_until_gone(domain, timeout=20.0):
    """The processes still on the domain once none is left or `timeout` passed."""
    deadline = time.monotonic() + timeout
    while processes_on_domain(domain) and time.monotonic() < deadline:
        time.sleep(0.1)
    return processes_on_domain(domain)


def read_back(folder):
    """The run's bag through two independent readers; returns (poses count, last status state)."""
    import yaml
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.rosbag2 import Reader
    with open(os.path.join(folder, "metadata.yaml")) as f:   # closed by the recorder, not recovered
        assert yaml.safe_load(f)["rosbag2_bagfile_information"]["custom_data"]["complete"] == "true"
    with Reader(folder) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert sum(1 for _ in reader.messages()) == reader.message_count
    (mcap_file,) = glob.glob(os.path.join(folder, "*.mcap"))
    with open(mcap_file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_summary() is not None, "the MCAP file was not closed (no summary)"
        statuses = [m.state for _, channel, _, m in reader.iter_decoded_messages(topics=[NAMESPACE + "/status"])]
    return counts[NAMESPACE + "/poses"], statuses[-1]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT, signal.SIGKILL],
                         ids=lambda s: s.name)
def test_a_signal_to_run_leaves_no_testbed_behind(lab, sig):
    before = run_folders(lab["bags"])
    run = start_run(lab)
    try:
        os.kill(run.proc.pid, sig)   # to `run` alone, as `kill PID` does
        code = run.wait(timeout=60)
    finally:
        run.close()
    # caught signals: the shell's 128 + n; SIGKILL: killed
    assert code == (-sig if sig == signal.SIGKILL else 128 + sig), run.output()
    left = wait_until_gone(lab["domain"])
    assert not left, "still running after %s to ./robotarium run: %s" % (sig.name, left)
    (folder,) = run_folders(lab["bags"]) - before
    poses, last_state = read_back(folder)
    assert poses > 5
    from robotarium_msgs.msg import TestbedStatus
    assert last_state == TestbedStatus.STATE_IDLE, "the recording does not show the experiment ending"
    # the local testbed's registry entry went with it; its logs stay in a folder of its own
    assert not [e for e in _registry_entries() if e["domain"] == str(lab["domain"])]
    assert glob.glob(os.path.join(str(lab["root"]), "log", "testbed", "lifetime_%d_*" % lab["domain"], "simulator.log"))


def _registry_entries():
    from robotarium_bringup import local_testbeds
    return [entry for _, entry in local_testbeds.registered()]


def test_the_time_limit_ends_the_experiment_cleanly(lab):
    """--time-limit 1 in lockstep: exactly ceil(1 / 0.033) = 31 steps, then the experiment is ended,
    the script stopped (exit code 5), the report says so and every result is written."""
    before = run_folders(lab["bags"])
    run = CliRun(["--bags-dir", lab["bags"], "--lockstep", "--no-video", "--time-limit", "1", lab["script"]],
                 lab["env"], cwd=str(lab["root"]))
    try:
        code = run.wait(timeout=120)
    finally:
        run.close()
    out = run.output()
    assert code == 5, out
    assert "Stopped at the time limit: 1 s of testbed time (step 31" in out, out
    assert "RUNNING" in out and "##### DEBUG OUTPUT #####" in out, out
    assert not wait_until_gone(lab["domain"])
    (folder,) = run_folders(lab["bags"]) - before
    with open(os.path.join(folder, "report.txt")) as f:
        assert f.readline().startswith("Stopped at the time limit: 1 s of testbed time (step 31,")
    with open(os.path.join(folder, "run.json")) as f:
        info = json.load(f)
    assert info["steps"] == 31 and info["time_limit"]["limit"] == 1.0 and info["exit_code"] == 5
    for name in ("log.txt", "trajectories.png", "forever.py"):
        assert os.path.exists(os.path.join(folder, name)), name
    poses, last_state = read_back(folder)
    assert poses == 32   # step 0 and the 31 steps, nothing after the limit


def cli(lab, *args, ns=NAMESPACE, timeout=60):
    env = dict(lab["env"], ROBOTARIUM_NAMESPACE=ns)
    return subprocess.run([sys.executable, "-m", "robotarium_cli", *args], env=env, cwd=str(lab["root"]),
                          capture_output=True, text=True, timeout=timeout)


def test_status_lists_local_testbeds_and_stop_and_end_get_rid_of_them(lab):
    """`up` in our namespace and a stray simulator in another (started without a lifeline, as by
    `ros2 run`): status lists both with their process ids, the experiment running on the first and
    since when; `end` ends that experiment and prints its report; `stop` stops each, cleanly."""
    from robotarium_msgs.srv import StartExperiment
    up = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "up", "--bags-dir", lab["bags"]],
                          env=lab["env"], cwd=str(lab["root"]), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          start_new_session=True)
    stray = NodeProcess("robotarium_sim.simulator_node", lab["domain"], ros_args=["-r", "__ns:=/stray"])
    probe = RosProbe(lab["domain"])
    try:
        # someone else's experiment: another user on another host
        started = probe.hold_client_presence(probe.call(
            StartExperiment, NAMESPACE + "/start_experiment",
            StartExperiment.Request(name="held", number_of_robots=3, real_time=True,
                                    holder="bob@elsewhere pid 4242 erin.py"), timeout=60))
        assert started.success, started.message

        status = cli(lab, "status", "--json")
        assert status.returncode == 0, status.stderr
        listed = {t["namespace"]: t for t in json.loads(status.stdout)["local_testbeds"]
                  if t["domain"] == str(lab["domain"])}
        ours, other = listed[NAMESPACE], listed["/stray"]
        assert ours["owner"]["command"].startswith("./robotarium up") and ours["owner"]["pid"] == up.pid
        assert set(ours["nodes"]) == {"simulator", "safety", "recorder"}
        assert ours["experiment"]["running"] and ours["experiment"]["run_id"] == started.run_id
        assert ours["experiment"]["since"]
        assert other["owner"] is None and other["nodes"] == {"simulator": stray.proc.pid}

        end = cli(lab, "end")   # not ours: refused, saying whose it is and how to force it
        assert end.returncode == 1, end.stderr
        assert ("experiment %s is not yours: it is held by bob@elsewhere (pid 4242, script erin.py), run %s since "
                % (started.run_id, started.run_id)) in end.stderr, end.stderr
        assert "./robotarium end --force ends it anyway" in end.stderr and "step " in end.stderr, end.stderr
        end = cli(lab, "end", "--force")
        assert end.returncode == 0, end.stderr
        assert "##### DEBUG OUTPUT #####" in end.stdout and started.run_id in end.stdout, end.stdout
        assert "ended by an operator (end --force)" in end.stdout, end.stdout

        # our own (this user on this host): end ends it without --force, saying by whom
        from robotarium_client.testbed_link import holder_of_this_process
        mine = probe.hold_client_presence(probe.call(
            StartExperiment, NAMESPACE + "/start_experiment",
            StartExperiment.Request(name="mine", number_of_robots=2, real_time=True,
                                    holder=holder_of_this_process()), timeout=60))
        assert mine.success, mine.message
        end = cli(lab, "end")
        assert end.returncode == 0 and mine.run_id in end.stdout, end.stdout + end.stderr
        from robotarium_cli.folders import wait_until_recorded
        from robotarium_recording.results import recompute
        assert wait_until_recorded(os.path.join(lab["bags"], mine.run_id))
        ended = recompute(os.path.join(lab["bags"], mine.run_id))   # the recording says who ended it
        assert "ended by its user (%s) with ./robotarium end" % holder_of_this_process().split()[0] \
            in ended["first_line"], ended["first_line"]
        assert cli(lab, "end").returncode == 1   # nothing running now

        # no experiment runs on either: stop says so, not "experiment ended" (issue 36)
        stopped = cli(lab, "stop", "--namespace", "/stray")
        assert stopped.returncode == 0 and "stopped (no experiment was running)" in stopped.stderr, stopped.stderr
        assert stray.proc.wait(timeout=5) == 0
        stopped = cli(lab, "stop")   # this shell's namespace: asks `up` to stop
        assert stopped.returncode == 0 and "stopped (no experiment was running)" in stopped.stderr, stopped.stderr
        assert up.wait(timeout=5) == 0
        assert not wait_until_gone(lab["domain"])
        assert cli(lab, "stop").returncode == 1   # nothing left to stop
    finally:
        probe.close()
        stray.close()
        if up.poll() is None:
            os.killpg(up.pid, signal.SIGKILL)
        up.wait()


def test_a_testbed_without_a_safety_node_is_incomplete_not_a_script_error(lab):
    """A simulator and a recorder answer, no safety node does (issue 23): `status` says the testbed
    is incomplete, and `run` refuses with exit 4 and one line naming what is missing, with a hint
    about the testbed: never a traceback or "fix it" (the script is fine)."""
    from robotarium_bringup.testbed import LocalTestbed, testbed_answers
    ns = "/incomplete"
    saved = dict(os.environ)
    os.environ.update(lab["env"])
    try:
        testbed = LocalTestbed(ns=ns, bags_dir=lab["bags"], log_dir=str(lab["root"] / "incomplete_logs"))
        testbed.names = ["simulator", "recorder"]   # everything `up` starts but the safety node
        testbed.start()
        # Its simulator answers before `status` looks (on a loaded machine it took more than 5 s to come up).
        assert testbed_answers(ns, timeout=60), "the simulator did not come up: %s" % testbed.failed()
    finally:
        os.environ.clear()
        os.environ.update(saved)
    try:
        # (status is a new process: its discovery starts afresh, seconds on a loaded machine; it
        # answers as soon as the testbed's status comes)
        status = cli(lab, "status", "--timeout", "30", ns=ns)
        assert status.returncode == 0, status.stderr
        here = [line for line in status.stdout.splitlines() if line.startswith("On ROS_DOMAIN_ID")]
        assert here and "a testbed answers, incomplete: no safety node" in here[0], status.stdout
        script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "two_robots_to_goals.py")
        run = cli(lab, "run", "--no-video", "--bags-dir", lab["bags"], script, ns=ns, timeout=180)
        out = run.stdout + run.stderr
        assert run.returncode == 4, out
        assert "Traceback" not in out and "fix it" not in out, out
        assert ("The testbed in %s on ROS_DOMAIN_ID %s is incomplete: no safety node answers" % (ns, lab["domain"])
                in out), out
        assert "hint: the testbed has no safety node (nothing ran)" in out, out
        # A start the simulator refuses for the request's sake is said in its own words, though no safety node
        # answers there either (this client never sees one): "incomplete" only when the safety node was waited
        # for in vain (the start's `incomplete`), never for every refusal of a client that has not seen it yet.
        run = cli(lab, "run", "--no-video", "--hardware", "--bags-dir", lab["bags"], RPS2_EXAMPLE, ns=ns, timeout=180)
        out = run.stdout + run.stderr
        assert REFUSED_2X in out and "is incomplete" not in out, out
        assert not testbed.failed(), testbed.failed()   # the testbed itself goes on
    finally:
        testbed.stop()


def test_a_refused_start_on_a_testbed_started_a_moment_ago_says_the_refusal(lab):
    """`./robotarium run --hardware` of a 2.x example starts a testbed of its own and is refused at once (the
    hardware-like mode models the guide's API only), before its client may have seen the safety node's
    presence: the refusal's words reach the user, not "the testbed is incomplete" (the service soak's 2.x runs)."""
    ns = "/refused"
    run = cli(lab, "run", "--no-video", "--hardware", "--bags-dir", lab["bags"], RPS2_EXAMPLE, ns=ns, timeout=180)
    out = run.stdout + run.stderr
    assert "started one on this machine" in out, out   # (a fresh testbed of its own)
    assert REFUSED_2X in out, out
    assert "is incomplete" not in out, out
    assert run.returncode != 0, out
    assert not wait_until_gone(lab["domain"])   # its testbed went with it


def test_stop_mid_run_names_the_stopped_testbed_first(lab):
    """`./robotarium stop` of an `up` testbed while a run goes on (issue 23): the run ends with exit 4,
    the first cause it prints is the real one (the testbed was stopped), in one line (no traceback:
    the script is fine), and no "could not end the experiment" line follows (the testbed ended it
    itself)."""
    ns = "/stopped"
    env = dict(lab["env"], ROBOTARIUM_NAMESPACE=ns)
    up = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "up", "--bags-dir", lab["bags"]],
                          env=env, cwd=str(lab["root"]), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          start_new_session=True)
    run = None
    try:
        run = CliRun(["--no-local-testbed", "--no-video", "--bags-dir", lab["bags"], lab["script"]], env,
                     cwd=str(lab["root"]))
        assert run.wait_for("RUNNING", timeout=120), run.output()
        stopped = cli(lab, "stop", ns=ns)
        assert stopped.returncode == 0, stopped.stderr
        assert run.wait(timeout=60) == 4, run.output()
        out = run.output()
        assert "could not end the experiment" not in out and "Traceback" not in out, out
        causes = [line for line in out.splitlines() if "gone" in line or "stopped at step" in line]
        assert len(causes) == 1 and "the testbed was stopped at step" in causes[0], out   # said once, truly
        assert "hint: the testbed ended the experiment (it was stopped" in out and "fix it" not in out, out
    finally:
        if run is not None:
            run.close()
        if up.poll() is None:
            os.killpg(up.pid, signal.SIGKILL)
        up.wait()


def test_every_new_command_has_help():
    from robotarium_cli import main as robotarium_cli
    for command in ("status", "stop", "end", "run", "up"):
        with pytest.raises(SystemExit) as exit_:
            robotarium_cli.main([command, "--help"])
        assert exit_.value.code == 0, command
