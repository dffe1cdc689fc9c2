"""The portal's security rules and operator's view through Django's test client: the real views, forms,
database (SQLite in a folder of its own, conftest.py) and mail (Django's test outbox).

Another user's experiment, results, files and settings answer 404; only administrators approve accounts
and write return messages; an unconfirmed or unapproved account cannot submit; file names that could
leave the folder are refused; upload limits say so; user text stays text everywhere; the pending cap; a
mail server that is down costs no account; the admin pages of the workers and the queue, cancelling,
and a watcher finding a silent worker lost."""
import os
import re
import socket
import time

import pytest
from django.core import mail
from django.core.files.uploadedfile import SimpleUploadedFile
from django.http import Http404
from django.test import Client, override_settings
from django_q.models import OrmQ

from robotarium_portal import files
from robotarium_portal.models import Experiment, ExperimentFile, Profile, ReturnMessage

PASSWORD = "a-long-Passphrase-7"
SCRIPT = "import numpy as np\nprint('hello')\n"


_count = [0]


def make_user(approved=True, confirmed=True, staff=False):
    from django.contrib.auth import get_user_model
    _count[0] += 1
    email = "user%d-%d@example.org" % (os.getpid(), _count[0])
    user = get_user_model().objects.create_user(username=email, email=email, password=PASSWORD, is_staff=staff)
    Profile.objects.create(user=user, name="User %d" % _count[0], city="Atlanta", state="GA", institute="GT",
                           reason="class", email_confirmed=confirmed, approved=approved)
    return user


def client_for(user):
    client = Client()
    client.force_login(user)
    return client


def logs_in(client, username, password):
    """The log-in form, as a person posts it (through the log-in limit); True when it let them in."""
    return client.post("/login/", {"username": username, "password": password}).status_code == 302


def experiment_of(user, title="Swap", files_=None, results=None):
    experiment = Experiment.objects.create(owner=user, title=title, estimated_duration=30, number_of_robots=2,
                                           main_file="main.py")
    for name, text in (files_ or {"main.py": SCRIPT}).items():
        experiment.files_dir.mkdir(parents=True, exist_ok=True)
        (experiment.files_dir / name).write_text(text)
        ExperimentFile.objects.create(experiment=experiment, name=name, size=len(text))
    if results:
        folder = experiment.folder / "run-1" / "results" / "run"
        (folder / "data").mkdir(parents=True)
        for name, text in results.items():
            (folder / name).write_text(text)
        experiment.results = "run-1/results/run"
        experiment.state = Experiment.COMPLETED
        experiment.save()
    return experiment


def post_form(client, url, action="save", uploads=(), **fields):
    data = {"title": "Swap", "description": "two robots", "estimated_duration": 30, "number_of_robots": 2,
            "action": action, **fields}
    if uploads:
        data["upload"] = list(uploads)
    return client.post(url, data, follow=True)


# --- a user sees only their own experiments ----------------------------------------------------------------

def test_another_users_experiment_results_files_and_settings_answer_404():
    owner, other = make_user(), make_user()
    experiment = experiment_of(owner, results={"log.txt": "the script's prints", "data/out.txt": "saved"})
    urls = ["/experiments/%d/" % experiment.pk, "/experiments/%d/settings.json" % experiment.pk,
            "/experiments/%d/files/main.py" % experiment.pk, "/experiments/%d/results/log.txt" % experiment.pk,
            "/experiments/%d/results/data/out.txt" % experiment.pk]
    mine, theirs = client_for(owner), client_for(other)
    for url in urls:
        assert mine.get(url).status_code == 200, url
        assert theirs.get(url).status_code == 404, url
    assert b"the script's prints" in b"".join(mine.get(urls[3]).streaming_content)
    # nor can they delete or change it
    assert theirs.post("/experiments/%d/delete/" % experiment.pk).status_code == 404
    assert post_form(theirs, urls[0], title="taken").status_code == 404
    experiment.refresh_from_db()
    assert experiment.title == "Swap"
    # the dashboard lists only one's own
    assert b"Swap" in mine.get("/?tab=completed").content and b"Swap" not in theirs.get("/?tab=completed").content
    assert Client().get(urls[0]).status_code == 302   # nobody logged in: to the log-in page


# --- a run that behaved otherwise than its verification is flagged (issue 36) --------------------------------

def test_a_run_the_safety_layer_changed_where_verification_needed_nothing_is_flagged_with_both_figures():
    """A script that stays still while verified and drives robots head-on in its run: its run's safety
    layer changed arrays a verification's certificate would have changed too (run.json
    ideal_interventions, measured by the safety node); its verification's certificate none. The page
    says so at the top with both figures; a clean run is not flagged."""
    import json
    owner = make_user()
    flagged = experiment_of(owner, results={"run.json": json.dumps({"outcome": "completed", "safety_interventions": 90,
                                                                    "ideal_interventions": 61})})
    flagged.verification = {"verdict": "accepted", "counts": {"safety_interventions": 0}}
    flagged.save()
    assert flagged.differs_from_verification() == (61, 0)
    page = client_for(owner).get("/experiments/%d/" % flagged.pk).content.decode()
    assert 'id="differs"' in page and "changed 61 command arrays" in page and "would have changed 0" in page
    # wider margins alone (real time, hardware-like) are no difference; nor a verification that changed too
    clean = experiment_of(owner, results={"run.json": json.dumps({"outcome": "completed", "safety_interventions": 40,
                                                                  "ideal_interventions": 0})})
    clean.verification = {"verdict": "accepted", "counts": {"safety_interventions": 0}}
    clean.save()
    assert clean.differs_from_verification() is None
    assert 'id="differs"' not in client_for(owner).get("/experiments/%d/" % clean.pk).content.decode()
    flagged.verification = {"verdict": "accepted", "counts": {"safety_interventions": 12}}
    flagged.save()
    assert flagged.differs_from_verification() is None


# --- only administrators approve accounts and write return messages ------------------------------------------

def test_only_administrators_approve_accounts_and_write_return_messages():
    waiting = make_user(approved=False)
    owner, admin = make_user(), make_user(staff=True)
    experiment = experiment_of(owner)
    user_client = client_for(owner)
    user_client.post("/staff/approvals/%d/" % waiting.profile.pk)
    assert user_client.get("/staff/approvals/").status_code == 302   # to the admin's log-in
    user_client.post("/experiments/%d/message/" % experiment.pk, {"text": "I approve of myself"})
    waiting.profile.refresh_from_db()
    assert not waiting.profile.approved
    assert not ReturnMessage.objects.filter(experiment=experiment).exists()

    admin_client = client_for(admin)
    listing = admin_client.get("/staff/approvals/").content.decode()
    assert waiting.email in listing and owner.email not in listing   # only those waiting
    mail.outbox.clear()
    admin_client.post("/staff/approvals/%d/" % waiting.profile.pk)
    assert [m.to for m in mail.outbox] == [[waiting.email]] and "approved" in mail.outbox[0].subject
    admin_client.post("/experiments/%d/message/" % experiment.pk, {"text": "Nice swap; slow down near the wall."})
    waiting.profile.refresh_from_db()
    assert waiting.profile.approved and waiting.profile.approved_by == admin
    assert "Nice swap; slow down near the wall." in user_client.get("/experiments/%d/" % experiment.pk).content.decode()


# --- an unconfirmed or unapproved account cannot submit -------------------------------------------------------

def test_sign_up_confirm_approve_then_submit():
    make_user(staff=True)   # an administrator to tell
    mail.outbox.clear()
    client = Client()
    response = client.post("/signup/", {"email": "Ada@Example.org", "password": PASSWORD, "confirmation": PASSWORD,
                                        "name": "Ada", "city": "Atlanta", "state": "GA", "institute": "GT",
                                        "reason": "swarm lab"})
    assert b"Thank you for signing up" in response.content
    (message,) = mail.outbox
    assert message.to == ["ada@example.org"]
    link = re.search(r"https?://[^/\s]+(/confirm/\S+/)", message.body).group(1)

    assert logs_in(client, "ada@example.org", PASSWORD)
    response = post_form(client, "/experiments/new/", action="submit",
                         uploads=[SimpleUploadedFile("main.py", SCRIPT.encode())])
    experiment = Experiment.objects.get(owner__username="ada@example.org")
    assert experiment.state == Experiment.SAVED and b"Confirm your email address first" in response.content

    mail.outbox.clear()
    assert client.get(link).status_code == 200
    assert Profile.objects.get(user__username="ada@example.org").email_confirmed
    assert "ada@example.org waits for approval" in mail.outbox[0].subject   # the administrators hear of it
    assert client.get(link).status_code == 400   # a used link is void
    response = post_form(client, "/experiments/%d/" % experiment.pk, action="submit")
    experiment.refresh_from_db()
    assert experiment.state == Experiment.SAVED and b"waits for an administrator" in response.content

    Profile.objects.filter(user__username="ada@example.org").update(approved=True)
    before = OrmQ.objects.filter(key="verify").count()
    post_form(client, "/experiments/%d/" % experiment.pk, action="submit")
    experiment.refresh_from_db()
    assert experiment.state == Experiment.SUBMITTED and experiment.main_file == "main.py"
    assert OrmQ.objects.filter(key="verify").count() == before + 1   # its verification job is queued


def test_a_submission_and_its_verification_job_are_one_transaction():
    """Submitted and its job, or neither: put on the queue after the commit, a database lost in between left
    the experiment submitted with no job to verify it, for ever."""
    from django.db import transaction

    from robotarium_portal.views_experiments import submit

    class DatabaseLost(Exception):
        pass
    user = make_user()
    experiment = experiment_of(user)
    before = OrmQ.objects.filter(key="verify").count()
    with pytest.raises(DatabaseLost):
        with transaction.atomic():
            assert submit(user, experiment) is None
            assert OrmQ.objects.filter(key="verify").count() == before + 1   # written with the submission
            raise DatabaseLost()   # lost before the commit
    experiment.refresh_from_db()
    assert experiment.state == Experiment.SAVED and OrmQ.objects.filter(key="verify").count() == before


def test_a_mail_server_that_is_down_costs_no_account_and_no_page():
    with socket.socket() as s:   # a port nobody listens on: the connection is refused
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    down = {"default": {"BACKEND": "django.core.mail.backends.smtp.EmailBackend",
                        "OPTIONS": {"host": "127.0.0.1", "port": port, "timeout": 5}}}
    with override_settings(MAILERS=down):
        response = Client().post("/signup/", {"email": "eve@example.org", "password": PASSWORD,
                                              "confirmation": PASSWORD, "name": "Eve", "city": "Atlanta",
                                              "state": "GA", "institute": "GT", "reason": "class"})
    assert response.status_code == 200 and b"could not be sent just now" in response.content
    assert Profile.objects.filter(user__username="eve@example.org").exists()


# --- uploaded files stay in the experiment's folder, within limits ----------------------------------------------

@pytest.mark.parametrize("name", ["../escape.py", "/etc/passwd", "..", ".bashrc", "a b.py", "semi;colon.py",
                                  "back\\slash.py", "ünï.py", "x" * 101 + ".py", "new\nline.py"])
def test_file_names_that_could_leave_the_folder_are_refused(name):
    assert files.name_problem(name)
    with pytest.raises(Http404):
        files.inside("/srv/data", name)


def test_odd_upload_names_are_refused_and_nothing_is_written_outside(portal):
    user = make_user()
    client = client_for(user)
    before = set(os.listdir(portal)) | {"experiments"}
    for name in ("a b.py", "semi;colon.py", ".bashrc", "ünï.py"):
        response = post_form(client, "/experiments/new/", uploads=[SimpleUploadedFile(name, b"print(1)\n")])
        assert b"is not allowed" in response.content, name
    assert not Experiment.objects.filter(owner=user).exists()
    # a path is cut to its last part by Django's parser: it lands inside, as escape.py
    post_form(client, "/experiments/new/", uploads=[SimpleUploadedFile("../../escape.py", b"print(1)\n")])
    experiment = Experiment.objects.get(owner=user)
    assert experiment.file_names() == ["escape.py"] and (experiment.files_dir / "escape.py").exists()
    assert set(os.listdir(portal)) == before
    # nor can a download name leave the folder (the secret key is two levels up)
    assert client.get("/experiments/%d/files/../../../secret_key" % experiment.pk).status_code == 404
    completed = experiment_of(user, results={"log.txt": "x"})
    # the run folder is DATA/experiments/<id>/run-1/results/run: five levels below DATA
    for name in ("../../../../../secret_key", "data/../../../../../../secret_key",
                 "%2e%2e/%2e%2e/%2e%2e/%2e%2e/%2e%2e/secret_key"):
        assert client.get("/experiments/%d/results/%s" % (completed.pk, name)).status_code == 404, name


@override_settings(PORTAL_MAX_FILES=2, PORTAL_MAX_FILE_BYTES=1000)
def test_upload_count_and_size_limits_say_so():
    user = make_user()
    client = client_for(user)
    three = [SimpleUploadedFile("f%d.py" % k, b"x = 1\n") for k in range(3)]
    response = post_form(client, "/experiments/new/", uploads=three, main_file="f0.py")
    assert b"Too many files: 3; an experiment has at most 2." in response.content
    response = post_form(client, "/experiments/new/", uploads=[SimpleUploadedFile("big.py", b"#" * 2000)])
    assert b"Too large (at most" in response.content and b"big.py" in response.content
    assert not Experiment.objects.filter(owner=user).exists()
    two = [SimpleUploadedFile("f%d.py" % k, b"x = 1\n") for k in range(2)]
    post_form(client, "/experiments/new/", uploads=two, main_file="f0.py")
    assert Experiment.objects.get(owner=user).file_names() == ["f0.py", "f1.py"]


# --- user text is text everywhere ----------------------------------------------------------------------------

def test_user_written_text_is_escaped_everywhere():
    attack = "<script>alert('x')</script>"
    user = make_user(approved=False)
    Profile.objects.filter(user=user).update(name=attack, reason=attack)
    experiment = experiment_of(user, title=attack)
    Experiment.objects.filter(pk=experiment.pk).update(description=attack, state=Experiment.QUEUED,
                                                       queued_at=experiment.created, detail=attack)
    ReturnMessage.objects.create(experiment=experiment, text=attack)
    admin = client_for(make_user(staff=True))
    pages = [client_for(user).get("/"), client_for(user).get("/experiments/%d/" % experiment.pk),
             client_for(user).get("/queue/"), admin.get("/staff/approvals/")]
    for response in pages:
        html = response.content.decode()
        assert "&lt;script&gt;alert(" in html, response.request["PATH_INFO"]
        assert attack not in html, response.request["PATH_INFO"]
    # an uploaded .html is shown as text, never as this site's page
    experiment_of(user, files_={"main.py": SCRIPT, "page.html": attack})
    response = client_for(user).get("/experiments/%d/files/page.html" % (experiment.pk + 1))
    assert response["Content-Type"].startswith("text/plain")


# --- at most PORTAL_MAX_PENDING pending experiments per user ---------------------------------------------------

@override_settings(PORTAL_MAX_PENDING=2)
def test_a_user_has_at_most_the_configured_pending_experiments():
    user = make_user()
    client = client_for(user)
    for k in range(3):
        response = post_form(client, "/experiments/new/", action="submit", title="try %d" % k,
                             uploads=[SimpleUploadedFile("main.py", SCRIPT.encode())])
    states = dict(Experiment.objects.filter(owner=user).values_list("title", "state"))
    assert states == {"try 0": "submitted", "try 1": "submitted", "try 2": "saved"}
    assert b"You have 2 experiments pending, the most one may have" in response.content
    # one finishes: the saved one may go
    Experiment.objects.filter(owner=user, title="try 0").update(state=Experiment.COMPLETED)
    saved = Experiment.objects.get(owner=user, title="try 2")
    post_form(client, "/experiments/%d/" % saved.pk, action="submit", title="try 2")
    saved.refresh_from_db()
    assert saved.state == Experiment.SUBMITTED


def test_settings_json_has_the_guide_fields():
    user = make_user()
    experiment = experiment_of(user, files_={"main.py": SCRIPT, "helper.py": "X = 1\n"})
    response = client_for(user).get("/experiments/%d/settings.json" % experiment.pk)
    assert response.json() == {"title": "Swap", "description": "", "estimated_duration": 30, "number_of_robots": 2,
                               "main_file": "main.py", "files": ["helper.py", "main.py"]}
    assert "attachment" in response["Content-Disposition"]


# --- the operator's view: workers, the queue, cancelling; a lost worker --------------------------------------

def make_administrator():
    """As ./robotarium serve --create-admin makes them: staff and superuser."""
    user = make_user(staff=True)
    user.is_superuser = True
    user.save()
    return user


def make_worker(kind="runs", host="lab-pc-2"):
    from robotarium_portal.models import Worker
    return Worker.objects.create(host=host, pid=4242, kind=kind, domain=17, current_job="", jobs_done=3)


def test_the_admin_pages_list_the_workers_and_the_queue():
    admin_client = client_for(make_administrator())
    worker = make_worker()
    experiment = experiment_of(make_user(), title="Held")
    experiment.state, experiment.worker = Experiment.RUNNING, worker
    experiment.save()
    worker.current_job = "run #%d" % experiment.pk
    worker.save()
    page = admin_client.get("/admin/robotarium_portal/worker/").content.decode()
    for column in ("Host", "Alive since", "Current job", "Jobs done", "Last heartbeat"):
        assert column in page, column
    assert "lab-pc-2" in page and "run #%d" % experiment.pk in page
    queue = admin_client.get("/admin/robotarium_portal/experiment/?state__exact=running").content.decode()
    assert "Held" in queue and "lab-pc-2" in queue   # the experiment with the worker that holds it
    assert client_for(make_user()).get("/admin/robotarium_portal/worker/").status_code == 302   # staff only


def test_a_jobs_text_with_nul_bytes_is_stored_not_a_database_error():
    """A run's output with NUL bytes (a file written on past its truncation) failed the run's whole job
    with PostgreSQL's DataError in a service test; the experiment keeps its text, NUL shown as U+FFFD."""
    experiment = experiment_of(make_user(), title="Nul")
    experiment.detail = "Failed: the script raised ValueError\x00\x00 at step 3"
    experiment.verification = {"rules": [{"rule": "collisions\x00", "count": 1}], "log": ["a\x00b"]}
    experiment.save()
    experiment.refresh_from_db()
    assert experiment.detail == "Failed: the script raised ValueError\ufffd\ufffd at step 3"
    assert experiment.verification == {"rules": [{"rule": "collisions\ufffd", "count": 1}], "log": ["a\ufffdb"]}


def test_an_administrator_cancels_a_queued_or_running_experiment_and_its_page_says_so():
    from robotarium_portal import jobs
    admin_user = make_administrator()
    owner = make_user()
    queued, running, completed = (experiment_of(owner, title=t) for t in ("Waiting", "Going", "Done"))
    Experiment.objects.filter(pk=queued.pk).update(state=Experiment.QUEUED, queued_at=timezone_now())
    Experiment.objects.filter(pk=running.pk).update(state=Experiment.RUNNING, attempts=1)
    Experiment.objects.filter(pk=completed.pk).update(state=Experiment.COMPLETED, detail="Run completed.")
    url = "/admin/robotarium_portal/experiment/"
    data = {"action": "cancel", "_selected_action": [queued.pk, running.pk, completed.pk]}
    client_for(owner).post(url, data)   # not an administrator: nothing happens
    assert Experiment.objects.get(pk=queued.pk).state == Experiment.QUEUED
    response = client_for(admin_user).post(url, data, follow=True)
    assert b"1 of the selected experiments were neither queued nor running" in response.content
    for experiment in (queued, running):
        experiment.refresh_from_db()
        assert experiment.state == Experiment.CANCELLED and "Cancelled by an administrator" in experiment.detail
        page = client_for(owner).get("/experiments/%d/" % experiment.pk).content.decode()
        assert "Cancelled by an administrator" in page and 'id="state">cancelled<' in page
    assert Experiment.objects.get(pk=completed.pk).state == Experiment.COMPLETED   # left as it was
    # The stopped run's job ends later: its outcome does not overwrite the cancellation, its results are kept.
    running.folder.mkdir(parents=True, exist_ok=True)
    jobs._finish(running, Experiment.COMPLETED, "Run completed.", results="run-1/results/x", run_outcome="completed")
    running.refresh_from_db()
    assert running.state == Experiment.CANCELLED and running.results == "run-1/results/x"
    assert "Cancelled by an administrator" in running.detail


def test_a_jobs_environment_carries_no_database_url(monkeypatch):
    from robotarium_portal import jobs
    monkeypatch.setenv("ROBOTARIUM_PORTAL_DATABASE", "postgresql://robotarium:s3cret-pw@db.example.org/robotarium")
    env = jobs.job_env("ROBOTARIUM_PORTAL_RUN_DOMAIN")
    assert not any("s3cret-pw" in value for value in env.values())


def timezone_now():
    from django.utils import timezone
    return timezone.now()


def test_a_worker_whose_beats_stop_is_found_lost_its_verification_again_its_run_failed():
    from robotarium_portal.models import Worker
    from robotarium_portal.supervisor import Watcher
    owner = make_user()
    Worker.objects.filter(state=Worker.ALIVE).update(state=Worker.STOPPED)   # other tests' slots: not watched
    silent, beating = make_worker(kind="verify"), make_worker(kind="runs", host="lab-pc-3")
    verifying, running = experiment_of(owner, title="V"), experiment_of(owner, title="R")
    Experiment.objects.filter(pk=verifying.pk).update(state=Experiment.VERIFYING, worker=silent)
    Experiment.objects.filter(pk=running.pk).update(state=Experiment.RUNNING, worker=silent, attempts=1)
    recorded = running.folder / "run-1" / "results" / "2026-01-01-run"
    recorded.mkdir(parents=True)
    (recorded / "partial.mcap").write_text("so far")
    watcher = Watcher()
    verify_jobs = OrmQ.objects.filter(key="verify").count()
    with override_settings(WORKER_LOST_AFTER=0.3):
        watcher.sweep()
        time.sleep(0.4)
        Worker.objects.filter(pk=beating.pk).update(beats=beating.beats + 1)   # this one beats, that one not
        watcher.sweep()
    assert Worker.objects.get(pk=silent.pk).state == Worker.LOST
    assert Worker.objects.get(pk=beating.pk).state == Worker.ALIVE
    verifying.refresh_from_db()
    assert verifying.state == Experiment.SUBMITTED and "was lost" in verifying.detail
    assert OrmQ.objects.filter(key="verify").count() == verify_jobs + 1   # verified again
    running.refresh_from_db()
    assert running.state == Experiment.FAILED and "the testbed was lost" in running.detail
    assert running.results == "run-1/results/2026-01-01-run"   # what was recorded so far, on its page
    page = client_for(owner).get("/experiments/%d/" % running.pk).content.decode()
    assert "the testbed was lost" in page and "partial.mcap" in page
    watcher.forget()   # a watcher that lost the database starts its watch afresh: nobody is lost at once
    with override_settings(WORKER_LOST_AFTER=0.3):
        watcher.sweep()
    assert Worker.objects.get(pk=beating.pk).state == Worker.ALIVE


def test_the_jobs_a_lost_slot_took_off_the_queue_go_back_at_once_a_live_slots_keep_their_lock(monkeypatch):
    """The broker keeps who took each job (TaskHold, with its lock); the watch that finds a slot lost unlocks
    that slot's jobs (begun or not) at once, and leaves the lock of a job a live slot took."""
    from django_q.brokers import get_broker

    from robotarium_portal import jobs
    from robotarium_portal.broker import HoldingORM
    from robotarium_portal.models import TaskHold, Worker
    from robotarium_portal.supervisor import Watcher
    OrmQ.objects.filter(key="verify").delete()
    Worker.objects.filter(state=Worker.ALIVE).update(state=Worker.STOPPED)   # other tests' slots: not watched
    silent, beating = make_worker(kind="verify"), make_worker(kind="verify", host="lab-pc-3")
    owner = make_user()
    for title in ("taken by the silent slot", "taken by the beating slot"):
        jobs.enqueue_verification(experiment_of(owner, title=title))
    broker = get_broker("verify")
    assert isinstance(broker, HoldingORM)   # the service's broker (settings' broker_class)
    time.sleep(0.01)   # (a job is there once its enqueue time has passed)
    taken = {}
    for slot in (silent, beating):
        monkeypatch.setenv("ROBOTARIUM_WORKER_ID", str(slot.pk))
        ((task, _),) = broker.dequeue()
        taken[slot.pk] = task
    monkeypatch.delenv("ROBOTARIUM_WORKER_ID")
    assert dict(TaskHold.objects.values_list("worker", "task")) == taken
    now = timezone_now()
    assert OrmQ.objects.filter(pk__in=taken.values(), lock__gt=now).count() == 2   # both locked for `retry`
    watcher = Watcher()
    with override_settings(WORKER_LOST_AFTER=0.3):
        watcher.sweep()
        time.sleep(0.4)
        Worker.objects.filter(pk=beating.pk).update(beats=beating.beats + 1)
        watcher.sweep()
    assert Worker.objects.get(pk=silent.pk).state == Worker.LOST
    assert OrmQ.objects.get(pk=taken[silent.pk]).lock <= timezone_now()   # back on the queue now
    assert OrmQ.objects.get(pk=taken[beating.pk]).lock > now               # still the live slot's
    assert list(TaskHold.objects.values_list("worker", flat=True)) == [beating.pk]
    OrmQ.objects.filter(pk=taken[beating.pk]).delete()   # done (acknowledged): its hold goes with it
    assert not TaskHold.objects.exists()


@pytest.mark.parametrize("committed", [True, False])
def test_a_job_taken_as_the_database_went_away_goes_back_on_the_queue(monkeypatch, committed):
    """The connection cut while the broker takes a job (a database restart): whether the take was committed
    is not known to the slot, whose pusher starts again without the job. A committed take would keep the job
    locked for `retry` (35 minutes for a run) by a live slot that never runs it; it goes back on the queue at
    once, and a take that was not committed leaves nothing to give back."""
    from django.db import OperationalError, connection
    from django_q.brokers import get_broker

    from robotarium_portal import jobs
    from robotarium_portal.models import TaskHold, Worker
    OrmQ.objects.filter(key="verify").delete()
    slot = make_worker(kind="verify")
    jobs.enqueue_verification(experiment_of(make_user(), title="taken as the database went away"))
    broker = get_broker("verify")
    time.sleep(0.01)   # (a job is there once its enqueue time has passed)
    monkeypatch.setenv("ROBOTARIUM_WORKER_ID", str(slot.pk))
    cut = OperationalError("server closed the connection unexpectedly")
    if committed:
        commit, cuts = connection.commit, [cut]

        def commit_then_cut():   # (once: the database is back for the give-back)
            commit()
            if cuts:
                raise cuts.pop()
        monkeypatch.setattr(connection, "commit", commit_then_cut)
    else:
        def cut_before_commit(*args, **kwargs):
            raise cut
        monkeypatch.setattr(TaskHold.objects, "update_or_create", cut_before_commit)
    began = time.monotonic()
    with pytest.raises(OperationalError):
        broker.dequeue()
    assert time.monotonic() - began < 30   # given back at once, not after database_retry's patience
    monkeypatch.undo()
    (job,) = OrmQ.objects.filter(key="verify")
    assert job.lock <= timezone_now() and not TaskHold.objects.exists()   # on the queue, held by nobody
    monkeypatch.setenv("ROBOTARIUM_WORKER_ID", str(slot.pk))
    ((task, _),) = broker.dequeue()   # and taken again
    assert task == job.pk and TaskHold.objects.get().worker_id == slot.pk
    assert Worker.objects.get(pk=slot.pk).state == Worker.ALIVE


def test_a_slot_found_lost_takes_no_job_and_puts_back_what_it_was_handed(monkeypatch):
    """A slot cut off from the database past WORKER_LOST_AFTER is found lost; its cluster went on taking jobs
    under its name, and its supervisor stopped each one: six verifications failed "could not run (exit code
    -15)" after a database restart (2026-11-30). A lost slot's claims now fail, and the job goes back in the
    queue for another slot; a live slot's claims are as before."""
    from robotarium_portal import jobs
    from robotarium_portal.models import Worker
    monkeypatch.setattr(jobs, "BUSY_OWNER_PAUSE", 0.0)
    owner = make_user()
    lost, alive = make_worker(kind="verify"), make_worker(kind="verify", host="lab-pc-3")
    Worker.objects.filter(pk=lost.pk).update(state=Worker.LOST)
    submitted = experiment_of(owner, title="Submitted")
    Experiment.objects.filter(pk=submitted.pk).update(state=Experiment.SUBMITTED)
    OrmQ.objects.filter(key="verify").delete()
    monkeypatch.setenv("ROBOTARIUM_WORKER_ID", str(lost.pk))
    said = jobs.verify_experiment(submitted.pk)
    submitted.refresh_from_db()
    assert "this slot was found lost" in said and submitted.state == Experiment.SUBMITTED and submitted.worker is None
    assert OrmQ.objects.filter(key="verify").count() == 1   # back in the queue for another slot
    assert not submitted.claim_verification(lost.pk)
    assert submitted.claim_verification(alive.pk) and submitted.worker_id == alive.pk
    # a run: the lost slot takes none and puts the job back; a live one takes it
    queued = experiment_of(make_user(), title="Queued")
    Experiment.objects.filter(state=Experiment.QUEUED).update(state=Experiment.CANCELLED)   # other tests' queue
    Experiment.objects.filter(pk=queued.pk).update(state=Experiment.QUEUED, queued_at=timezone_now())
    runs = OrmQ.objects.filter(key="runs").count()
    assert "this slot was found lost" in jobs.run_next() and OrmQ.objects.filter(key="runs").count() == runs + 1
    assert Experiment.claim_next_run(lost.pk) is None
    assert Experiment.claim_next_run(alive.pk).pk == queued.pk


def test_a_slot_found_lost_is_started_afresh_as_a_new_slot(tmp_path):
    """Its supervisor finds at its next beat that the slot was found lost: it stops the slot's cluster and
    starts it again as a new Worker, so the machine goes on working for the service."""
    from robotarium_portal.models import Worker
    from robotarium_portal.supervisor import Supervisor
    supervisor = Supervisor(settings_data(), ["runs"], 1, dict(os.environ))
    supervisor.start()
    try:
        (old, first), = supervisor.slots
        Worker.objects.filter(pk=old.pk).update(state=Worker.LOST)   # a watcher found it lost
        supervisor.beat()
        deadline = time.monotonic() + 60
        while (supervisor.slots[0][1] is None or supervisor.slots[0][0].pk == old.pk) and time.monotonic() < deadline:
            time.sleep(0.1)
        new, second = supervisor.slots[0]
        assert new.pk != old.pk and Worker.objects.get(pk=new.pk).state == Worker.ALIVE and new.kind == "runs"
        assert first.poll() is not None and second.poll() is None   # the old cluster gone, a new one working
        supervisor.beat()
        assert Worker.objects.get(pk=new.pk).beats >= 1   # and it beats (its heartbeat thread may have beaten too)
    finally:
        supervisor.stop()
    assert all(process.poll() is not None for _, process in supervisor.slots)


def settings_data():
    from django.conf import settings
    return settings.DATA_DIR


def test_a_script_verified_with_the_2x_api_runs_without_the_hardware_like_mode_and_says_so():
    from robotarium_portal import jobs
    experiment = experiment_of(make_user())
    for verification, hardware_like in ((None, True), ({"verdict": "accepted"}, True),
                                        ({"verdict": "accepted", "api": "guide"}, True),
                                        ({"verdict": "accepted", "api": "2"}, False)):
        experiment.verification = verification
        mode = jobs.run_mode(experiment)
        assert mode.hardware_like is hardware_like, verification
        assert ("the hardware-like mode covers the guide's API only" in mode.note) is not hardware_like


def test_password_reset_through_the_mailed_link():
    user = make_user()
    mail.outbox.clear()
    client = Client()
    client.post("/password/reset/", {"email": user.email})
    (message,) = mail.outbox
    link = re.search(r"https?://[^/\s]+(/password/reset/\S+/)", message.body).group(1)
    form = client.get(link, follow=True)   # Django moves the token into the session and redirects
    new = "another-Passphrase-9"
    done = client.post(form.redirect_chain[-1][0], {"new_password1": new, "new_password2": new}, follow=True)
    assert b"Your password is set" in done.content
    assert logs_in(Client(), user.username, new)
