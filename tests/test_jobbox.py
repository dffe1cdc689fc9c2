"""Each job in its own box (robotarium_portal/jobbox.py): hostile scripts through the real `./robotarium run`
in a real box (network and mount namespaces, a job account made with useradd, resource limits), each
stopped or refused with its message, and a normal script that still runs and saves its results; one
through the portal's own run path (jobs.run_next), after which the worker runs the next experiment.

Needs root (accounts, namespaces): without it the box cannot isolate, and these tests skip saying so.
Tight limits keep them short; every account, folder and process they make is removed."""
import json
import os
import pwd
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from devtools.rosutil import REPO, processes_on_domain, unique_domain_id
from robotarium_core import script_box
from robotarium_portal import jobbox

pytestmark = [pytest.mark.e2e,
              pytest.mark.skipif(os.geteuid() != 0, reason="a job box isolates only when the service is root "
                                 "(accounts, namespaces); run the tests as root")]

LIMITS = jobbox.Limits(cpu_seconds=6, memory_bytes=3 * 1024 ** 3, file_bytes=20 * 1024 ** 2, processes=200,
                       open_files=256, disk_bytes=60 * 1024 ** 2)
SECRETS = {"ROBOTARIUM_SMTP_PASSWORD": "hunter2-smtp", "DATABASE_URL": "postgresql://svc:hunter2-db@db/portal",
           "DJANGO_SECRET_KEY": "hunter2-django"}
NORMAL = """\
import os
import numpy as np
import rps.robotarium as robotarium
r = robotarium.Robotarium(number_of_robots=2, show_figure=False)
for _ in range(20):
    r.get_poses()
    r.set_velocities(np.arange(2), np.array([[0.05, 0.05], [0.0, 0.0]]))
    r.step()
np.save("saved.npy", np.arange(3))
print("uid", os.getuid(), "secrets", sorted(k for k in os.environ if "hunter2" in os.environ[k]))
print("cpu group", [line.split(":")[2] for line in open("/proc/self/cgroup").read().split() if ":cpu:" in line])
r.call_at_scripts_end()
"""
TAG = "t%d" % (os.getpid() % 100000)


@pytest.fixture(scope="module")
def place():
    root = Path(tempfile.mkdtemp(prefix="robotarium-jobbox-test-"))
    root.chmod(0o711)
    made = []
    yield root, made
    for user in made:
        try:
            jobbox.kill_account(pwd.getpwnam(user).pw_uid)
        except KeyError:
            continue
        jobbox.remove_account(user)
    shutil.rmtree(root, ignore_errors=True)


def new_box(place, name):
    root, made = place
    box = jobbox.JobBox(root / "boxes", TAG + name, LIMITS, keep=[root])
    if box.user not in made:
        made.append(box.user)
    return box


def run_script(place, name, script, timeout=120, prepare=None, extra_files=None):
    """./robotarium run SCRIPT in its own box: (outcome, run.json, output, the box's uid)."""
    root, _ = place
    box = new_box(place, name)
    files = root / ("files-" + name)
    files.mkdir()
    (files / "main.py").write_text(script)
    for path, text in (extra_files or {}).items():
        (files / path).parent.mkdir(parents=True, exist_ok=True)
        (files / path).write_text(text)
    box.prepare(files)
    if prepare:
        prepare(box)
    domain = unique_domain_id()
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", MPLBACKEND="Agg",
               **SECRETS)
    results, output = root / ("results-" + name), root / ("output-%s.txt" % name)
    try:
        outcome = box.run([os.path.join(REPO, "robotarium"), "run", "--lockstep", "--no-video", "--results-dir",
                           str(results), "--bags-dir", str(results), "main.py"], env, output, timeout)
    finally:
        box.clean()
    assert not jobbox.processes_of(box.uid), "the script's processes outlived its job"
    assert not processes_on_domain(domain), "the job's processes outlived it"
    assert not box.folder.exists()
    found = list(results.glob("*/run.json"))
    assert len(found) == 1, "no run.json in %s; the job's %s; the output:\n%s" % (
        results, outcome, output.read_text()[-3000:])   # (once: an empty output and no run.json, cause unknown)
    (run_json,) = found
    return outcome, json.loads(run_json.read_text()), output.read_text(), box.uid


def test_a_normal_script_runs_in_its_box_as_its_own_account_and_saves_its_results(place):
    outcome, run, output, uid = run_script(place, "ok", NORMAL)
    assert run["outcome"] == "completed" and outcome.code == 0 and outcome.notes == [], output
    assert "uid %d secrets []" % uid in output and uid != 0   # demoted, and no service secret in sight
    if os.path.isdir(script_box.CPU_GROUPS):   # its processes share one process's CPU (a cgroup v1 host)
        assert "cpu group ['/robotarium-script-%d']" % uid in output, output
    assert list(Path(place[0]).glob("results-ok/*/data/saved.npy"))   # its data file reached the results


def test_a_fork_bomb_meets_the_process_limit_and_nothing_of_it_is_left(place):
    outcome, run, output, uid = run_script(place, "bomb", "import os\nwhile True:\n    os.fork()\n")
    # Refused at the limit, then stopped: at the limit itself, or when its first process ended (whichever first),
    # or gone by itself (each fork's copy of the run ends at its first refused fork, and ends only itself)
    assert "BlockingIOError: [Errno 11] Resource temporarily unavailable" in output
    assert "the script made more processes than the job's limit (200 processes and threads)" in output
    assert not jobbox.processes_of(uid, []), "processes of the bomb were left: %s" % output[-2000:]
    assert run["outcome"] in ("script_error", "interrupted") and outcome.code is not None   # not the wall time


def test_a_second_job_in_a_box_waits_for_the_first_and_stops_none_of_it(place):
    """One job at a time in a box: a job handed out while another still runs there waits for it;
    before, its prepare() stopped the running job's processes as leftovers of a job before it."""
    first = new_box(place, "shared")
    first.prepare()
    running = subprocess.Popen(["sleep", "60"], user=first.uid)   # the first job's script, as its account
    second = new_box(place, "shared")
    entered = threading.Event()
    threading.Thread(target=lambda: (second.prepare(), entered.set()), daemon=True).start()
    try:
        assert not entered.wait(1.0), "the second job took the box the first still holds"
        assert running.poll() is None, "the second job stopped the first's processes"
    finally:
        first.clean()   # the first job ends: its processes stopped, the box free
    assert entered.wait(10), "the box stayed taken after the first job ended"
    second.clean()
    assert running.wait(timeout=10) != 0


def _namespace_of(pid, own):
    """pid's network namespace ("net:[inode]") once it is not `own`."""
    for _ in range(200):
        netns = os.readlink("/proc/%d/ns/net" % pid)
        if netns != own:
            return netns
        time.sleep(0.01)
    raise AssertionError("no namespace of its own")


def test_an_ended_jobs_namespace_keeps_its_number_until_its_cleanup_is_done():
    """A job's cleanup kills what still runs in its network namespace, found by the namespace's number.
    The kernel gives an ended namespace's number to the next one made: a cleanup that looked up the
    number after its job had ended killed a verification just started on another worker (exit code -9,
    no output; the service's twelve submissions, 2026-11-27). The job's namespace is pinned while its
    cleanup may run: no namespace made meanwhile gets its number, and the cleanup stops nothing else."""
    own = os.readlink("/proc/self/ns/net")
    first = subprocess.Popen(["unshare", "--net", "sleep", "0.3"])
    _namespace_of(first.pid, own)
    netns, pin = jobbox.pin_namespace(first.pid, own)
    assert netns and netns != own and pin is not None
    first.wait()   # the job ended: only the pin holds its namespace now
    others = []
    try:
        for _ in range(20):
            other = subprocess.Popen(["unshare", "--net", "sleep", "30"])
            others.append(other)
            assert _namespace_of(other.pid, own) != netns   # its number stays taken
        assert jobbox.kill_namespace(netns) == 0
        assert all(other.poll() is None for other in others)   # none of them stopped
    finally:
        os.close(pin)
        for other in others:
            other.kill()
            other.wait()


def test_children_the_script_leaves_behind_are_stopped(place):
    script = "import os, time\nif os.fork() == 0:\n    time.sleep(600)\nprint('parent done')\n"
    outcome, run, output, _ = run_script(place, "orphan", script)
    assert "parent done" in output and outcome.code is not None   # it did not wait for the child's 600 s
    assert "the script's process ended leaving 1 processes behind; they were stopped" in output


def test_the_scripts_own_package_never_runs_as_the_service(place):
    """./robotarium's pre-check looks for the modules a script imports: for `import evil.sub` that would
    import evil (the user's code) as the service, before the script is demoted; boxed, it does not."""
    mark = place[0] / "written-by-evil"
    evil = "import os\nopen(%r, 'w').write(str(os.getuid()))\n" % str(mark)
    outcome, run, output, uid = run_script(place, "evil", "import evil.sub\n",
                                           extra_files={"evil/__init__.py": evil, "evil/sub.py": ""})
    assert not mark.exists(), "the user's package ran as uid %s" % mark.read_text()
    assert "PermissionError" in run["detail"]   # it ran, as the script's account, and was refused


def test_filling_the_disk_meets_the_file_size_limit_then_the_exact_disk_quota(place):
    """The quota is the size of the box's tmpfs: the kernel refuses the first byte past it (ENOSPC). The
    watch it replaced let a fast writer reach ~250 MB against a 60 MiB quota before it stopped it."""
    script = """\
import os
written = 0
try:
    with open("big.bin", "wb") as f:
        while True:
            f.write(bytes(1024 ** 2))
            f.flush()
            written += 1024 ** 2
except OSError as error:
    print("one file:", error, flush=True)
try:
    for i in range(30):   # 30 files of 10 MB, each under the file size limit: 300 MB, over the 60 MB quota
        with open("part%d.bin" % i, "wb") as f:
            for _ in range(10):
                f.write(bytes(1024 ** 2))
                f.flush()
                written += 1024 ** 2
except OSError as error:
    try:   # to the last byte: the run's own books share this disk
        with open("rest.bin", "wb", buffering=0) as f:
            while True:
                written += f.write(bytes(4096))
    except OSError:
        pass
    for i in range(300):   # more than a page of output once the disk is full
        print("output once the disk is full, line", i, flush=True)
    print("many files:", error, "after", written, "bytes", flush=True)
    raise
"""
    outcome, run, output, _ = run_script(place, "disk", script)
    assert "one file: [Errno 27] File too large" in output
    assert "wrote a file larger than the job's file size limit (20 MiB)" in output
    refused = re.search(r"many files: \[Errno 28\] No space left on device after (\d+) bytes", output)
    assert refused and int(refused.group(1)) <= LIMITS.disk_bytes, output[-2000:]
    assert "the script filled the job's disk quota (60 MiB); the write was refused" in output
    assert run["outcome"] == "script_error"
    # Its record and its last words reach the run folder, though the books of its run share its full disk
    # (a whole-suite run had no run.json: the runner's and the log's writes were refused too).
    (log,) = (place[0] / "results-disk").glob("*/log.txt")
    assert "many files: [Errno 28] No space left on device" in log.read_text()


def test_allocating_20_gb_is_refused_by_the_memory_limit(place):
    outcome, run, output, _ = run_script(place, "memory", "import numpy as np\nx = np.ones(20 * 10 ** 9, np.uint8)\n")
    assert run["outcome"] == "script_error" and "MemoryError" in run["detail"] and "20" in run["detail"]
    assert "more memory than the job's 3072 MiB limit" in output


def test_a_script_spinning_forever_is_stopped_at_its_cpu_time(place):
    outcome, run, output, _ = run_script(place, "spin", "while True:\n    pass\n")
    assert "killed by SIGXCPU" in run["detail"]
    assert "the script used up its 6 s of CPU time (the job's CPU limit) and was stopped" in output


def test_reading_shadow_another_jobs_folder_or_the_service_data_is_refused(place):
    root, _ = place
    other = new_box(place, "other")
    (root / "files-other").mkdir()
    (root / "files-other" / "main.py").write_text("secret = 'the other job'\n")
    other_work = other.prepare(root / "files-other")
    data = root / "data"
    data.mkdir(mode=0o700)
    (data / "portal.sqlite3").write_text("the service's database")
    targets = ["/etc/shadow", str(other_work / "main.py"), str(data / "portal.sqlite3")]
    script = "import sys\nfor path in %r:\n    try:\n        print('READ', path, open(path).read()[:20])\n" \
             "    except OSError as error:\n        print('REFUSED', path, error)\nopen(%r).read()\n" % (
                 targets, targets[-1])
    try:
        outcome, run, output, _ = run_script(place, "reads", script)
    finally:
        other.clean()
    assert "READ" not in output.replace("[robotarium]", "")
    for path in targets:
        assert "REFUSED %s [Errno 13] Permission denied" % path in output
    assert run["outcome"] == "script_error" and "PermissionError" in run["detail"]
    assert "tried to read or write outside its own folder" in output


def test_the_network_and_the_database_are_out_of_reach(place):
    with socket.socket() as database:   # stands for the database: a TCP server on this machine
        database.bind(("127.0.0.1", 0))
        database.listen()
        database.settimeout(0.2)
        port = database.getsockname()[1]
        accepted, done = [], threading.Event()

        def accept():
            while not done.is_set():
                try:
                    accepted.append(database.accept())
                except OSError:
                    continue

        threading.Thread(target=accept, daemon=True).start()
        script = ("import socket\nfor where in [('127.0.0.1', %d), ('1.1.1.1', 53)]:\n    try:\n"
                  "        socket.create_connection(where, timeout=5)\n        print('CONNECTED', where)\n"
                  "    except OSError as error:\n        print('REFUSED', where, error)\n"
                  "socket.create_connection(('1.1.1.1', 53), timeout=5)\n" % port)
        try:
            outcome, run, output, _ = run_script(place, "net", script)
        finally:
            done.set()
    assert not accepted and "CONNECTED" not in output
    assert "REFUSED ('127.0.0.1', %d) [Errno 111] Connection refused" % port in output
    assert "REFUSED ('1.1.1.1', 53) [Errno 101] Network is unreachable" in output
    assert "the script tried to reach the network; a job has none beyond its own testbed (refused)" in output


def test_through_the_portal_a_hostile_run_fails_with_its_message_and_the_next_one_completes(place, monkeypatch):
    from devtools.service import django_for_tests
    django_for_tests()
    from django.contrib.auth import get_user_model
    from django.test import override_settings

    from robotarium_portal import jobs
    from robotarium_portal.models import Experiment
    root, made = place
    owner = get_user_model().objects.create_user(username="boxed-%s@example.org" % TAG, password="x")
    experiments = []
    for title, script in (("hog", "import numpy as np\nx = np.ones(20 * 10 ** 9, np.uint8)\n"), ("fine", NORMAL)):
        experiment = Experiment.objects.create(owner=owner, title=title, estimated_duration=5, number_of_robots=2,
                                               main_file="main.py", state=Experiment.QUEUED)
        experiment.files_dir.mkdir(parents=True, exist_ok=True)
        (experiment.files_dir / "main.py").write_text(script)
        experiments.append(experiment)
    made.append(jobbox.account_name(jobs.RUN_CLUSTER))   # the portal's run slot's account (removed after)
    domain = unique_domain_id()
    monkeypatch.setenv("ROBOTARIUM_PORTAL_RUN_DOMAIN", str(domain))
    with override_settings(JOB_BOXES_DIR=root / "portal-boxes", JOB_LIMITS=dict(LIMITS.__dict__, cpu_seconds=30)):
        jobs.run_next()
        jobs.run_next()
    hog, fine = experiments
    hog.refresh_from_db()
    fine.refresh_from_db()
    assert hog.state == Experiment.FAILED, hog.detail
    assert "MemoryError" in hog.detail
    assert "The job's box: the script asked for more memory than the job's 3072 MiB limit" in hog.detail
    assert fine.state == Experiment.COMPLETED, fine.detail
    assert (fine.folder / fine.results / "data" / "saved.npy").exists()
    assert not processes_on_domain(domain)


ON_ROBOTS = """\
import numpy as np
import rps.robotarium as robotarium
r = robotarium.Robotarium(number_of_robots=2, show_figure=False,
                          initial_conditions=np.array([[-0.2, 0.2], [0.1, 0.1], [0.0, 0.0]]))
for _ in range(30):
    r.get_poses()
    r.set_velocities(np.arange(2), np.array([[0.05, 0.05], [0.0, 0.0]]))
    r.step()
r.call_at_scripts_end()
"""


def test_through_the_portal_a_run_moves_a_fleet_of_robots(place, monkeypatch):
    """A worker of robots (./robotarium worker --fleet): its run slot's testbed is the fleet's hardware arena
    (supervisor.start_fleet_testbed), the job's box shares the machine's network with it, and the run's folder,
    recorded by that testbed, ends up in the experiment's results."""
    from devtools.service import django_for_tests
    data = django_for_tests()
    from django.contrib.auth import get_user_model
    from django.test import override_settings

    from devtools.rosutil import node_env
    from robotarium_bringup.testbed import testbed_answers
    from robotarium_hardware.sim_fleet import SimulatedFleet
    from robotarium_portal import jobs, supervisor
    from robotarium_portal.models import Experiment
    root, made = place
    domain = unique_domain_id()
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    # (a second for a robot or the tracking to count as gone: the fault bounds are test_own_robots', and a loaded
    # machine holds a stand-in back 60-150 ms)
    fleet = SimulatedFleet(2, "mocap", str(root / "fleet.yaml"), env=node_env(domain), log_dir=str(root),
                           answer_timeout=1.0, lost_after=1.0, lost_behind=1.0)
    fleet.start(say=lambda line: None)
    testbed = None
    try:
        assert fleet.wait_ready(), fleet.failed()
        # where the worker's own testbed records (its data folder's fleet-runs/: the job's box sees that folder)
        testbed = supervisor.start_fleet_testbed(fleet.fleet_file, domain, data / "fleet-runs", root / "fleet-logs")
        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
        assert testbed_answers(timeout=60), testbed.failed()
        owner = get_user_model().objects.create_user(username="robots-%s@example.org" % TAG, password="x")
        experiment = Experiment.objects.create(owner=owner, title="on robots", estimated_duration=5, number_of_robots=2,
                                               main_file="main.py", state=Experiment.QUEUED)
        experiment.files_dir.mkdir(parents=True, exist_ok=True)
        (experiment.files_dir / "main.py").write_text(ON_ROBOTS)
        made.append(jobbox.account_name(jobs.RUN_CLUSTER))
        monkeypatch.setenv("ROBOTARIUM_PORTAL_RUN_DOMAIN", str(domain))
        monkeypatch.setenv(jobs.FLEET_VARIABLE, fleet.fleet_file)
        with override_settings(JOB_BOXES_DIR=root / "portal-boxes", JOB_LIMITS=dict(LIMITS.__dict__, cpu_seconds=30)):
            jobs.run_next()
        experiment.refresh_from_db()
        assert experiment.state == Experiment.COMPLETED, experiment.detail
        results = experiment.folder / experiment.results
        assert (results / "report.txt").exists() and list(results.glob("*.mcap")), list(results.iterdir())
    finally:
        if testbed is not None:
            testbed.stop()
        fleet.stop()


RESIDENT = """\
import socket
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 47001))
while True:
    data, peer = s.recvfrom(100)
    s.sendto(b"resident " + data, peer)
"""
# A job in the slot's network namespace: it reaches the resident (the warm testbed's stand-in), says what it
# sees of the job before it (a UDP port, processes, files), then leaves a process behind that holds a port.
JOB = """\
import os, socket, subprocess, sys, time
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.settimeout(5)
s.sendto(b"%s", ("127.0.0.1", 47001))
print("heard:", s.recvfrom(100)[0].decode())
probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
try:
    probe.bind(("127.0.0.1", 47002))
    print("port 47002 free")
    probe.close()
except OSError as error:
    print("port 47002 taken:", error)
print("processes:", sorted(int(p) for p in os.listdir("/proc") if p.isdigit()))
print("files:", sorted(os.listdir("/tmp")), sorted(os.listdir(os.environ.get("TMPDIR", "/tmp"))))
open("/tmp/left-by-job", "w").write("secret")
subprocess.Popen([sys.executable, "-c", "import socket, time; s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); "
                  "s.bind(('127.0.0.1', 47002)); time.sleep(600)"], start_new_session=True)
time.sleep(0.5)
"""


def test_boxes_in_a_slots_network_namespace_reach_its_resident_and_nothing_of_each_other(place):
    """A verification slot keeps its warm testbed in a network namespace of its own that each verification's box
    joins (jobbox.start_in_network, JobBox(network=...)): the jobs reach what runs there (a UDP echo stands in
    for the testbed), and nothing of one job reaches the next: the process and the port the first left behind
    are gone (stopped with its PID namespace; the cleanup stops what ran there, not what else runs in the shared
    network), its
    files too, and the second sees its own processes only. The resident outlives both jobs."""
    root, _ = place
    with open(root / "resident.txt", "wb") as log:
        resident, network = jobbox.start_in_network([sys.executable, "-c", RESIDENT], dict(os.environ), log)
    try:
        assert network and os.readlink(network) != os.readlink("/proc/self/ns/net")
        outputs = []
        for k in range(2):
            box = new_box(place, "slotnet")
            box.network = network   # (new_box makes a box of the default kind)
            files = root / ("files-slotnet-%d" % k)
            files.mkdir()
            (files / "job.py").write_text(JOB % ("job%d" % k))
            box.prepare(files)
            output = root / ("output-slotnet-%d.txt" % k)
            try:
                outcome = box.run([sys.executable, "job.py"], dict(os.environ), output, 60)
            finally:
                box.clean()
            outputs.append(output.read_text())
            assert outcome.code == 0, outputs[-1]
            assert "heard: resident job%d" % k in outputs[-1], outputs[-1]
            assert resident.poll() is None, "a job's cleanup stopped what runs in the slot's namespace"
        first, second = outputs
        assert "port 47002 free" in first and "port 47002 free" in second, second   # the first's process is gone
        assert "processes: [1, 2]" in second, second   # PID 1 and the job: no other job's, no resident
        assert "files:" in second and "left-by-job" not in second, second   # (the test's own folder is kept in)
    finally:
        jobbox.stop_group(resident.pid, grace=5)
