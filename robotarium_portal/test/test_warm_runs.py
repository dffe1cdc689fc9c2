"""A run slot's warm testbed records every run into one folder of the slot's (jobs.warm_bags); a run's folder moves
to its experiment's results when its job ends. What a job cut short outright left there (its worker killed mid-run)
goes to that job's results before the slot's next run, where a testbed of the job's own would have left it, and
nothing else stays for the next job (jobs.rescue_warm_recordings). Real files and the test database; the runs
themselves: tests/test_portal_submit.py."""
import itertools
import json

from django.contrib.auth import get_user_model

from robotarium_portal import jobs
from robotarium_portal.models import Experiment

_users = itertools.count()


def experiment(attempts):
    n = next(_users)
    owner = get_user_model().objects.create_user(username="warm%d@example.org" % n, email="warm%d@example.org" % n)
    return Experiment.objects.create(owner=owner, title="t", estimated_duration=10, number_of_robots=2,
                                     main_file="main.py", state=Experiment.RUNNING, attempts=attempts)


def test_a_recording_a_job_cut_short_left_goes_to_its_results_and_nothing_stays_for_the_next(monkeypatch):
    monkeypatch.setenv("ROBOTARIUM_PORTAL_RUN_DOMAIN", "warm-runs-test")   # (a folder name here, no DDS)
    folder = jobs.warm_bags()
    assert folder.name == "warm-runs-test" and folder.parent.parent == jobs.settings.DATA_DIR
    cut_short, nxt = experiment(attempts=2), experiment(attempts=1)
    results = jobs.run_folder(cut_short) / "results"
    results.mkdir(parents=True)
    left = folder / "main_20261201-010203"
    left.mkdir(parents=True)
    (left / "main_20261201-010203_0.mcap").write_bytes(b"\x89MCAP0\r\n")
    (folder / "stray.txt").write_text("not a run")
    (folder / jobs.WARM_JOB).write_text(json.dumps({"experiment": cut_short.pk, "attempt": 2}))

    jobs.rescue_warm_recordings(nxt)

    assert (results / left.name / "main_20261201-010203_0.mcap").read_bytes() == b"\x89MCAP0\r\n"
    assert sorted(p.name for p in folder.iterdir()) == [jobs.WARM_JOB]
    assert json.loads((folder / jobs.WARM_JOB).read_text()) == {"experiment": nxt.pk, "attempt": 1}

    # A leftover whose job is unknown (no record of it, or its experiment gone) is removed, not handed to anyone.
    (folder / "orphan").mkdir()
    (folder / jobs.WARM_JOB).write_text("{not json")
    jobs.rescue_warm_recordings(None)
    assert sorted(p.name for p in folder.iterdir()) == [jobs.WARM_JOB]
    assert not (jobs.run_folder(nxt) / "results").exists()
