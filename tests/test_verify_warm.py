"""./robotarium verify on a warm verification testbed (./robotarium up --verification; issue 40, goal 2):
which testbed it takes (the pure rule), that a verdict there is the one of a testbed of its own, and
that a busy warm testbed, or one that dies mid-verification, costs time but never the verdict (verify
runs the script again on a testbed of its own, saying so).

The warm testbed is `python -m robotarium_cli up --verification` on a ROS_DOMAIN_ID of this module's own.
"""
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from devtools.rosutil import REPO, node_env, unique_domain_id
from robotarium_bringup import local_testbeds
from robotarium_cli import running
from robotarium_core import outcomes

DATA = os.path.join(REPO, "tests", "data")
HEAD_ON = os.path.join(DATA, "head_on_no_barrier.py")

# A script that keeps the warm testbed busy long enough to be killed mid-run: 2 robots, lockstep, ~10 s.
SLOW = """\
import time
import numpy as np
import rps.robotarium as robotarium
r = robotarium.Robotarium(number_of_robots=2, show_figure=False, sim_in_real_time=False,
                          initial_conditions=np.array([[-0.5, 0.5], [0.0, 0.0], [0.0, 0.0]]))
for _ in range(2000):
    r.get_poses()
    r.set_velocities(np.arange(2), np.zeros((2, 2)))
    r.step()
    time.sleep(0.005)
r.call_at_scripts_end()
"""

# A script that holds the warm testbed (an experiment in real time) until the file its argument names exists.
HOLDS = """\
import os, sys, time
import numpy as np
import rps.robotarium as robotarium
r = robotarium.Robotarium(number_of_robots=1, show_figure=False, sim_in_real_time=True)
print("HOLDING", flush=True)
deadline = time.monotonic() + 120
while not os.path.exists(sys.argv[1]) and time.monotonic() < deadline:
    r.get_poses()
    r.step()
r.call_at_scripts_end()
"""


# -- which testbed: the pure rule ------------------------------------------------------------------------

def entry(**changes):
    """A registry entry of a warm verification testbed that a recorded verification with the defaults takes."""
    base = {"namespace": running.VERIFY_NAMESPACE, "domain": "7", "discovery_range": "LOCALHOST", "root": "/co",
            "config_file": "", "hardware": False, "fleet_file": "", "bags_dir": "",
            "owner": {"pid": 1, "start": 1}, "nodes": {"simulator": {"pid": 2, "start": 1},
                                                     "safety": {"pid": 3, "start": 1},
                                                     "recorder": {"pid": 4, "start": 1}}}
    base.update(changes)
    return base


def take(entries, record=True, bags_dir="/co/bags", config_file="", alive=lambda p: bool(p and p.get("start"))):
    return running.warm_verification_testbed(entries, "7", "LOCALHOST", "/co", config_file, record, bags_dir, alive)


def test_verify_takes_a_warm_testbed_only_where_it_judges_as_one_of_its_own_would():
    good = entry()
    assert take([good]) is good
    assert take([entry(bags_dir="/co/bags")]) is not None   # the recorder's default, said
    no_recorder = entry(nodes={"simulator": {"pid": 2, "start": 1}, "safety": {"pid": 3, "start": 1}})
    assert take([no_recorder], record=False, bags_dir="/co/bags") is no_recorder
    assert take([good, no_recorder], record=False) is no_recorder   # --no-record: never recorded anyway
    refused = {
        "another namespace": entry(namespace="/robotarium"),
        "another domain": entry(domain="8"),
        "another discovery range": entry(discovery_range=""),
        "another checkout": entry(root="/other"),
        "another configuration": entry(config_file="/co/mine.yaml"),
        "hardware-like": entry(hardware=True),
        "an older registry entry (no hardware field)": {k: v for k, v in entry().items() if k != "hardware"},
        "a fleet": entry(fleet_file="/co/fleet.yaml"),
        "recording elsewhere": entry(bags_dir="/elsewhere"),
        "no recorder for a recorded verification": no_recorder,
        "its owner gone": entry(owner={"pid": 1, "start": None}),
        "its simulator gone": entry(nodes=dict(entry()["nodes"], simulator={"pid": 2, "start": None})),
        "a hardware arena's nodes": entry(nodes={"arena": {"pid": 2, "start": 1}, "safety": {"pid": 3, "start": 1},
                                                 "recorder": {"pid": 4, "start": 1}}),
    }
    for why, wrong in refused.items():
        assert take([wrong]) is None, why
    assert take([good], record=False) is None   # a recorder: a verification not recorded would be
    assert take([entry(config_file="/co/mine.yaml")], config_file="/co/mine.yaml") is not None


def test_a_warm_testbed_the_portal_names_is_taken_without_the_registry_and_never_reaches_the_script(monkeypatch):
    """In a job box (robotarium_portal.jobs) verify can see neither this machine's registry nor the warm testbed's
    processes: the slot names it (WARM_VARIABLE), verify still checks its settings, and takes the variable out of
    its environment, so the script never sees it."""
    named = entry(nodes={"simulator": {"pid": 2, "start": 1}, "safety": {"pid": 3, "start": 1}},
                  owner={"pid": 99999999, "start": 5})   # no such process here: not looked at
    monkeypatch.setenv("ROBOTARIUM_ROOT", "/co")
    monkeypatch.setenv("ROS_DOMAIN_ID", "7")
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setattr(local_testbeds, "registered", lambda: [])
    monkeypatch.setenv(running.WARM_VARIABLE, json.dumps(named))
    assert running.find_warm_verification_testbed(None, False, None) == named
    assert running.WARM_VARIABLE not in os.environ
    monkeypatch.setenv(running.WARM_VARIABLE, json.dumps(named))
    assert running.find_warm_verification_testbed(None, True, None) is None   # recorded: it has no recorder
    monkeypatch.setenv(running.WARM_VARIABLE, json.dumps(dict(named, domain="8")))
    assert running.find_warm_verification_testbed(None, False, None) is None


@pytest.mark.parametrize("outcome, code, failed", [
    ("testbed_busy", 4, True), ("testbed_lost", 4, True), ("unfinished", 4, True), ("testbed_incomplete", 4, True),
    ("interrupted", 4, True),      # the testbed ended it (stopped)
    ("interrupted", 130, False),   # Ctrl-C to verify itself: no second run
    ("completed", 0, False), ("script_error", 1, False), ("no_end", 3, False), ("client_lost", 4, False)])
def test_only_the_warm_testbeds_own_failures_send_the_script_to_a_testbed_of_its_own(outcome, code, failed):
    from robotarium_core.run_record import RunRecord
    assert (running.warm_testbed_failure(code, RunRecord(outcome=outcome, detail="why")) is not None) == failed
    assert running.warm_testbed_failure(2, None) is None   # nothing ran (a bad command line)


def test_a_warm_testbed_that_does_not_answer_the_scripts_client_is_its_failure_not_the_scripts():
    from robotarium_core.run_record import RunRecord
    silent = "the script raised RuntimeError: %s in namespace /robotarium_verify on ROS_DOMAIN_ID 7. Start one " \
             "with './robotarium up' at step 0" % outcomes.NO_TESTBED_ANSWERS
    assert running.warm_testbed_failure(1, RunRecord(outcome="script_error", detail=silent)) == "does not answer"
    # the script's own error, or one raised after its experiment started, is the script's
    assert running.warm_testbed_failure(1, RunRecord(outcome="script_error", detail="the script raised KeyError")) is None
    assert running.warm_testbed_failure(1, RunRecord(outcome="script_error", detail=silent, run_id="r1")) is None


# -- a real warm testbed ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def env():
    return node_env(unique_domain_id(), ROBOTARIUM_ROOT=REPO, ROBOTARIUM_PROGRESS="0")


class WarmTestbed:
    """python -m robotarium_cli up --verification --no-record on the module's domain, its output in a file."""

    def __init__(self, env, log_path):
        self.log_path = log_path
        self.log = open(log_path, "w")
        self.process = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "up", "--verification", "--no-record"],
                                        env=env, cwd=REPO, stdout=self.log, stderr=subprocess.STDOUT,
                                        start_new_session=True)
        self.wait_for("safety node ready", 60)
        self.wait_for("simulator ready", 60)

    def output(self):
        with open(self.log_path) as f:
            return f.read()

    def wait_for(self, words, timeout):
        deadline = time.monotonic() + timeout
        while words not in self.output():
            assert self.process.poll() is None and time.monotonic() < deadline, self.output()
            time.sleep(0.05)

    def node(self, name, domain):
        (found,) = [e for _, e in local_testbeds.registered()
                    if e["namespace"] == running.VERIFY_NAMESPACE and e["domain"] == domain]
        return found["nodes"][name]

    def stop(self):
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGINT)
            try:
                self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()
        self.log.close()


@pytest.fixture
def warm(env, tmp_path):
    testbed = WarmTestbed(env, str(tmp_path / "up.txt"))
    yield testbed
    testbed.stop()


def verify(env, tmp_path, script, *args, wait=True):
    command = [sys.executable, "-m", "robotarium_cli", "verify", "--no-record", script, "--json",
               str(tmp_path / "verdict.json"), "--results-dir", str(tmp_path / "results"), *args]
    process = subprocess.Popen(command, env=env, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if not wait:
        return process
    return finished(process, tmp_path)


def finished(process, tmp_path):
    out, _ = process.communicate(timeout=300)
    with open(tmp_path / "verdict.json") as f:
        return process.returncode, json.load(f), out


@pytest.mark.e2e   # ./robotarium verify, whole, with ./robotarium up --verification
def test_a_verification_on_the_warm_testbed_gives_the_verdict_of_a_testbed_of_its_own(env, tmp_path, warm):
    code, document, out = verify(env, tmp_path, HEAD_ON)
    assert code == outcomes.VERIFY_REJECTED, out
    assert "on the warm verification testbed (%s" % running.VERIFY_NAMESPACE in out, out
    assert "started head_on_no_barrier" in warm.output() and "audited for verification" in warm.output()
    # the Robotarium's simulator 0.0.0 counts 168 (tests/test_verify.py), as a testbed of verify's own does
    assert document["counts"]["collisions"] == 168 and [r["rule"] for r in document["rules"]] == ["collisions"]
    assert "a testbed of its own" not in out, out
    # the next one too: the warm testbed is free again at once
    (tmp_path / "verdict.json").unlink()
    code, again, out = verify(env, tmp_path, HEAD_ON)
    assert code == outcomes.VERIFY_REJECTED and again["counts"] == document["counts"], out
    assert warm.output().count("started head_on_no_barrier") == 2 and "a testbed of its own" not in out


@pytest.mark.e2e   # ./robotarium verify, whole, with ./robotarium up --verification
def test_a_busy_warm_testbed_sends_the_verification_to_a_testbed_of_its_own(env, tmp_path, warm):
    script, release = tmp_path / "holds.py", tmp_path / "release"
    script.write_text(HOLDS)
    holder = subprocess.Popen([sys.executable, str(script), str(release)], cwd=str(tmp_path), stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True,
                              env=dict(env, ROBOTARIUM_NAMESPACE=running.VERIFY_NAMESPACE))
    try:
        assert holder.stdout.readline().strip() == "HOLDING"
        code, document, out = verify(env, tmp_path, HEAD_ON)
    finally:
        release.write_text("")
        holder.communicate(timeout=60)
    assert "the warm verification testbed is busy: verifying" in out and "on a testbed of its own" in out, out
    assert code == outcomes.VERIFY_REJECTED and document["counts"]["collisions"] == 168, out


@pytest.mark.e2e   # ./robotarium verify, whole, with ./robotarium up --verification
def test_a_warm_testbed_that_dies_mid_verification_costs_a_second_run_not_the_verdict(env, tmp_path, warm):
    script = tmp_path / "slow.py"
    script.write_text(SLOW)
    process = verify(env, tmp_path, str(script), wait=False)
    warm.wait_for("started slow", 120)
    time.sleep(1.0)   # mid-run
    os.kill(warm.node("simulator", env["ROS_DOMAIN_ID"])["pid"], signal.SIGKILL)
    code, document, out = finished(process, tmp_path)
    assert "the warm verification testbed failed" in out and "on a testbed of its own" in out, out
    assert code == outcomes.VERIFY_ACCEPTED and document["iterations"] == 2000, out


@pytest.mark.e2e   # ./robotarium verify, whole
def test_verify_makes_a_video_only_when_asked(env, tmp_path):
    script = os.path.join(DATA, "two_robots_to_goals.py")
    refused = subprocess.run([sys.executable, "-m", "robotarium_cli", "verify", "--video", "--no-record", script],
                             env=env, cwd=REPO, capture_output=True, text=True, timeout=60)
    assert refused.returncode == outcomes.USAGE_ERROR and "not with --no-record" in refused.stderr
    for flags in ([], ["--video"]):
        bags = tmp_path / ("bags%d" % len(flags))
        completed = subprocess.run([sys.executable, "-m", "robotarium_cli", "verify", "--bags-dir", str(bags),
                                    "--results-dir", str(tmp_path / "results"), *flags, script],
                                   env=env, cwd=REPO, capture_output=True, text=True, timeout=300)
        assert completed.returncode == outcomes.VERIFY_ACCEPTED, completed.stdout + completed.stderr
        (folder,) = os.listdir(bags)
        files = os.listdir(bags / folder)
        assert "report.txt" in files and ("run.mp4" in files) == bool(flags), files


def test_a_warm_verification_testbed_is_neither_hardware_like_nor_a_fleet(env):
    for flag in (["--hardware"], ["--fleet", os.path.join(REPO, "tests", "data", "missing_fleet.yaml")]):
        completed = subprocess.run([sys.executable, "-m", "robotarium_cli", "up", "--verification", *flag], env=env,
                                   cwd=REPO, capture_output=True, text=True, timeout=60)
        assert completed.returncode == 2 and "not with --hardware or --fleet" in completed.stderr, completed.stderr
