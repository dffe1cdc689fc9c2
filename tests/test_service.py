"""The Robotarium service on several machines: PostgreSQL, workers anywhere, exactly once or clearly failed.

A PostgreSQL server of the test's own (initdb and pg_ctl into a temporary folder, a free port), the portal
(`./robotarium serve --database ... --jobs 0`: no worker of its own) and two workers
(`./robotarium worker --database ...`): one on this machine, the other as a second host in a network
namespace of its own (a veth pair on a private test subnet; its host name its own), reaching PostgreSQL
over that link only. They share the data folder (on one machine the same path; across machines a shared
mount). Submissions go in as the portal's submit does (the experiment's files and its row, then its
verification job), from a Django process of the test's own pointed at the same database; the test reads the
truth straight from PostgreSQL (psycopg) and from the data folder.

No timing assertions: every wait is for a state, with a generous deadline and the logs on failure. The
heartbeat is 1 s here (ROBOTARIUM_WORKER_HEARTBEAT), so a lost worker is found after 5 s without a beat.
"""
import json
import os
import shutil
import socket
import sys
import tempfile
import threading
import time

import pytest

from devtools.postgres import PostgreSQL, server_binaries
from devtools.rosutil import processes_with_env
from devtools.service import HOLD, SECOND_HOST, SHORT, TIMEOUT, Service, run_quietly

pytestmark = pytest.mark.e2e
@pytest.fixture(scope="module")
def service():
    if server_binaries() is None:
        pytest.skip("no PostgreSQL server here (/usr/lib/postgresql/*/bin) and it could not be installed "
                    "(./robotarium test installs Debian's postgresql package when it runs as root with apt-get)")
    if os.geteuid() != 0 or shutil.which("ip") is None or shutil.which("unshare") is None:
        pytest.skip("the second host is a network namespace: this needs root and the ip and unshare commands")
    folder = tempfile.mkdtemp(prefix="robotarium-service-test-")
    service = Service(folder)
    try:
        service.make_second_host()
        service.postgres = PostgreSQL(listen=("127.0.0.1", service.host_address))
        service.start_portal()
        threads = [threading.Thread(target=service.start_worker, args=(name,)) for name in ("here", SECOND_HOST)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert set(service.workers) == {"here", SECOND_HOST}, service.logs()
        yield service
    finally:
        service.close()
        shutil.rmtree(folder, ignore_errors=True)
    assert processes_with_env("ROBOTARIUM_PORTAL_DATA", service.data) == {}


def test_the_second_host_reaches_the_database_over_its_own_link_only(service):
    """The namespace is a host of its own: its only way out is the veth link (not this machine's loopback)."""
    probe = "import socket,sys; s=socket.socket(); s.settimeout(3); s.connect((sys.argv[1], %d))" % service.postgres.port
    inside = ["ip", "netns", "exec", service.namespace, sys.executable, "-c", probe]
    assert run_quietly(*inside, service.host_address).returncode == 0
    assert run_quietly(*inside, "127.0.0.1").returncode != 0
    hosts = {h for (h,) in service.postgres.query("SELECT DISTINCT host FROM robotarium_portal_worker "
                                                  "WHERE state = 'alive'")}
    assert hosts == {socket.gethostname(), SECOND_HOST}


def test_twelve_submissions_on_two_hosts_and_a_database_restart_mid_run_each_verified_and_run_exactly_once(service):
    # a class of four, three each (one person's submissions are verified one at a time: the portal's fairness)
    items = [{"title": "short %d" % k, "robots": robots, "script": SHORT.format(robots=robots, steps=10 + k, name=k),
              "owner": "student%d@example.org" % (k % 4)} for k, robots in enumerate([2, 3, 4, 5] * 3)]
    pks = service.submit(items)
    # PostgreSQL restarts (every connection cut) while one of them runs: the workers and the portal reconnect,
    # the run completes, nothing is lost and nobody is taken for lost.
    deadline = time.monotonic() + TIMEOUT
    while not any(os.path.exists(os.path.join(service.data, "experiments", str(pk), "run-1", "output.txt"))
                  and service.experiment(pk)["state"] == "running" for pk in pks):
        assert time.monotonic() < deadline, service.logs()
        time.sleep(0.2)
    service.postgres.restart()
    for pk in pks:
        row = service.wait_for(pk, ("completed",), "(all twelve complete)")
        assert row["attempts"] == 1, row
    for pk in pks:
        folder = os.path.join(service.data, "experiments", str(pk))
        runs = sorted(n for n in os.listdir(folder) if n.startswith("run-"))
        assert runs == ["run-1"], runs
        recordings = [name for _, _, names in os.walk(os.path.join(folder, "run-1", "results")) for name in names
                      if name.endswith(".mcap")]
        assert len(recordings) == 1, recordings
        reports = [json.load(open(os.path.join(d, "run.json"))) for d, _, names in
                   os.walk(os.path.join(folder, "run-1", "results")) if "run.json" in names]
        assert [r["outcome"] for r in reports] == ["completed"], reports
    # Each job done once, and both hosts did some of them.
    service.wait_until_idle()
    done = dict(((host, kind), n) for host, kind, n in service.query(
        "SELECT host, kind, SUM(jobs_done) FROM robotarium_portal_worker GROUP BY host, kind"))
    assert sum(n for (_, kind), n in done.items() if kind == "runs") == 12, done
    assert sum(n for (_, kind), n in done.items() if kind == "verify") == 12, done
    assert all(sum(n for (h, _), n in done.items() if h == host) > 0 for host in (socket.gethostname(), SECOND_HOST)), done
    assert lost_workers(service) == 0, service.logs()   # (the logs: where its beats stopped, and why)
    assert all(w.process.poll() is None for w in service.workers.values())
    assert 'id="state">completed<' in service.page(pks[-1])   # the portal answers after the restart too


def _hold(service, title, tmp, hold_in="work"):
    release = service.release_file(title.replace(" ", "-"))
    pk = service.submit([{"title": title, "robots": 2, "script": HOLD.format(release=release, hold_in=hold_in)}])[0]
    return pk, release


def _restart(service, name):
    del service.workers[name]
    service.start_worker(name)


def test_a_worker_killed_mid_run_fails_that_run_only_and_one_killed_mid_verification_is_verified_again(service, tmp_path):
    # Mid-run: the holding script runs; its worker (machine) is killed outright.
    pk, release = _hold(service, "lost mid-run", str(tmp_path))
    service.wait_for(pk, ("running",))
    deadline = time.monotonic() + TIMEOUT
    while not os.path.exists(os.path.join(service.data, "experiments", str(pk), "run-1", "output.txt")):
        assert time.monotonic() < deadline
        time.sleep(0.2)
    killed, slot = service.worker_of(pk), service.experiment(pk)["worker"]   # (a failed run holds no worker)
    service.workers[killed].kill()
    row = service.wait_for(pk, ("failed", "completed"), "(found lost)")
    assert row["state"] == "failed" and "the testbed was lost" in row["detail"], row
    assert row["attempts"] == 1 and row["results"], row   # what was recorded so far is attached
    assert os.path.isdir(os.path.join(service.data, "experiments", str(pk), row["results"]))
    assert "the testbed was lost" in service.page(pk) and 'id="state">failed<' in service.page(pk)
    lost = service.postgres.query("SELECT state FROM robotarium_portal_worker WHERE id = %s", slot)
    assert lost == [("lost",)]
    open(release, "w").close()
    assert service.experiment(pk)["state"] == "failed"   # stays said; nothing runs it again
    _restart(service, killed)

    # Mid-verification: the holding script is being verified; its worker is killed outright; the other
    # verifies it again, and it runs once, to completion.
    pk, release = _hold(service, "lost mid-verification", str(tmp_path), hold_in="verify")
    service.wait_for(pk, ("verifying",))
    deadline = time.monotonic() + TIMEOUT
    while not os.path.exists(os.path.join(service.data, "experiments", str(pk), "verification-output.txt")):
        assert time.monotonic() < deadline
        time.sleep(0.2)
    killed = service.worker_of(pk)
    service.workers[killed].kill()
    deadline = time.monotonic() + TIMEOUT
    while "was lost" not in service.experiment(pk)["detail"]:   # handed out again, and its page says why
        assert time.monotonic() < deadline, "%s\n%s" % (service.experiment(pk), service.logs())
        time.sleep(0.3)
    assert service.experiment(pk)["state"] in ("submitted", "verifying")
    _restart(service, killed)
    open(release, "w").close()
    row = service.wait_for(pk, ("completed",), "(after its verification again)")
    assert row["attempts"] == 1, row


def lost_workers(service):
    return service.query("SELECT COUNT(*) FROM robotarium_portal_worker WHERE state = 'lost'")[0][0]
