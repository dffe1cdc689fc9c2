"""The portal (./robotarium serve) end to end: turnaround of a 300-step experiment on an empty queue, and the
pages' response times under 20 users browsing while an experiment runs: at a person's pace (a page every 1-3 s
each), then as fast as each can (a load test).

    ./robotarium bench portal [--users 20] [--steps 300] [--think 2] [--baseline [--baseline-env VAR=VALUE]] [--repeat N]
                              [--back-to-back N]

--baseline: the turnaround also with no warm testbeds (ROBOTARIUM_PORTAL_WARM_VERIFICATION=0 and
ROBOTARIUM_PORTAL_WARM_RUNS=0: each verification and each run starts a testbed of its own in its box), or,
with --baseline-env VAR=VALUE (e.g. ROBOTARIUM_PORTAL_WARM_RUNS=0, ROBOTARIUM_LIVE_VIDEO=0), with those
variables instead; a service of each kind in turn, --repeat times each, interleaved, medians side by side
with their ratio. Then --back-to-back N experiments submitted at once, on a service of each kind: how long
each takes beyond its run. Then the pages under load on the warm one.

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
import random
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
from pathlib import Path

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)
PASSWORD = "bench-Passphrase-42"
SCRIPT = """import time
first = time.time()
import numpy as np
import rps.robotarium as robotarium
N = 5
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=True)
built = time.time()
for k in range(%d):
    r.get_poses()
    r.set_velocities(np.arange(N), np.vstack([np.zeros(N), 0.5 * np.ones(N)]))
    r.step()
print("turned for", k + 1, "steps")
print("bench marks: first %%.3f built %%.3f looped %%.3f" %% (first, built, time.time()))
r.call_at_scripts_end()
"""
# The script's own clock marks (its first line, its imports and Robotarium made, its loop done): the turnaround's timeline.
MARKS = re.compile(r"bench marks: first ([\d.]+) built ([\d.]+) looped ([\d.]+)")


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
    parser.add_argument("--think", type=float, default=2.0, metavar="S",
                        help="seconds a browsing user reads a page before the next (uniform in [S/2, 3S/2]); "
                             "then the same users browse with none, as a load test")
    parser.add_argument("--baseline", action="store_true",
                        help="also measure the turnaround with no warm testbeds, interleaved")
    parser.add_argument("--baseline-env", metavar="VAR=VALUE", action="append", default=[],
                        help="with --baseline: the baseline is the service with these variables instead (its warm "
                             "verification testbed kept), e.g. ROBOTARIUM_LIVE_VIDEO=0 (the video made from the bag)")
    parser.add_argument("--repeat", type=int, default=1, help="turnarounds of each kind (median shown)")
    parser.add_argument("--back-to-back", type=int, default=3, metavar="N",
                        help="then N experiments submitted at once, on a service of each kind: how long each takes "
                             "beyond its run, from the one before it completed to its own completion (0: none)")
    args = parser.parse_args()
    baseline_env = dict(item.split("=", 1) for item in args.baseline_env)
    baseline_name = ("with %s" % " ".join(args.baseline_env) if baseline_env
                     else "no warm testbeds: each job on a testbed of its own")

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

    def new_experiment(title, owner=0):
        experiment = Experiment.objects.create(owner=users[owner], title=title, estimated_duration=60,
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

    def start_serve(warm):
        port = free_port()
        earlier = set((Path(data) / "logs").glob("worker-*.txt"))   # (an earlier service's slots, in this data)
        env = dict(os.environ, ROBOTARIUM_PORTAL_WARM_VERIFICATION="1", ROBOTARIUM_PORTAL_WARM_RUNS="1")
        if not warm:
            env.update(baseline_env or {"ROBOTARIUM_PORTAL_WARM_VERIFICATION": "0", "ROBOTARIUM_PORTAL_WARM_RUNS": "0"})
        serve = subprocess.Popen([os.path.join(REPO, "robotarium"), "serve", "--data", data, "--port", str(port),
                                  "--run-domain", str(unique_domain_id()), "--verify-domain", str(unique_domain_id())],
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
                                 env=env)
        for line in serve.stdout:
            if "portal is at" in line:
                break
        threading.Thread(target=lambda: [None for _ in serve.stdout], daemon=True).start()
        # The slots' clusters running (the verification slot's after its warm testbed): a turnaround on a service
        # that has been up a while, as the goal's empty queue is, not its start.
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and sum("] running." in p.read_text(errors="replace") for p in
                                                  set((Path(data) / "logs").glob("worker-*.txt")) - earlier) < 2:
            time.sleep(0.2)
        return serve, "http://127.0.0.1:%d/" % port

    def stop_serve(serve):
        serve.send_signal(signal.SIGINT)
        try:
            serve.wait(timeout=120)
        except subprocess.TimeoutExpired:
            os.killpg(serve.pid, signal.SIGKILL)

    def turnaround(base):
        """One experiment submitted on an empty queue: {part: s}, its state, its verification's first line."""
        owner = Session(base)
        owner.log_in(users[0].email)
        experiment = new_experiment("turnaround")
        clicked = time.time()
        submit(owner, experiment)
        experiment = wait_until(experiment, ("completed", "failed", "rejected"))
        run = json.loads((experiment.results_dir / "run.json").read_text()) if experiment.results_dir else {}
        command = experiment.timings.get("run_command", 0.0)
        script = run.get("wall_time", 0.0)
        said = (experiment.folder / "verification-output.txt").read_text(errors="replace")
        job = experiment.folder / ("run-%d" % experiment.attempts) / "output.txt"
        said_by_job = job.read_text(errors="replace") if job.exists() else ""
        live_videos.append("made as the run went" in said_by_job)
        timelines.append(timeline(experiment, MARKS.search(said), MARKS.search(said_by_job)))
        return {"total": experiment.finished_at.timestamp() - clicked,
                "verification": (experiment.queued_at - experiment.submitted_at).total_seconds(),
                "verify_command": experiment.timings.get("verify_command", 0.0),
                "waiting": (experiment.started_at - experiment.queued_at).total_seconds(),
                "run": script, "around": command - script,
                "attaching": (experiment.finished_at - experiment.started_at).total_seconds() - command,
                }, experiment, ("warm" if "on the warm verification testbed" in said else "own")

    def median(values):
        return sorted(values)[len(values) // 2]

    def timeline(experiment, verified, ran):
        """{stage: s} of one turnaround from the database's timestamps and the script's own marks in its
        verification and its run (None where a mark is missing)."""
        if not (verified and ran):
            return None
        v, r = [float(x) for x in verified.groups()], [float(x) for x in ran.groups()]
        return {"verify: submitted -> the script's first line": v[0] - experiment.submitted_at.timestamp(),
                "verify: imports, its Robotarium made": v[1] - v[0],
                "verify: the loop, lockstep": v[2] - v[1],
                "verify: the loop's end -> queued": experiment.queued_at.timestamp() - v[2],
                "queued -> claimed": (experiment.started_at - experiment.queued_at).total_seconds(),
                "run: claimed -> the script's first line": r[0] - experiment.started_at.timestamp(),
                "run: imports, its Robotarium made": r[1] - r[0],
                "run: the loop, real time": r[2] - r[1],
                "run: the loop's end -> completed": experiment.finished_at.timestamp() - r[2]}

    live_videos = []   # per turnaround, in order: its video drawn while the run went (live_video)
    timelines = []     # per turnaround, in order: timeline() or None
    keep = []          # the folders of turnarounds far slower than the others, for a look
    kinds = [True, False] if args.baseline else [True]
    measured = {kind: [] for kind in kinds}
    for _ in range(args.repeat):
        for kind in kinds:
            serve, base = start_serve(kind)
            try:
                measured[kind].append(turnaround(base))
            finally:
                stop_serve(serve)
    PARTS = [("verification", "submitted -> queued"), ("verify_command", "./robotarium verify in its box"),
             ("waiting", "queued -> claimed by the worker"),
             ("run", "the script: %d steps in real time = %.1f s of testbed time" % (args.steps, args.steps * 0.033)),
             ("around", "./robotarium run's start, the testbed's start and stop, the results: report, plot, video"),
             ("attaching", "copying the files in, the results to the experiment, the mail")]
    warm_runs = measured[True]
    experiment = warm_runs[-1][1]
    verdict = experiment.verification or {}
    print("Turnaround of a %d-step, 5-robot experiment on an empty queue: %s, %.1f s from Submit to the completed "
          "results (median of %d; the Robotarium: 10 minutes at best); its verification %s, %s iterations, on %s"
          % (args.steps, experiment.state, median([r["total"] for r, _, _ in warm_runs]), len(warm_runs),
             verdict.get("verdict", "not verified"), verdict.get("iterations", "-"),
             ", ".join(sorted({"the slot's warm testbed" if w == "warm" else "a testbed of its own"
                               for _, _, w in warm_runs}))))
    if args.baseline:
        cold = measured[False]
        print("  %-16s %9s %12s %6s   %s" % ("part", "warm (s)", "baseline (s)", "ratio", "what"))
        for name, what in [("total", "Submit -> completed")] + PARTS:
            w, c = median([r[name] for r, _, _ in warm_runs]), median([r[name] for r, _, _ in cold])
            print("  %-16s %9.1f %12.1f %6s   %s" % (name, w, c, "%.2f" % (w / c) if c > 0.05 else "-", what))
        print("  runs (total, s): warm %s; baseline (%s; verified on %s) %s" % (
            " ".join("%.1f" % r["total"] for r, _, _ in warm_runs), baseline_name,
            ", ".join(sorted({"the slot's warm testbed" if w == "warm" else "a testbed of its own" for _, _, w in cold})),
            " ".join("%.1f" % r["total"] for r, _, _ in cold)))
        print("  videos drawn as the run went: %d of %d; baseline %d of %d" % (
            sum(live_videos[0::2]), len(live_videos[0::2]), sum(live_videos[1::2]), len(live_videos[1::2])))
    else:
        for name, what in PARTS:
            print("  %-16s %6.1f s   (%s)" % (name, median([r[name] for r, _, _ in warm_runs]), what))
        print("  runs (total, s): %s" % " ".join("%.1f" % r["total"] for r, _, _ in warm_runs))
    marked = [t for t in timelines[0::len(kinds)] if t]
    if marked:
        print("  where it goes, by the database's timestamps and the script's own clock marks (median of %d, warm):"
              % len(marked))
        for stage in marked[0]:
            print("    %-46s %6.2f s" % (stage, median([t[stage] for t in marked])))
    for kind in kinds:   # a turnaround far from its kind's median: its parts, and its experiment kept
        usual = median([r["total"] for r, _, _ in measured[kind]])
        for parts, slow, _ in measured[kind]:
            if parts["total"] > 1.3 * usual:
                keep.append(slow.folder)
                print("  a slow one (%s, experiment %d, kept in %s): %s" % (
                    "warm" if kind else "baseline", slow.pk, slow.folder,
                    ", ".join("%s %.1f" % (name, parts[name]) for name, _ in [("total", "")] + PARTS)))
    print("goal: submit -> completed <= 14 s: %.1f s -> %s" % (
        median([r["total"] for r, _, _ in warm_runs]),
        "met" if median([r["total"] for r, _, _ in warm_runs]) <= 14 else "not met"))

    def back_to_back(base, count):
        """count experiments of count people submitted at once on an empty queue: each one's time beyond its run,
        from the completion of the one before it to its own, less the run's testbed time."""
        made = [new_experiment("back to back %d" % k, owner=k % len(users)) for k in range(count)]
        for k, experiment in enumerate(made):
            session = Session(base)
            session.log_in(users[k % len(users)].email)
            submit(session, experiment)
        done = [wait_until(experiment, ("completed", "failed", "rejected")) for experiment in made]
        finished = sorted(e.finished_at.timestamp() for e in done)
        testbed_time = args.steps * 0.033
        return [b - a - testbed_time for a, b in zip(finished, finished[1:])], [e.state for e in done]

    if args.back_to_back > 1:
        beyond = {}
        for kind in kinds:
            serve, base = start_serve(kind)
            try:
                beyond[kind] = back_to_back(base, args.back_to_back)
            finally:
                stop_serve(serve)
        print("%d experiments submitted at once, each after the one before it (from its completion to the next "
              "one's, less the run's %.1f s of testbed time):" % (args.back_to_back, args.steps * 0.033))
        for kind in kinds:
            gaps, states = beyond[kind]
            print("  %-9s each %s s beyond its run (median %.1f s); states %s" % (
                "warm" if kind else "baseline", " ".join("%.1f" % g for g in gaps), median(gaps), " ".join(states)))
        print("goal: back to back, each <= 3 s beyond its run: %.1f s (median, warm) -> %s" % (
            median(beyond[True][0]), "met" if max(beyond[True][0]) <= 3 else "not met"))

    # 2. Pages while an experiment runs (on a service with the warm verification testbed): 20 people browsing, each
    # reading a page for a while before the next, then the same 20 as fast as each can (a load test: with no time
    # between pages each answer waits for the others', so its latency is users / throughput, Little's law).
    serve, base = start_serve(True)
    try:
        owner = Session(base)
        owner.log_in(users[0].email)
        sessions = []
        for user in users:
            session = Session(base)
            session.log_in(user.email)
            sessions.append(session)
        pages = ["/", "/?tab=completed", "/queue/", "/experiments/new/"]

        def browse_during_a_run(title, think):
            """Each session browses while a fresh experiment runs, `think` s (uniform in [think/2, 3 think/2];
            0: none) between its pages; prints the table and returns (the p99 over every page in ms, pages/s)."""
            experiment = new_experiment(title)
            submit(owner, experiment)
            wait_until(experiment, ("running",))
            latencies, errors, stop = {p: [] for p in pages + ["experiment"]}, [], threading.Event()

            def browse(k, session):
                own = "/experiments/%d/" % experiment.pk if k == 0 else None
                pause = random.Random(k)
                if think:   # people come at their own moments, not all at the run's first instant
                    stop.wait(pause.uniform(0, think))
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
                    if think:
                        stop.wait(pause.uniform(think / 2, 3 * think / 2))

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
            print("%d users browsing for %.0f s while the experiment ran (%s at the end), %s: %d pages, %.0f pages/s, "
                  "%d errors" % (args.users, seconds, experiment.state,
                                 "a page every %.1f-%.1f s each" % (think / 2, 3 * think / 2) if think
                                 else "each as fast as it can (a load test)",
                                 len(every), len(every) / seconds, len(errors)))
            print("  %-22s %6s %8s %8s" % ("page", "count", "p50 ms", "p99 ms"))
            for name, values in list(latencies.items()) + [("all", every)]:
                if values:
                    print("  %-22s %6d %8.0f %8.0f" % (name, len(values), 1000 * percentile(values, 50),
                                                         1000 * percentile(values, 99)))
            if errors:
                print("  first error:", errors[0])
            return (1000 * percentile(every, 99) if every else float("nan")), len(every) / seconds

        people, _ = browse_during_a_run("browsed", args.think)
        flat_out, rate = browse_during_a_run("under load", 0.0)
        print("goal: pages p99 <= 150 ms with %d users browsing during a run (a page every %.1f-%.1f s each): %.0f ms "
              "-> %s" % (args.users, args.think / 2, 3 * args.think / 2, people, "met" if people <= 150 else "not met"))
        print("      the same users as fast as each can (%.0f pages/s): p99 %.0f ms -> %s" % (
            rate, flat_out, "met" if flat_out <= 150 else "not met"))
    finally:
        stop_serve(serve)
        if keep:
            print("the service's folder is kept for the slow turnarounds' experiments: %s" % data)
        else:
            shutil.rmtree(data, ignore_errors=True)


if __name__ == "__main__":
    main()
