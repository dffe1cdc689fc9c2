"""The portal (./robotarium serve) end to end: turnaround of a 300-step experiment on an empty queue, and the
pages' response times under 20 users browsing while an experiment runs.

    ./robotarium bench portal [--users 20] [--steps 300]

A fresh service in a temporary folder, on ROS_DOMAIN_IDs of its own. The user and the experiment are made
in its database (not measured); the submission, the pages and the log-ins go through HTTP as a browser's
would. Turnaround is split by the experiment's own timestamps: verification (submitted -> queued),
waiting (queued -> the worker claimed it), the run (./robotarium run's wall time: testbed start, the
script in real time, its end) and the rest (the results: report, plot, video; attaching them; the mail).
"""
import argparse
import http.cookiejar
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
import urllib.request

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)
PASSWORD = "bench-Passphrase-42"
SCRIPT = """import numpy as np
import rps.robotarium as robotarium
N = 5
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=True)
for k in range(%d):
    r.get_poses()
    r.set_velocities(np.arange(N), np.vstack([np.zeros(N), 0.5 * np.ones(N)]))
    r.step()
print("turned for", k + 1, "steps")
r.call_at_scripts_end()
"""


class Session:
    """A browser's session: cookies, the CSRF token, log in, get, post a form."""

    def __init__(self, base):
        self.base = base
        self.opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar()))

    def get(self, path):
        with self.opener.open(self.base + path.lstrip("/"), timeout=60) as response:
            return response.status, response.read().decode()

    def post(self, path, fields):
        _, page = self.get(path)
        token = re.search(r'name="csrfmiddlewaretoken" value="([^"]+)"', page).group(1)
        body = urllib.parse.urlencode(dict(fields, csrfmiddlewaretoken=token)).encode()
        request = urllib.request.Request(self.base + path.lstrip("/"), data=body,
                                         headers={"Referer": self.base + path.lstrip("/")})
        with self.opener.open(request, timeout=60) as response:
            return response.status, response.read().decode()

    def log_in(self, email):
        _, page = self.post("/login/", {"username": email, "password": PASSWORD})
        assert "Dashboard" in page, "log-in failed"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q / 100 * (len(ordered) - 1))))]


def main():
    parser = argparse.ArgumentParser(prog="./robotarium bench portal", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--users", type=int, default=20, help="users browsing while an experiment runs")
    parser.add_argument("--steps", type=int, default=300, help="steps of the experiment's script")
    args = parser.parse_args()

    from devtools.rosutil import unique_domain_id
    data = tempfile.mkdtemp(prefix="robotarium-bench-portal-")
    os.environ["ROBOTARIUM_PORTAL_DATA"] = data
    os.environ["DJANGO_SETTINGS_MODULE"] = "robotarium_portal.settings"
    import django
    django.setup()
    from django.contrib.auth import get_user_model
    from django.core.management import call_command

    from robotarium_portal.models import Experiment, ExperimentFile, Profile
    call_command("migrate", interactive=False, verbosity=0)
    users = []
    for k in range(args.users):
        email = "student%d@example.org" % k
        user = get_user_model().objects.create_user(username=email, email=email, password=PASSWORD)
        Profile.objects.create(user=user, name="Student %d" % k, city="Atlanta", state="GA", institute="GT",
                               reason="bench", email_confirmed=True, approved=True)
        users.append(user)

    def new_experiment(title):
        experiment = Experiment.objects.create(owner=users[0], title=title, estimated_duration=60,
                                               number_of_robots=5, main_file="main.py")
        experiment.files_dir.mkdir(parents=True)
        (experiment.files_dir / "main.py").write_text(SCRIPT % args.steps)
        ExperimentFile.objects.create(experiment=experiment, name="main.py", size=len(SCRIPT))
        return experiment

    def submit(session, experiment):
        session.post("/experiments/%d/" % experiment.pk, {"title": experiment.title, "description": "",
                                                           "estimated_duration": 60, "number_of_robots": 5,
                                                           "main_file": "main.py", "action": "submit"})

    def wait_until(experiment, states, timeout=600):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            experiment.refresh_from_db()
            if experiment.state in states:
                return experiment
            time.sleep(0.1)
        raise SystemExit("experiment %d still %s after %d s" % (experiment.pk, experiment.state, timeout))

    port = free_port()
    serve = subprocess.Popen([os.path.join(REPO, "robotarium"), "serve", "--data", data, "--port", str(port),
                              "--run-domain", str(unique_domain_id()), "--verify-domain", str(unique_domain_id())],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        for line in serve.stdout:
            if "portal is at" in line:
                break
        threading.Thread(target=lambda: [None for _ in serve.stdout], daemon=True).start()
        base = "http://127.0.0.1:%d/" % port
        owner = Session(base)
        owner.log_in(users[0].email)

        # 1. Turnaround on an empty queue, nobody browsing.
        experiment = new_experiment("turnaround")
        clicked = time.time()
        submit(owner, experiment)
        experiment = wait_until(experiment, ("completed", "failed", "rejected"))
        run = json.loads((experiment.results_dir / "run.json").read_text()) if experiment.results_dir else {}
        total = experiment.finished_at.timestamp() - clicked
        verification = (experiment.queued_at - experiment.submitted_at).total_seconds()
        waiting = (experiment.started_at - experiment.queued_at).total_seconds()
        command = experiment.timings.get("run_command", 0.0)
        script = run.get("wall_time", 0.0)
        after = (experiment.finished_at - experiment.started_at).total_seconds() - command
        print("Turnaround of a %d-step, 5-robot experiment on an empty queue: %s, %.1f s from Submit to the "
              "completed results (the Robotarium: 10 minutes at best)" % (args.steps, experiment.state, total))
        verdict = experiment.verification or {}
        print("  verification    %6.1f s   (submitted -> queued; ./robotarium verify %.1f s: %s, %s iterations)"
              % (verification, experiment.timings.get("verify_command", 0.0), verdict.get("verdict", "not verified"),
                 verdict.get("iterations", "-")))
        print("  waiting         %6.1f s   (queued -> claimed by the worker)" % waiting)
        print("  run             %6.1f s   (the script: %d steps in real time = %.1f s of testbed time)"
              % (script, args.steps, args.steps * 0.033))
        print("  around the run  %6.1f s   (./robotarium run's start, the testbed's start and stop, the results: "
              "report, plot, video)" % (command - script))
        print("  attaching       %6.1f s   (copying the files in, the results to the experiment, the mail)" % after)

        # 2. Pages under load while an experiment runs.
        sessions = []
        for user in users:
            session = Session(base)
            session.log_in(user.email)
            sessions.append(session)
        experiment = new_experiment("under load")
        submit(owner, experiment)
        wait_until(experiment, ("running",))
        pages = ["/", "/?tab=completed", "/queue/", "/experiments/new/"]
        latencies, errors, stop = {p: [] for p in pages + ["experiment"]}, [], threading.Event()

        def browse(k, session):
            own = "/experiments/%d/" % experiment.pk if k == 0 else None
            i = 0
            while not stop.is_set():
                path = own if own and i % 2 else pages[i % len(pages)]
                started = time.perf_counter()
                try:
                    session.get(path)
                    latencies["experiment" if path == own else path].append(time.perf_counter() - started)
                except Exception as error:   # noqa: BLE001 - counted and shown
                    errors.append(repr(error))
                i += 1

        threads = [threading.Thread(target=browse, args=(k, s)) for k, s in enumerate(sessions)]
        began = time.monotonic()
        for t in threads:
            t.start()
        while experiment.state == "running":
            time.sleep(0.2)
            experiment.refresh_from_db(fields=["state"])
        stop.set()
        for t in threads:
            t.join()
        seconds = time.monotonic() - began
        every = [v for values in latencies.values() for v in values]
        print("%d users browsing for %.0f s while the experiment ran (%s at the end): %d pages, %.0f pages/s, "
              "%d errors" % (args.users, seconds, experiment.state, len(every), len(every) / seconds, len(errors)))
        print("  %-22s %6s %8s %8s" % ("page", "count", "p50 ms", "p99 ms"))
        for name, values in list(latencies.items()) + [("all", every)]:
            if values:
                print("  %-22s %6d %8.0f %8.0f" % (name, len(values), 1000 * percentile(values, 50),
                                                     1000 * percentile(values, 99)))
        if errors:
            print("  first error:", errors[0])
    finally:
        serve.send_signal(signal.SIGINT)
        try:
            serve.wait(timeout=120)
        except subprocess.TimeoutExpired:
            os.killpg(serve.pid, signal.SIGKILL)
        shutil.rmtree(data, ignore_errors=True)


if __name__ == "__main__":
    main()
