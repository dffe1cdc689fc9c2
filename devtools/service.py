"""The Robotarium service's stack for tests and benchmarks (tests/test_service.py, bench/bench_service.py):
a PostgreSQL server of its own (devtools.postgres), the portal (./robotarium serve --database ... --jobs 0),
workers (./robotarium worker), one of them optionally a second host in a network namespace of its own
(a veth pair on a private test subnet, its own host name); submissions made as the portal's submit makes
them, from a Django process pointed at the same database; the truth read straight from PostgreSQL."""
import json
import os
import re
import signal
import subprocess
import sys
import time

from devtools.postgres import free_port
from devtools.rosutil import REPO, processes_with_env

TIMEOUT = 180.0
HEARTBEAT = "1"   # s: a lost worker is found after 5 s without a beat
SUBNETS = ["10.%d.%d" % (a, b) for a in range(250, 255) for b in range(1, 251)]   # private test /24s
NAMESPACE_PREFIX, VETH_PREFIX = "robotarium-test-", "rbt"   # + the pid of the test process that made it
_OPEN = set()   # the namespaces of this process's Services not closed yet
SECOND_HOST = "second-host"
PASSWORD = "a-long-Passphrase-7"

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
# Turns in place until its release file exists, while it runs ("work": the portal's run, in real time) or
# while it is verified ("verify": lockstep): the test acts while it surely runs or is verified. (It asked the
# folder's name before, but a job box runs every job in <box>/work: a verification never held, and a test
# that needed it held passed only when its next step came within the few seconds the verification took.)
# The release file goes in the service's data folder (Service.release_file), which a job box keeps: the
# box's /tmp is its own. At most 2600 steps: under the 2700 (90 s) a verification allows the declared 60 s.
HOLD = """import os
import time
import numpy as np
import rps.robotarium as robotarium
N = 2
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=False,
                          initial_conditions=np.array([[-0.4, 0.4], [0.0, 0.0], [0.0, 0.0]]))
for k in range(2600):
    r.get_poses()
    r.set_velocities(np.arange(N), np.vstack([np.zeros(N), 0.5 * np.ones(N)]))
    r.step()
    if r.sim_in_real_time != ({hold_in!r} == "work") or os.path.exists({release!r}):
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
from robotarium_portal import jobs
from robotarium_portal.models import Experiment, ExperimentFile, Profile
def person(email):
    user, made = get_user_model().objects.get_or_create(username=email, email=email)
    if made:
        user.set_password(os.environ["PASSWORD"])
        user.save()
    Profile.objects.get_or_create(user=user, defaults=dict(name=email.split("@")[0], email_confirmed=True,
                                                           approved=True))
    return user
pks = []
for item in json.loads(sys.stdin.read()):
    e = Experiment.objects.create(owner=person(item.get("owner", "ada@example.org")), title=item["title"], estimated_duration=60,
                                  number_of_robots=item["robots"], main_file="main.py")
    e.files_dir.mkdir(parents=True, exist_ok=True)
    (e.files_dir / "main.py").write_text(item["script"])
    ExperimentFile.objects.create(experiment=e, name="main.py", size=len(item["script"]))
    e.state, e.submitted_at = Experiment.SUBMITTED, timezone.now()
    e.save()
    jobs.enqueue_verification(e)
    pks.append(e.pk)
print(json.dumps(pks))
"""


def django_for_tests():
    """Django in this test process, on a data folder of its own (made once per process, removed at its exit),
    its tables made, mail into Django's test outbox and a fast password hasher (Django's advice for tests;
    the service keeps PBKDF2). Returns the data folder. Both the portal's own tests and tests/ use it."""
    from django.conf import settings
    if settings.configured:
        return settings.DATA_DIR
    import atexit
    import shutil
    import tempfile

    import django
    from django.core.management import call_command
    from django.test.utils import setup_test_environment

    from robotarium_portal.data_folder import prepare
    data = prepare(tempfile.mkdtemp(prefix="robotarium-portal-test-"))
    atexit.register(shutil.rmtree, data, ignore_errors=True)
    os.environ["ROBOTARIUM_PORTAL_DATA"] = str(data)
    os.environ["ROBOTARIUM_PORTAL_HOSTS"] = "testserver,localhost,127.0.0.1"
    os.environ["DJANGO_SETTINGS_MODULE"] = "robotarium_portal.settings"
    django.setup()
    setup_test_environment()   # mail into django.core.mail.outbox
    settings.PASSWORD_HASHERS = ["django.contrib.auth.hashers.MD5PasswordHasher"]
    call_command("migrate", interactive=False, verbosity=0)
    return data


def run_quietly(*command):
    return subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def free_subnet():
    """A private test /24 ("10.250.1") that no address or route on this machine is in; the search starts at
    one of this process's own (two test processes looking at once mostly pick different ones)."""
    used = run_quietly("ip", "-4", "-o", "addr").stdout + run_quietly("ip", "-4", "route").stdout
    start = os.getpid() % len(SUBNETS)
    for subnet in SUBNETS[start:] + SUBNETS[:start]:
        if subnet + "." not in used:
            return subnet
    raise RuntimeError("no free 10.250-254.x.0/24 test subnet here:\n" + used)


def remove_stale_second_hosts():
    """The namespaces and veths make_second_host made in test processes that are gone (killed before their
    clean-up) or in an earlier process with this one's pid."""
    def stale(name, prefix):
        pid = name[len(prefix):]
        if not pid.isdigit() or NAMESPACE_PREFIX + pid in _OPEN:
            return False
        return int(pid) == os.getpid() or not os.path.exists("/proc/" + pid)   # (a pid used again)
    for line in run_quietly("ip", "netns", "list").stdout.splitlines():
        name = line.split()[0] if line.split() else ""
        if name.startswith(NAMESPACE_PREFIX) and stale(name, NAMESPACE_PREFIX):
            run_quietly("ip", "netns", "delete", name)
    for line in run_quietly("ip", "-o", "link").stdout.splitlines():
        name = line.split(":")[1].strip().split("@")[0] if line.count(":") >= 2 else ""
        if name.startswith(VETH_PREFIX) and stale(name, VETH_PREFIX):
            run_quietly("ip", "link", "delete", name)


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
        self.namespace = NAMESPACE_PREFIX + str(os.getpid())
        self.host_address = self.second_address = None   # the veth pair's two ends (make_second_host)
        self.workers = {}
        self.portal = None
        self.postgres = None

    def release_file(self, name):
        """A path for HOLD's release file that its script sees inside a job box too (the data folder is kept
        there; the box's /tmp is its own)."""
        return os.path.join(self.data, "release-%s" % name)

    def make_second_host(self):
        """A network namespace with a veth pair on a /24 no interface here uses: this side host_address, the
        second host second_address. What killed test processes left first goes: a stale pair on the same
        subnet routes the second host's replies into a namespace that is gone (its connections time out)."""
        remove_stale_second_hosts()
        subnet = free_subnet()
        self.host_address, self.second_address = subnet + ".1", subnet + ".2"
        here, there = (VETH_PREFIX + str(os.getpid()))[:15], ("rbs%d" % os.getpid())[:15]
        for command in (["ip", "netns", "add", self.namespace],
                        ["ip", "link", "add", here, "type", "veth", "peer", "name", there],
                        ["ip", "link", "set", there, "netns", self.namespace],
                        ["ip", "addr", "add", self.host_address + "/24", "dev", here],
                        ["ip", "link", "set", here, "up"],
                        ["ip", "-n", self.namespace, "addr", "add", self.second_address + "/24", "dev", there],
                        ["ip", "-n", self.namespace, "link", "set", there, "up"],
                        ["ip", "-n", self.namespace, "link", "set", "lo", "up"]):
            result = run_quietly(*command)
            if result.returncode:
                raise RuntimeError("%s: %s" % (" ".join(command), result.stdout))
        self.veth = here
        _OPEN.add(self.namespace)

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
                       "--database", self.postgres.url(self.host_address), "--data", self.data]
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
        if self.postgres is not None:
            texts.append("--- PostgreSQL's log\n%s" % self.postgres.log())
            texts.append("--- the database now\n%s" % self.state_of_the_queue())
        return "\n".join(texts)

    def state_of_the_queue(self):
        """Every slot, experiment and job of the queue (who holds it, locked until when), for a failure's log."""
        import psycopg
        lines = []
        for title, sql in (
                ("slots: id host pid kind state beats last_heartbeat current_job jobs_done",
                 "SELECT id, host, pid, kind, state, beats, last_heartbeat, current_job, jobs_done "
                 "FROM robotarium_portal_worker ORDER BY id"),
                ("experiments: id state attempts worker_id queued_at started_at",
                 "SELECT id, state, attempts, worker_id, queued_at, started_at FROM robotarium_portal_experiment "
                 "ORDER BY id"),
                ("jobs: id key lock held_by",
                 "SELECT q.id, q.key, q.lock, h.worker_id FROM django_q_ormq q LEFT JOIN robotarium_portal_taskhold h "
                 "ON h.task_id = q.id ORDER BY q.id")):
            try:
                rows = self.postgres.query(sql)
            except psycopg.Error as error:
                rows = [("(%s)" % error,)]
            lines.append(title)
            lines.extend("  " + " ".join(str(v) for v in row) for row in rows)
        return "\n".join(lines)

    def submit(self, items):
        env = dict(self.env(), PASSWORD=PASSWORD, ROBOTARIUM_PORTAL_DATA=self.data,
                   ROBOTARIUM_PORTAL_DATABASE=self.postgres.url(), DJANGO_SETTINGS_MODULE="robotarium_portal.settings",
                   PYTHONPATH=os.pathsep.join([REPO, os.environ.get("PYTHONPATH", "")]))
        result = subprocess.run([sys.executable, "-c", SUBMIT], input=json.dumps(items), env=env, cwd=REPO,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=TIMEOUT)
        assert result.returncode == 0, result.stderr
        return json.loads(result.stdout.strip().splitlines()[-1])

    def experiment(self, pk):
        row = self.query("SELECT state, attempts, detail, results, worker_id FROM "
                                  "robotarium_portal_experiment WHERE id = %s", pk)[0]
        return dict(zip(("state", "attempts", "detail", "results", "worker"), row))

    def page(self, pk):
        """The experiment's page as its owner sees it, through the portal (logged in over HTTP)."""
        import http.cookiejar
        import urllib.parse
        import urllib.request
        base = re.search(r"portal is at (http://\S+)", self.portal.output()).group(1)
        owner = self.query("SELECT u.username FROM robotarium_portal_experiment e JOIN auth_user u "
                           "ON u.id = e.owner_id WHERE e.id = %s", pk)[0][0]   # (its owner sees it)
        jar = http.cookiejar.CookieJar()
        opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(jar))
        form = opener.open(base + "login/", timeout=60).read().decode()
        token = re.search(r'name="csrfmiddlewaretoken" value="([^"]+)"', form).group(1)
        opener.open(urllib.request.Request(base + "login/", data=urllib.parse.urlencode(
            {"csrfmiddlewaretoken": token, "username": owner, "password": PASSWORD}).encode(),
            headers={"Referer": base + "login/"}), timeout=60).read()
        return opener.open(base + "experiments/%d/" % pk, timeout=60).read().decode()

    def query(self, sql, *params):
        """From PostgreSQL, waiting out a restart of it."""
        import psycopg
        deadline = time.monotonic() + TIMEOUT
        while True:
            try:
                return self.postgres.query(sql, *params)
            except psycopg.OperationalError:
                assert time.monotonic() < deadline
                time.sleep(0.3)

    def worker_of(self, pk):
        """The name (host) of the worker that holds the experiment."""
        host, pid = self.query("SELECT w.host, w.pid FROM robotarium_portal_worker w JOIN "
                               "robotarium_portal_experiment e ON e.worker_id = w.id WHERE e.id = %s", pk)[0]
        for name, worker in self.workers.items():
            if worker.process.pid == pid:   # ./robotarium execs the worker: the same process
                return name
        return SECOND_HOST if host == SECOND_HOST else "here"

    def wait_for(self, pk, states, what="", timeout=TIMEOUT):
        deadline = time.monotonic() + timeout
        while True:
            row = self.experiment(pk)
            if row["state"] in states:
                return row
            assert time.monotonic() < deadline, "experiment %d %s, wanted %s %s\n%s" % (
                pk, row, states, what, self.logs())
            time.sleep(0.3)

    def wait_until_idle(self):
        """Every live slot between jobs: a job counts itself done (jobs_done) just after its experiment's last
        state, so counts are read only once no slot is still on a job."""
        deadline = time.monotonic() + TIMEOUT
        while self.query("SELECT id, current_job FROM robotarium_portal_worker WHERE state = 'alive' "
                         "AND current_job <> ''"):
            assert time.monotonic() < deadline, self.logs()
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
        _OPEN.discard(self.namespace)


