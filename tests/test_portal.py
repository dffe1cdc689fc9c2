"""The Robotarium service (robotarium_portal): its security rules through Django's test client, and a
real browser (headless Chromium) walking the guide's whole flow against `./robotarium serve`.

The security tests run the real views, forms, database (SQLite in a folder of their own) and mail
(Django's test outbox). The walk starts `./robotarium serve` itself, with its mail sent to a real SMTP
server (aiosmtpd) the test starts, its runs and verification on ROS_DOMAIN_IDs of their own, and stops
the service mid-run to check that the experiment runs again and completes after the restart.
"""
import os
import re
import shutil
import signal
import socket
import sqlite3
import subprocess
import tempfile
import threading
import time

import pytest

from devtools.rosutil import REPO, processes_on_domain, unique_domain_id

DATA = tempfile.mkdtemp(prefix="robotarium-portal-test-")
os.environ["ROBOTARIUM_PORTAL_DATA"] = DATA
os.environ["ROBOTARIUM_PORTAL_HOSTS"] = "testserver,localhost,127.0.0.1"
os.environ.setdefault("DJANGO_SETTINGS_MODULE", "robotarium_portal.settings")

import django  # noqa: E402

django.setup()
from django.core import mail  # noqa: E402
from django.core.files.uploadedfile import SimpleUploadedFile  # noqa: E402
from django.core.management import call_command  # noqa: E402
from django.http import Http404  # noqa: E402
from django.test import Client, override_settings  # noqa: E402
from django.test.utils import setup_test_environment  # noqa: E402
from django_q.models import OrmQ  # noqa: E402

from robotarium_portal import files  # noqa: E402
from robotarium_portal.models import Experiment, ExperimentFile, Profile, ReturnMessage  # noqa: E402

PASSWORD = "a-long-Passphrase-7"
SCRIPT = "import numpy as np\nprint('hello')\n"


@pytest.fixture(scope="module", autouse=True)
def database():
    setup_test_environment()   # mail into mail.outbox
    # Django's advice for tests: a fast hasher (the service keeps Django's default, PBKDF2)
    from django.conf import settings
    settings.PASSWORD_HASHERS = ["django.contrib.auth.hashers.MD5PasswordHasher"]
    call_command("migrate", interactive=False, verbosity=0)
    yield
    shutil.rmtree(DATA, ignore_errors=True)


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
    assert client.login(username=user.username, password=PASSWORD)
    return client


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
    admin_client.post("/staff/approvals/%d/" % waiting.profile.pk)
    admin_client.post("/experiments/%d/message/" % experiment.pk, {"text": "Nice swap; slow down near the wall."})
    waiting.profile.refresh_from_db()
    assert waiting.profile.approved and waiting.profile.approved_by == admin
    assert "Nice swap; slow down near the wall." in user_client.get("/experiments/%d/" % experiment.pk).content.decode()


# --- an unconfirmed or unapproved account cannot submit -------------------------------------------------------

def test_sign_up_confirm_approve_then_submit():
    mail.outbox.clear()
    client = Client()
    response = client.post("/signup/", {"email": "Ada@Example.org", "password": PASSWORD, "confirmation": PASSWORD,
                                        "name": "Ada", "city": "Atlanta", "state": "GA", "institute": "GT",
                                        "reason": "swarm lab"})
    assert b"Thank you for signing up" in response.content
    (message,) = mail.outbox
    assert message.to == ["ada@example.org"]
    link = re.search(r"http://testserver(/confirm/\S+/)", message.body).group(1)

    assert client.login(username="ada@example.org", password=PASSWORD)
    response = post_form(client, "/experiments/new/", action="submit",
                         uploads=[SimpleUploadedFile("main.py", SCRIPT.encode())])
    experiment = Experiment.objects.get(owner__username="ada@example.org")
    assert experiment.state == Experiment.SAVED and b"Confirm your email address first" in response.content

    assert client.get(link).status_code == 200
    assert Profile.objects.get(user__username="ada@example.org").email_confirmed
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


# --- uploaded files stay in the experiment's folder, within limits ----------------------------------------------

@pytest.mark.parametrize("name", ["../escape.py", "/etc/passwd", "..", ".bashrc", "a b.py", "semi;colon.py",
                                  "back\\slash.py", "ünï.py", "x" * 101 + ".py", "new\nline.py"])
def test_file_names_that_could_leave_the_folder_are_refused(name):
    assert files.name_problem(name)
    with pytest.raises(Http404):
        files.inside(DATA, name)


def test_odd_upload_names_are_refused_and_nothing_is_written_outside():
    user = make_user()
    client = client_for(user)
    before = set(os.listdir(DATA))
    for name in ("a b.py", "semi;colon.py", ".bashrc", "ünï.py"):
        response = post_form(client, "/experiments/new/", uploads=[SimpleUploadedFile(name, b"print(1)\n")])
        assert b"is not allowed" in response.content, name
    assert not Experiment.objects.filter(owner=user).exists()
    # a path is cut to its last part by Django's parser: it lands inside, as escape.py
    post_form(client, "/experiments/new/", uploads=[SimpleUploadedFile("../../escape.py", b"print(1)\n")])
    experiment = Experiment.objects.get(owner=user)
    assert experiment.file_names() == ["escape.py"] and (experiment.files_dir / "escape.py").exists()
    assert set(os.listdir(DATA)) == before
    # nor can a download name leave the folder (the secret key is two levels up)
    assert client.get("/experiments/%d/files/../../../secret_key" % experiment.pk).status_code == 404
    completed = experiment_of(user, results={"log.txt": "x"})
    for name in ("../../../../secret_key", "data/../../../../../secret_key", "%2e%2e/%2e%2e/secret_key"):
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
