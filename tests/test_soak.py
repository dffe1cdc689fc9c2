"""The short soak (issue 41): the core of `./robotarium bench soak` (devtools/soak.py) for 50 runs on one
`./robotarium up` of its own, with the same faults: the script's process killed (SIGKILL) and `run`
interrupted (SIGINT) or killed (SIGKILL) mid-run, a flood of foreign and forged arrays, the recorder's disk
full (a 256 KiB tmpfs: as root), and each node (recorder, safety node, simulator) killed (`up` restarts it;
the soak waits for it to be ready) and frozen (SIGSTOP for 3 s, longer than its lease, then SIGCONT), one
node fault in each stretch of 8 runs. Mostly short lockstep runs of the guide's listings and the 2.x
examples; the runs a fault goes into run long enough for it.

Every run must complete or end with the true cause of the fault that hit it, in run.json and in its
report.txt, with its results: a killed safety node's run goes on and completes, its record naming the restart
(the simulator arms the new process; issue 41, item 2), a killed simulator's ends "testbed node restarted at
step k: ... exited (killed by SIGKILL) and ./robotarium up restarted it", a killed recorder's run completes with
its recording stopped, and `up` never stops. Nothing the soak started may stay running.
"""
import os

import pytest

from devtools import soak
from devtools.rosutil import processes_on_domain

pytestmark = pytest.mark.e2e   # whole runs through ./robotarium

RUNS, SEED, NODE_EVERY = 50, 46, 8
NODE_FAULTS = ["freeze:recorder", "kill:safety", "freeze:simulator", "kill:recorder", "freeze:safety",
               "kill:simulator"]   # one in each stretch of NODE_EVERY runs, in this order
ITERATIONS = {("lockstep", "long"): 600, ("real-time", "long"): 150}   # a fault's run: long enough for it
# Scripts whose short run takes 10-30 s here (an EKF, a sensor sweep, loops that end only at their goals, a 2.x
# drive-on in real time) took half the soak's time; each runs in a test of its own (tests/test_rps2_examples.py,
# tests/test_safe_scripts.py). Loops with no iteration count run in lockstep here (15-25 s in real time).
LEAVE_OUT = ("rps2/state_estimation/extended_kalman_filter/ekf_experiment.py", "rps2/sensors/distance_sensor_avoidance.py",
             "rps2/go_to_goal/go_to_pose_hybrid.py", "guide/3_8_1_circle_switch_positions_with_plotting.py",
             "rps2/data_saving/leader_follower_save_data.py", "rps2/sensors/sensor_readings.py")


@pytest.fixture(scope="module")
def soaked(tmp_path_factory):
    work = tmp_path_factory.mktemp("soak")
    said = []
    plans = soak.plan(RUNS, SEED, node_every=NODE_EVERY, real_time=0.1, long=0.0, client_faults=0.0, node_faults=NODE_FAULTS,
                      iterations=ITERATIONS, leave_out=LEAVE_OUT,
                      real_time_uncounted=False)
    run = soak.Soak(str(work), seed=SEED, say=said.append)
    try:
        run.start()
        run.soak(plans, sample_every=RUNS, progress=0)
    finally:
        run.close()
    yield run, plans, "\n".join(said + soak.summary(run, plans))


def killed(result):
    return result.fault.startswith("kill:")


def test_no_run_is_lost_and_each_fault_is_named_with_its_true_cause(soaked):
    run, plans, text = soaked
    assert len(run.results) == RUNS, text
    lost = [r for r in run.results if r.verdict not in ("completed", "by fault", "time limit")]
    assert not lost, text
    # every fault went into its run: injected mid-run, the flood heard by the testbed, the disk full
    faults = {p.fault for p in plans if p.fault}
    assert faults == set(soak.CLIENT_FAULTS) | set(NODE_FAULTS) | ({"disk_full"} if os.geteuid() == 0 else set()), text
    for r in run.results:
        if r.fault:
            assert r.injected and (r.verdict == "by fault" or r.fault == "flood"), text
    flood = [r for r in run.results if r.fault == "flood"]
    assert flood and all("arrays dropped by the testbed" in r.injected for r in flood), text
    # a killed node: up restarted it (its supervisor), and never stopped
    assert [after for after, _ in run.node_restarts] == [r.n for r in run.results if killed(r)], text
    assert not run.restarts, text


def test_a_run_whose_node_was_killed_names_that_node(soaked):
    run, _, text = soaked
    hit = [r for r in run.results if killed(r) and r.injected]
    assert {r.fault for r in hit} == {f for f in NODE_FAULTS if f.startswith("kill:")}, text
    assert all(r.verdict == "by fault" for r in hit), text
    for r in hit:
        if r.fault == "kill:recorder":   # the run goes on; its recording stopped where the recorder died
            assert r.report_first_line.startswith("Run completed. Recording stopped at step"), text
            assert "the recorder was restarted" in r.report_first_line, text
        elif r.fault == "kill:safety":   # the run goes on on the restarted safety node, armed again
            assert r.report_first_line == "Run completed.", text
        else:
            assert r.report_first_line.startswith("Run did not complete: " + soak.RESTARTED), text


def test_the_soak_leaves_nothing_running(soaked):
    run, _, text = soaked
    assert not processes_on_domain(run.domain), text
    assert not os.path.ismount(run.up.bags)
    assert run.up.process.poll() is not None
