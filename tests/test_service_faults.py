"""What the service soak (`./robotarium bench soak --service`) found, on the service's real stack: PostgreSQL of
the test's own, the portal (`./robotarium serve --database ... --jobs 0`) and one `./robotarium worker` on this
machine (devtools.service, as tests/test_service.py starts them; no second host here).

- A 2.x script is verified and then run in real time on the simulator's 2.x model, not hardware-like (which
  models the guide's API only, and the simulator refuses for a 2.x script): it completes, and its page says
  how it ran. A guide script still runs hardware-like.
- A verification that a worker took off the queue but had not begun when it was killed outright (SIGKILL to
  everything it started) is handed out again once the worker is found lost, not after django-q2's `retry`
  (1800 s).

No timing assertions: every wait is for a state, with a generous deadline and the logs on failure.
"""
import html
import json
import os
import shutil
import tempfile
import time

import pytest

from devtools.postgres import PostgreSQL, server_binaries
from devtools.rosutil import processes_with_env
from devtools.service import HOLD, SHORT, TIMEOUT, Service

pytestmark = pytest.mark.e2e

# A 2.x script (r.debug(), the drive-on phase): a few steps, its numpy seeded.
RPS2_SHORT = """import numpy as np
import rps.robotarium as robotarium
np.random.seed(3)
N = 2
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=False,
                          initial_conditions=np.array([[-0.4, 0.4], [0.0, 0.0], [0.0, 0.0]]))
for k in range(30):
    r.get_poses()
    r.set_velocities(np.arange(N), np.vstack([np.zeros(N), 0.5 * np.ones(N)]))
    r.step()
r.debug()
"""


@pytest.fixture(scope="module")
def service():
    if server_binaries() is None:
        pytest.skip("no PostgreSQL server here (/usr/lib/postgresql/*/bin) and it could not be installed")
    folder = tempfile.mkdtemp(prefix="robotarium-service-faults-")
    service = Service(folder)
    try:
        service.postgres = PostgreSQL()
        service.start_portal()
        service.start_worker("here")
        yield service
    finally:
        service.close()
        shutil.rmtree(folder, ignore_errors=True)
    assert processes_with_env("ROBOTARIUM_PORTAL_DATA", service.data) == {}


def run_records(service, pk):
    folder = os.path.join(service.data, "experiments", str(pk), "run-1", "results")
    return [json.load(open(os.path.join(d, "run.json"))) for d, _, names in os.walk(folder) if "run.json" in names]


def test_a_2x_script_runs_in_real_time_on_the_2x_model_and_its_page_says_so(service):
    (pk,) = service.submit([{"title": "a 2.x script", "robots": 2, "script": RPS2_SHORT}])
    row = service.wait_for(pk, ("completed", "failed", "rejected"), "(the 2.x script)")
    assert row["state"] == "completed" and row["attempts"] == 1, row
    (verdict,) = service.query("SELECT verification FROM robotarium_portal_experiment WHERE id = %s", pk)[0]
    assert verdict["api"] == "2", verdict   # what its verification ran it with
    (record,) = run_records(service, pk)
    assert record["outcome"] == "completed" and record["api"] == "2", record
    assert record["real_time"] is True and record["hardware"] is False, record
    said = "It ran in real time on the simulator's 2.x model, not hardware-like"
    assert said in row["detail"], row
    page = html.unescape(service.page(pk))
    assert 'id="state">completed<' in page and said in page
    assert 'id="video"' in page, page   # its results as any run's: the video, the files
    # The live view's feed followed it (poses of both robots), and its owner's mail says how it ran.
    with open(os.path.join(service.data, "experiments", str(pk), "run-1", "live.jsonl")) as f:
        poses = [line for line in map(json.loads, f) if "x" in line]
    assert poses and all(len(p["x"]) == 2 for p in poses), poses[:3]
    mails = []
    for folder, _, names in os.walk(os.path.join(service.data, "mail")):
        mails += [open(os.path.join(folder, name), errors="replace").read() for name in names]
    assert any("has completed" in m and "a 2.x script" in m and said in " ".join(m.split()) for m in mails), mails


def test_a_verification_taken_by_a_worker_killed_before_it_began_is_verified_again_at_once(service, tmp_path):
    # The worker's one verification slot holds A (its script waits for its release file while verified);
    # B, another person's, is submitted meanwhile: the slot's cluster takes B's job off the queue (its lock)
    # while A's verification goes on.
    release = service.release_file("a")
    (a,) = service.submit([{"title": "held in verification", "robots": 2, "owner": "a@example.org",
                            "script": HOLD.format(release=release, hold_in="verify")}])
    service.wait_for(a, ("verifying",))
    (b,) = service.submit([{"title": "taken, not begun", "robots": 2, "owner": "b@example.org",
                            "script": SHORT.format(robots=2, steps=10, name="b")}])
    deadline = time.monotonic() + TIMEOUT
    while service.query("SELECT COUNT(*) FROM django_q_ormq WHERE key = 'verify' AND lock > now()")[0][0] < 2:
        assert time.monotonic() < deadline, service.logs()   # A's job and B's, both locked by the cluster
        time.sleep(0.2)
    assert service.experiment(a)["state"] == "verifying" and service.experiment(b)["state"] == "submitted"
    # The worker killed outright (its machine gone); a new one starts. A's script would now finish.
    service.workers.pop("here").kill()
    open(release, "w").close()
    service.start_worker("here")
    # The new worker finds the old one lost: A is verified again (as before) and B, whose job the dead cluster
    # still held locked for django-q2's retry (1800 s), is verified and run now.
    row = service.wait_for(b, ("completed", "failed", "rejected"), "(B: verified once its worker was found lost)")
    assert row["state"] == "completed" and row["attempts"] == 1, row
    (record,) = run_records(service, b)
    assert record["outcome"] == "completed" and record["hardware"] is True, record   # a guide script: hardware-like
    row = service.wait_for(a, ("completed", "failed", "rejected"), "(A: verified again)")
    assert row["state"] == "completed" and row["attempts"] == 1, row
    lost = service.query("SELECT COUNT(DISTINCT pid) FROM robotarium_portal_worker WHERE state = 'lost'")[0][0]
    assert lost == 1   # the killed worker (its two slots), nobody else
