"""A process is its pid and its start: a claim's process is found running only while that very process runs."""
import json
import os
import socket
import subprocess

from robotarium_core import claim
from robotarium_core.processes import process_start, runs_here


def ident(pid, started):
    return {"who": "safety", "host": socket.gethostname(), "pid": pid, "started": started}


def test_a_claims_process_runs_here_while_it_runs_and_not_once_another_took_its_pid():
    child = subprocess.Popen(["sleep", "30"])
    try:
        mine = ident(child.pid, process_start(child.pid))
        assert mine["started"] and runs_here(mine)
        # the same pid, started at another moment: another process that took it once the claim's was gone
        assert not runs_here(ident(child.pid, mine["started"] + 1))
        assert runs_here(ident(child.pid, None))                       # an older claim: by the pid alone
        assert not runs_here(dict(mine, host=socket.gethostname() + "-elsewhere"))
    finally:
        child.kill()
        child.wait()
    assert not runs_here(mine) and process_start(child.pid) is None   # gone
    assert not runs_here(None)


def test_a_claim_carries_its_start_and_an_older_claim_without_one_still_parses():
    me = claim.identity("safety")
    assert me["started"] == process_start(os.getpid()) and runs_here(me)
    assert claim.parse(json.dumps(me)) == me
    older = dict(me)
    del older["started"]
    assert claim.parse(json.dumps(older))["started"] is None
    assert claim.parse(json.dumps(dict(me, started="soon"))) is None   # malformed: refused, never raised
