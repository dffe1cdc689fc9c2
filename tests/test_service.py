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
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

import pytest

from devtools.postgres import PostgreSQL, free_port, server_binaries
from devtools.rosutil import REPO, processes_with_env

pytestmark = pytest.mark.e2e
TIMEOUT = 180.0
HEARTBEAT = "1"
SUBNET = 250 + os.getpid() % 5       # 10.<SUBNET>.<x>.0/24: a private test subnet
OCTET = os.getpid() % 250 + 1
HOST_ADDRESS, SECOND_ADDRESS = "10.%d.%d.1" % (SUBNET, OCTET), "10.%d.%d.2" % (SUBNET, OCTET)
SECOND_HOST = "second-host"

# A few lockstep steps: the verification is quick, the run (real time, 30 steps a second) a second.
SHORT = """import numpy as np
import rps.robotarium as robotarium
N = {robots}
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=False,
                          initial_conditions=np.array([np.linspace(-0.5, 0.5, N), np.zeros(N), np.zeros(N)]))
for k in range({steps}):
    r.get_poses()
    r.set_velocities(np.arange(N), np.vstack([np.zeros(N), 0.5 * np.ones(N)]))
    r.step()
print("done {name}", flush=True)
r.call_at_scripts_end()
"""
# Turns in place until its release file exists (at most 900 steps), while it runs ("work": the run's
# folder) or while it is verified ("verify"): the test acts while it surely runs or is verified.
HOLD = """import os
import time
import numpy as np
import rps.robotarium as robotarium
N = 2
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=False,
                          initial_conditions=np.array([[-0.4, 0.4], [0.0, 0.0], [0.0, 0.0]]))
for k in range(900):
    r.get_poses()
    r.set_velocities(np.arange(N), np.vstack([np.zeros(N), 0.5 * np.ones(N)]))
    r.step()
    if os.path.basename(os.getcwd()) != {hold_in!r} or os.path.exists({release!r}):
        break
    time.sleep(0.02)
print("released at step", k, flush=True)
r.call_at_scripts_end()
"""

# Run by the test's own Python with Django on the service's database: what the portal's submit does.
SUBMIT = """
import json, os, sys
import django
django.setup()
from django.contrib.auth import get_user_model
from django.utils import timezone
from robotarium_portal import tasks
from robotarium_portal.models import Experiment, ExperimentFile, Profile
user, made = get_user_model().objects.get_or_create(username="ada@example.org", email="ada@example.org")
Profile.objects.get_or_create(user=user, defaults=dict(name="Ada", email_confirmed=True, approved=True))
pks = []
for item in json.loads(sys.stdin.read()):
    e = Experiment.objects.create(owner=user, title=item["title"], estimated_duration=60,
                                  number_of_robots=item["robots"], main_file="main.py")
    e.files_dir.mkdir(parents=True, exist_ok=True)
    (e.files_dir / "main.py").write_text(item["script"])
    ExperimentFile.objects.create(experiment=e, name="main.py", size=len(item["script"]))
    e.state, e.submitted_at = Experiment.SUBMITTED, timezone.now()
    e.save()
    tasks.enqueue_verification(e)
    pks.append(e.pk)
print(json.dumps(pks))
"""


def run_quietly(*command):
    return subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def session_processes(sid):
    """Every live process of this session."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open("/proc/%s/stat" % entry) as f:
                    fields = f.read().rsplit(")", 1)[1].split()
                if int(fields[3]) == sid:
                    found.append(int(entry))
            except (OSError, IndexError, ValueError):
                pass
    return found


class Process:
    """A command in a session of its own, its output kept."""

    def __init__(self, command, env, log):
        self.log_path = log
        self.log = open(log, "ab")
        self.process = subprocess.Popen(command, env=env, cwd=REPO, stdout=self.log, stderr=subprocess.STDOUT,
                                        stdin=subprocess.DEVNULL, start_new_session=True)

    def output(self):
        with open(self.log_path, errors="replace") as f:
            return f.read()

    def wait_for(self, text, what):
        deadline = time.monotonic() + TIMEOUT
        while text not in self.output():
            assert self.process.poll() is None and time.monotonic() < deadline, "%s:\n%s" % (what, self.output())
            time.sleep(0.2)

    def stop(self):
        """Ctrl-C, as an operator stops it."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=120)
            except subprocess.TimeoutExpired:
                self.kill()
        self.log.close()

    def kill(self):
        """kill -9 of everything it started (its machine gone): its session, and its jobs' testbeds."""
        for pid in session_processes(self.process.pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.process.wait()


class Service:
    """PostgreSQL, the portal and the workers; the data folder; the network namespace of the second host."""

    def __init__(self, folder):
        self.folder = folder
        self.data = os.path.join(folder, "service")
        os.makedirs(self.data)
        self.namespace = "robotarium-test-%d" % os.getpid()
        self.workers = {}
        self.portal = None
        self.postgres = None

    def make_second_host(self):
        """A network namespace with a veth pair: this side HOST_ADDRESS, the second host SECOND_ADDRESS."""
        here, there = "rbt%d" % os.getpid(), "rbs%d" % os.getpid()
        for command in (["ip", "netns", "add", self.namespace],
                        ["ip", "link", "add", here[:15], "type", "veth", "peer", "name", there[:15]],
                        ["ip", "link", "set", there[:15], "netns", self.namespace],
                        ["ip", "addr", "add", HOST_ADDRESS + "/24", "dev", here[:15]],
                        ["ip", "link", "set", here[:15], "up"],
                        ["ip", "-n", self.namespace, "addr", "add", SECOND_ADDRESS + "/24", "dev", there[:15]],
                        ["ip", "-n", self.namespace, "link", "set", there[:15], "up"],
                        ["ip", "-n", self.namespace, "link", "set", "lo", "up"]):
            result = run_quietly(*command)
            if result.returncode:
                raise RuntimeError("%s: %s" % (" ".join(command), result.stdout))
        self.veth = here[:15]

    def env(self):
        env = {k: v for k, v in os.environ.items() if not k.startswith(("ROBOTARIUM_PORTAL", "DJANGO_", "ROS_"))}
        env.update(ROBOTARIUM_WORKER_HEARTBEAT=HEARTBEAT, ROBOTARIUM_PORTAL_MAX_PENDING="50",
                   ROBOTARIUM_PORTAL_LOG="INFO")
        return env

    def start_portal(self):
        self.portal = Process([os.path.join(REPO, "robotarium"), "serve", "--data", self.data, "--database",
                               self.postgres.url(), "--port", str(free_port()), "--jobs", "0"], self.env(),
                              os.path.join(self.folder, "portal.txt"))
        self.portal.wait_for("portal is at", "the portal did not start")

    def start_worker(self, name):
        if name == SECOND_HOST:
            command = ["ip", "netns", "exec", self.namespace, "unshare", "--uts", "sh", "-c",
                       'hostname %s && exec "$0" "$@"' % SECOND_HOST, os.path.join(REPO, "robotarium"), "worker",
                       "--database", self.postgres.url(HOST_ADDRESS), "--data", self.data]
        else:
            command = [os.path.join(REPO, "robotarium"), "worker", "--database", self.postgres.url(), "--data",
                       self.data]
        worker = Process(command, self.env(), os.path.join(self.folder, "worker-%s.txt" % name))
        worker.wait_for("[robotarium] worker on", "the worker %s did not start" % name)
        self.workers[name] = worker
        return worker

    def logs(self):
        texts = []
        for folder, _, names in os.walk(self.folder):
            for name in names:
                if name.endswith(".txt") and ("worker" in name or name in ("portal.txt", "output.txt",
                                                                         "verification-output.txt")):
                    with open(os.path.join(folder, name), errors="replace") as f:
                        texts.append("--- %s\n%s" % (os.path.join(folder, name), f.read()[-2500:]))
        return "\n".join(texts)

    def submit(self, items):
        env = dict(self.env(), ROBOTARIUM_PORTAL_DATA=self.data, ROBOTARIUM_PORTAL_DATABASE=self.postgres.url(),
                   DJANGO_SETTINGS_MODULE="robotarium_portal.settings", PYTHONPATH=REPO)
        result = subprocess.run([sys.executable, "-c", SUBMIT], input=json.dumps(items), env=env, cwd=REPO,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=TIMEOUT)
        assert result.returncode == 0, result.stderr
        return json.loads(result.stdout.strip().splitlines()[-1])

    def experiment(self, pk):
        row = self.postgres.query("SELECT state, attempts, detail, results, worker_id FROM "
                                  "robotarium_portal_experiment WHERE id = %s", pk)[0]
        return dict(zip(("state", "attempts", "detail", "results", "worker"), row))

    def worker_of(self, pk):
        """The name (host) of the worker that holds the experiment."""
        host = self.postgres.query("SELECT w.host FROM robotarium_portal_worker w JOIN robotarium_portal_experiment e"
                                   " ON e.worker_id = w.id WHERE e.id = %s", pk)[0][0]
        return SECOND_HOST if host == SECOND_HOST else "here"

    def wait_for(self, pk, states, what=""):
        deadline = time.monotonic() + TIMEOUT
        while True:
            row = self.experiment(pk)
            if row["state"] in states:
                return row
            assert time.monotonic() < deadline, "experiment %d %s, wanted %s %s\n%s" % (
                pk, row, states, what, self.logs())
            time.sleep(0.3)

    def close(self):
        for worker in self.workers.values():
            worker.stop()
        if self.portal is not None:
            self.portal.stop()
        # whatever a killed worker left (its testbed), by the worker environment they all carry
        for pid in processes_with_env("ROBOTARIUM_PORTAL_DATA", self.data):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if self.postgres is not None:
            self.postgres.close()
        run_quietly("ip", "netns", "delete", self.namespace)
        if getattr(self, "veth", None):
            run_quietly("ip", "link", "delete", self.veth)


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
        service.postgres = PostgreSQL(listen=("127.0.0.1", HOST_ADDRESS))
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
    assert run_quietly(*inside, HOST_ADDRESS).returncode == 0
    assert run_quietly(*inside, "127.0.0.1").returncode != 0
    hosts = {h for (h,) in service.postgres.query("SELECT DISTINCT host FROM robotarium_portal_worker "
                                                  "WHERE state = 'alive'")}
    assert hosts == {socket.gethostname(), SECOND_HOST}


def test_twelve_submissions_each_verified_and_run_exactly_once_on_two_hosts(service):
    items = [{"title": "short %d" % k, "robots": robots, "script": SHORT.format(robots=robots, steps=20 + k, name=k)}
             for k, robots in enumerate([2, 3, 4, 5] * 3)]
    pks = service.submit(items)
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
    done = dict(((host, kind), n) for host, kind, n in service.postgres.query(
        "SELECT host, kind, SUM(jobs_done) FROM robotarium_portal_worker GROUP BY host, kind"))
    assert sum(n for (_, kind), n in done.items() if kind == "runs") == 12, done
    assert sum(n for (_, kind), n in done.items() if kind == "verify") == 12, done
    assert all(sum(n for (h, _), n in done.items() if h == host) > 0 for host in (socket.gethostname(), SECOND_HOST)), done


def _hold(service, title, tmp, hold_in="work"):
    release = os.path.join(tmp, "release-%s" % title.replace(" ", "-"))
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
    killed = service.worker_of(pk)
    service.workers[killed].kill()
    row = service.wait_for(pk, ("failed", "completed"), "(found lost)")
    assert row["state"] == "failed" and "the testbed was lost" in row["detail"], row
    assert row["attempts"] == 1 and row["results"], row   # what was recorded so far is attached
    assert os.path.isdir(os.path.join(service.data, "experiments", str(pk), row["results"]))
    lost = service.postgres.query("SELECT state FROM robotarium_portal_worker WHERE id = %s", row["worker"])
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
    return service.postgres.query("SELECT COUNT(*) FROM robotarium_portal_worker WHERE state = 'lost'")[0][0]


def test_a_database_restart_mid_run_costs_nothing(service, tmp_path):
    lost_before = lost_workers(service)
    pk, release = _hold(service, "database restart", str(tmp_path))
    short = service.submit([{"title": "meanwhile", "robots": 3, "script": SHORT.format(robots=3, steps=20, name="m")}])
    service.wait_for(pk, ("running",))
    service.postgres.restart()
    time.sleep(float(HEARTBEAT) * 3)   # the workers and the portal meet the restarted server
    open(release, "w").close()
    row = service.wait_for(pk, ("completed", "failed"))
    assert row["state"] == "completed" and row["attempts"] == 1, row
    assert service.wait_for(short[0], ("completed",))["attempts"] == 1
    assert lost_workers(service) == lost_before   # nobody was taken for lost
    assert all(w.process.poll() is None for w in service.workers.values())
