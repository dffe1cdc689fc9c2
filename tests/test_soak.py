"""A short soak (issue 41): the core of `./robotarium bench soak` (devtools/soak.py) for 16 runs on one
`./robotarium up` of its own, with the same faults: the script's process killed (SIGKILL) and `run`
interrupted (SIGINT) or killed (SIGKILL) mid-run, a flood of foreign and forged arrays, the recorder's disk
full (a 256 KiB tmpfs: as root), a recorder and a simulator frozen (SIGSTOP for 3 s, longer than their lease,
then SIGCONT) and a safety node killed (`up` stops the testbed; the soak starts it again). Mostly short
lockstep runs of the guide's listings and the 2.x examples; the runs a fault goes into run long enough for it.

Every run must complete or end with the true cause of the fault that hit it, in run.json and in its
report.txt, with its results; a killed node's runs do not yet (issue 41, item 2: `up` stops the whole testbed
at once, so the run names the testbed's stop, or another node): that test is an expected failure. Nothing the
soak started may stay running.
"""
import os

import pytest

from devtools import soak
from devtools.rosutil import processes_on_domain

pytestmark = pytest.mark.e2e   # whole runs through ./robotarium

RUNS, SEED = 16, 46
NODE_FAULTS = ["freeze:recorder", "kill:safety", "freeze:simulator"]   # one in each stretch of 6 runs
ITERATIONS = {("lockstep", "long"): 600, ("real-time", "long"): 150}   # a fault's run: long enough for it


@pytest.fixture(scope="module")
def soaked(tmp_path_factory):
    work = tmp_path_factory.mktemp("soak")
    said = []
    plans = soak.plan(RUNS, SEED, node_every=6, real_time=0.1, long=0.0, client_faults=0.0, node_faults=NODE_FAULTS,
                      iterations=ITERATIONS)
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
    lost = [r for r in run.results if r.verdict not in ("completed", "by fault", "time limit") and not killed(r)]
    assert not lost, text
    # every fault went into its run: injected mid-run, the flood heard by the testbed, the disk full
    faults = {p.fault for p in plans if p.fault}
    assert faults == set(soak.CLIENT_FAULTS) | set(NODE_FAULTS) | ({"disk_full"} if os.geteuid() == 0 else set()), text
    for r in run.results:
        if r.fault and not killed(r):
            assert r.injected and (r.verdict == "by fault" or r.fault == "flood"), text
    flood = [r for r in run.results if r.fault == "flood"]
    assert flood and all("arrays dropped by the testbed" in r.injected for r in flood), text
    # a killed node: up stopped the testbed, the soak started it again (and nothing else restarted it)
    assert [after for after, _, expected in run.restarts] == [r.n for r in run.results if killed(r)], text
    assert all(expected for _, _, expected in run.restarts), text


@pytest.mark.xfail(strict=True, reason="issue 41, item 2: a killed node makes ./robotarium up stop the whole testbed "
                                       "at once; the run in progress names the testbed's stop ('received SIGINT') or, "
                                       "for a killed simulator, the safety node up stopped first")
def test_a_run_whose_node_was_killed_names_that_node(soaked):
    run, _, text = soaked
    hit = [r for r in run.results if killed(r) and r.injected]
    assert hit and all(r.verdict == "by fault" for r in hit), text


def test_the_soak_leaves_nothing_running(soaked):
    run, _, text = soaked
    assert not processes_on_domain(run.domain), text
    assert not os.path.ismount(run.up.bags)
    assert run.up.process.poll() is not None
