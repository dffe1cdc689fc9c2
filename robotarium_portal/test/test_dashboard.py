"""The guide's dashboard exactly (issue 39): Pending = submitted and not finished, with state and place;
Completed = finished, with the outcome; drafts apart; an honest queue estimate from measured run times;
and the smaller items of the pages: results with unusual names served, no service path shown, too many
files said in words, a Content-Security-Policy, the main file chosen among the files being added."""
import itertools

from django.conf import settings
from django.contrib.auth import get_user_model
from django.core.files.uploadedfile import SimpleUploadedFile
from django.test import Client, override_settings
from django.utils import timezone

from robotarium_portal.models import Experiment, Profile, Worker

_n = itertools.count()


def person():
    email = "dash%d@example.org" % next(_n)
    user = get_user_model().objects.create_user(username=email, email=email)
    Profile.objects.create(user=user, name="D", city="c", state="s", institute="i", reason="r",
                           email_confirmed=True, approved=True)
    client = Client()
    client.force_login(user)
    return user, client


def experiment(owner, state, title, **fields):
    fields.setdefault("estimated_duration", 20)
    return Experiment.objects.create(owner=owner, title=title, number_of_robots=2, main_file="main.py", state=state,
                                     **fields)


def rows_of(page):
    """The titles in the tab's table, in order."""
    import re
    return re.findall(r'<a href="/experiments/\d+/">([^<]+)</a>', page)


def test_the_tabs_hold_what_the_guide_says():
    owner, client = person()
    now = timezone.now()
    for state in Experiment.PENDING:
        experiment(owner, state, "P-" + state, submitted_at=now, queued_at=now)
    for state, detail in ((Experiment.COMPLETED, "Run completed."), (Experiment.FAILED, "Failed: the testbed was lost"),
                          (Experiment.REJECTED, "Rejected by the verification:\ncollisions: 168 times, limit 100"),
                          (Experiment.CANCELLED, "Cancelled by an administrator (a@b) at x.")):
        experiment(owner, state, "C-" + state, detail=detail, finished_at=now)
    experiment(owner, Experiment.SAVED, "Draft")
    pending = client.get("/?tab=pending").content.decode()
    assert sorted(rows_of(pending)) == sorted("P-" + s for s in Experiment.PENDING)
    import re
    assert re.search(r"queued</span> <span class=\"muted\">place \d+ in the queue", pending), pending   # its place
    completed = client.get("/?tab=completed").content.decode()
    assert sorted(rows_of(completed)) == sorted("C-" + s for s in Experiment.DONE)
    for outcome in ("Run completed.", "Failed: the testbed was lost", "collisions: 168 times, limit 100",
                    "Cancelled by an administrator"):
        assert outcome in completed, outcome
    assert rows_of(client.get("/?tab=drafts").content.decode()) == ["Draft"]
    assert "Drafts (1)" in pending and "Pending Experiments (4)" in pending


def test_the_queue_estimate_comes_from_measured_run_times():
    owner, client = person()
    Experiment.objects.filter(state__in=(Experiment.QUEUED, Experiment.RUNNING)).update(state=Experiment.SAVED)
    Worker.objects.filter(state=Worker.ALIVE).update(state=Worker.STOPPED)
    Experiment.objects.update(timings={})   # other tests' runs in this database measured nothing here
    Worker.objects.create(host="h", pid=1, kind=Worker.RUNS, domain=3)
    for k in range(5):   # the last runs took 29 s each, start to results, whatever their 900 s limit
        experiment(owner, Experiment.COMPLETED, "done %d" % k, timings={"run_command": 29.0},
                   finished_at=timezone.now())
    for k in range(6):
        experiment(owner, Experiment.QUEUED, "waiting %d" % k, estimated_duration=900, queued_at=timezone.now())
    page = client.get("/").content.decode()
    assert "Total Experiments in Queue: 6" in page
    assert "starts in about 3 minutes, from the last 5 runs (29 s each on average)" in page, page   # not 90 minutes


def test_results_with_unusual_names_are_served_and_no_name_leaves_the_folder():
    owner, client = person()
    e = experiment(owner, Experiment.COMPLETED, "odd", results="run-1/results/r")
    (e.results_dir / "data").mkdir(parents=True)
    for name in ("a b (1).txt", "ü+ñ#%.csv", ".hidden"):
        (e.results_dir / "data" / name).write_text("saved " + name)
    page = client.get("/experiments/%d/" % e.pk).content.decode()
    from html import escape
    from urllib.parse import quote
    for name in ("a b (1).txt", "ü+ñ#%.csv", ".hidden"):
        url = "/experiments/%d/results/data/%s" % (e.pk, quote(name))
        assert escape(name) in page
        response = client.get(url)
        assert response.status_code == 200 and b"".join(response.streaming_content) == ("saved " + name).encode()
    for bad in ("data/../../../../secret_key", "../r/data/.hidden", "data", "data/x/y"):
        assert client.get("/experiments/%d/results/%s" % (e.pk, bad)).status_code == 404, bad


def test_a_page_never_shows_the_services_folders():
    owner, client = person()
    box = "%s/runs-12/work/" % settings.JOB_BOXES_DIR
    e = experiment(owner, Experiment.FAILED, "paths", detail='Failed: File "%smain.py", line 3 (data in %s/experiments)'
                   % (box, settings.DATA_DIR))
    page = client.get("/experiments/%d/" % e.pk).content.decode()
    assert 'File &quot;main.py&quot;, line 3' in page
    assert str(settings.JOB_BOXES_DIR) not in page and str(settings.DATA_DIR) not in page


@override_settings(PORTAL_MAX_FILES=20)
def test_too_many_files_are_said_in_words_never_a_bare_400():
    _, client = person()
    data = {"title": "many", "estimated_duration": 10, "number_of_robots": 1, "action": "save"}
    many = client.post("/experiments/new/", dict(data, upload=[SimpleUploadedFile("f%d.py" % k, b"x = 1\n") for k in range(101)]))
    assert b"Too many files: 101; an experiment has at most 20." in many.content
    too_many = client.post("/experiments/new/", dict(data, upload=[SimpleUploadedFile("f%d.py" % k, b"x = 1\n")
                                                                   for k in range(1001)]))
    assert too_many.status_code == 400 and b"at most 20 files" in too_many.content


def test_pages_carry_a_content_security_policy_and_the_main_file_is_chosen_among_the_files():
    _, client = person()
    response = client.get("/experiments/new/")
    policy = response["Content-Security-Policy"]
    assert "default-src 'self'" in policy and "object-src 'none'" in policy and "frame-ancestors 'none'" in policy
    page = response.content.decode()
    assert '<select name="main_file" id="id_main_file">' in page
