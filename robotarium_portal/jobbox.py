"""Each job in its own box: one verification or run, isolated from the service and from other jobs.

Plain Python (no Django): the portal's jobs use it; tests use it alone. As root, a box is its own
network namespace (its loopback only), PID namespace (its /proc shows the job's processes only) and
mount namespace (its folder an exact-size tmpfs, the disk quota, which also holds its /tmp, /var/tmp,
/dev/shm and the service's home; the repository's recordings and logs hidden); its folder is its
own account's; the user's script alone runs as that account with resource limits
(robotarium_core.script_box); the environment keeps named variables only. A service that is not
root says what of this holds (isolation()). docs/portal.md has the isolation table.
"""
import ctypes
import fcntl
import json
import os
import pwd
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

ACCOUNT_PREFIX = "robotarium-job-"
# What a job's environment keeps of the service's: the run's own needs, nothing else.
ENVIRONMENT = ("PATH", "HOME", "LANG", "LC_ALL", "LC_CTYPE", "TZ", "TERM", "PYTHONPATH", "PYTHONUNBUFFERED",
               "LD_LIBRARY_PATH", "VIRTUAL_ENV", "AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH", "RMW_IMPLEMENTATION",
               "MPLBACKEND", "ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS",
               "ROBOTARIUM_ROOT", "ROBOTARIUM_PROGRESS", "ROBOTARIUM_RPS", "ROBOTARIUM_PYTHON",
               "ROBOTARIUM_WARM_VERIFICATION",   # (verify takes it out of its environment: the script never sees it)
               "ROBOTARIUM_LIVE_VIDEO")   # (a service may turn it off for its runs: robotarium_recording.live_video)
SHARED_TMP = ("/tmp", "/var/tmp", "/dev/shm")
# The repository's folders of runs and logs (other people's `./robotarium run` on this machine): empty in a box.
PRIVATE_IN_REPOSITORY = ("bags", "log", "results", "service")
WATCH_PERIOD = 0.5   # s between two looks at the script's processes
NOTE = "[job box] "
SPEC_VARIABLE = "ROBOTARIUM_JOB_BOX"   # the door's spec (JSON), in its environment only


@dataclass(frozen=True)
class Limits:
    """A job's limits (the portal's settings hold the values, once)."""
    cpu_seconds: int    # of the script's process (RLIMIT_CPU; SIGXCPU, then SIGKILL)
    memory_bytes: int   # of the script's address space (RLIMIT_AS): a larger allocation fails
    file_bytes: int     # the largest file the script may write (RLIMIT_FSIZE)
    processes: int      # processes and threads of the job's account (RLIMIT_NPROC)
    open_files: int     # (RLIMIT_NOFILE)
    disk_bytes: int     # everything the job writes in its box: the size of its folder's tmpfs

    def script_limits(self):
        return {k: v for k, v in asdict(self).items() if k != "disk_bytes"}


@dataclass
class Outcome:
    code: int | None   # the command's exit code; None when the box stopped it at its wall-time limit
    notes: list        # sentences for the experiment's page: what the box stopped or refused, and why


def _mb(n):
    return "%g MiB" % round(n / 1024 ** 2, 1)


def isolated():
    return os.geteuid() == 0


def isolation():
    """One line on what this service's boxes hold (the worker says it on start)."""
    if isolated():
        from robotarium_core import script_box
        return ("job boxes: each job in its own network, PID and mount namespace (an exact disk quota), its script "
                "as an account of its own with resource limits%s, a scrubbed environment" % (
                    " and one process's share of the CPU" if os.path.isdir(script_box.CPU_GROUPS) else ""))
    return ("job boxes: the service is not root (uid %d): no accounts, so each job's script runs AS THE SERVICE "
            "(it can read what the service can); resource limits (no process limit) and a scrubbed environment "
            "hold; the namespaces (network, PID, the disk quota) only where the kernel lets a user namespace make "
            "them" % os.geteuid())


def account_name(name):
    name = re.sub(r"[^a-z0-9-]", "-", name.lower())
    return (ACCOUNT_PREFIX + name)[:32]


def ensure_account(user):
    """(uid, gid) of the job account, made when missing (a system account: no home, no log-in)."""
    try:
        entry = pwd.getpwnam(user)
    except KeyError:
        subprocess.run(["useradd", "--system", "--user-group", "--no-create-home", "--home-dir", "/nonexistent",
                        "--shell", "/usr/sbin/nologin", user], check=True, capture_output=True)
        entry = pwd.getpwnam(user)
    return entry.pw_uid, entry.pw_gid


def remove_account(user):
    from robotarium_core import script_box
    try:
        uid = pwd.getpwnam(user).pw_uid
    except KeyError:
        return
    subprocess.run(["userdel", user], capture_output=True)
    script_box.remove_cpu_group(uid)


def scrubbed(env):
    return {k: v for k, v in env.items() if k in ENVIRONMENT}


# -- the processes of an account ----------------------------------------------------------------------

def _status(pid):
    fields = {}
    try:
        with open("/proc/%s/status" % pid) as f:
            for line in f:
                key, _, value = line.partition(":")
                if key in ("Uid", "PPid", "Threads"):
                    fields[key] = int(value.split()[0])
                elif key == "State":
                    fields[key] = value.split()[0]
    except (OSError, ValueError, IndexError):
        return None
    return fields


def processes_of(uid, tasks=None):
    """{pid: parent pid} of every live process whose real uid is uid. tasks (a list): gets the number of
    tasks the kernel's process limit counts for uid (threads, and zombies not yet reaped)."""
    found, count = {}, 0
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            status = _status(entry)
            if status and status.get("Uid") == uid:
                count += status.get("Threads", 1)
                if status.get("State") != "Z":   # a zombie is gone already
                    found[int(entry)] = status["PPid"]
    if tasks is not None:
        tasks.append(count)
    return found


def kill_account(uid):
    """SIGKILL every process of uid (a fork bomb's children included); returns how many there were.
    kill(-1) from a child that became uid reaches all of them in one go, so none forks a new one meanwhile;
    the child never execs, so the account's process limit cannot stop it."""
    before = len(processes_of(uid))
    for _ in range(50):
        if not processes_of(uid):
            break
        with warnings.catch_warnings():   # "fork in a threaded process": the child makes two system calls only
            warnings.simplefilter("ignore", DeprecationWarning)
            child = os.fork()
        if child == 0:   # pragma: no cover - the child: only system calls, then out
            try:
                os.setresuid(uid, uid, uid)
                os.kill(-1, signal.SIGKILL)
            finally:
                os._exit(0)
        os.waitpid(child, 0)
        time.sleep(0.05)   # the killed are reaped by their parents (or init)
    return before


def in_namespace(netns, kind="net"):
    """The pids of the processes in the namespace netns (their /proc/PID/ns/<kind> link: "net", or "pid")."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                if os.readlink("/proc/%s/ns/%s" % (entry, kind)) == netns:
                    found.append(int(entry))
            except OSError:
                continue
    return found


def pin_namespace(pid, own, link="net"):
    """(identity, descriptor) of process pid's network namespace ("net:[inode]"), the namespace held
    open: it lives while a descriptor of it is open, so its number cannot pass to a namespace made
    later. Without the pin a job's cleanup (kill_namespace) once killed a job that had just started on
    another worker: the ended job's namespace was gone and the new one had been given its number.
    (None, None) while pid still shares `own` (the door has not made its namespace yet), or is gone.
    link "pid_for_children": the PID namespace the door made for the job (a box that joins a slot's network
    namespace is told from what else runs there by it)."""
    try:
        fd = os.open("/proc/%d/ns/%s" % (pid, link), os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None, None
    netns = os.readlink("/proc/self/fd/%d" % fd)
    if netns == own:
        os.close(fd)
        return None, None
    return netns, fd


def kill_namespace(netns, kind="net"):
    """SIGKILL whatever still runs in a job's network namespace once its command ended (a testbed node
    whose command line was killed): every process of the job is in it. How many there were. kind "pid":
    netns is the job's PID namespace (a box in a slot's network namespace, which others share)."""
    before = len(in_namespace(netns, kind))
    for _ in range(50):
        pids = in_namespace(netns, kind)
        if not pids:
            break
        for pid in pids:
            try:
                fd = os.pidfd_open(pid)
            except OSError:
                continue
            try:
                if os.readlink("/proc/%d/ns/%s" % (pid, kind)) == netns:
                    signal.pidfd_send_signal(fd, signal.SIGKILL)
            except OSError:
                pass
            finally:
                os.close(fd)
        time.sleep(0.05)
    return before


# -- what stopped the script: its limits as the log shows them ------------------------------------------

def explain(log, limits, network):
    """The sentences that name the limit or refusal the script met, from what it printed (its log)."""
    notes = []
    checks = [
        (r"SIGXCPU|CPU time limit", "the script used up its %d s of CPU time (the job's CPU limit) and was stopped"
         % limits.cpu_seconds),
        (r"MemoryError|Cannot allocate memory|bad_alloc", "the script asked for more memory than the job's %s "
         "limit (address space); the allocation was refused" % _mb(limits.memory_bytes)),
        (r"File too large|SIGXFSZ", "the script wrote a file larger than the job's file size limit (%s); the write "
         "was refused" % _mb(limits.file_bytes)),
        (r"BlockingIOError: \[Errno 11\]|Resource temporarily unavailable|can't start new thread",
         "the script made more processes than the job's limit (%d processes and threads); the next were refused"
         % limits.processes),
        (r"No space left on device|Disk quota exceeded", "the script filled the job's disk quota (%s); the write "
         "was refused" % _mb(limits.disk_bytes)),
        (r"Too many open files", "the script opened more files than the job's limit (%d); the next were refused"
         % limits.open_files),
        (r"PermissionError|Permission denied", "the script tried to read or write outside its own folder; "
         "the job's account may not (refused)"),
    ]
    if network:
        checks.append((r"Network is unreachable|Connection refused|Name or service not known|"
                       r"Temporary failure in name resolution|No address associated",
                       "the script tried to reach the network; a job has none beyond its own testbed (refused)"))
    for pattern, sentence in checks:
        if re.search(pattern, log):
            notes.append(sentence)
    return notes


def notes_in(output_path):
    """The box's notes in a job's output (what run_command wrote after it), one per line."""
    try:
        with open(output_path, encoding="utf-8", errors="replace") as f:
            return [line[len(NOTE):].strip() for line in f if line.startswith(NOTE)]
    except OSError:
        return []


# -- the box -------------------------------------------------------------------------------------------

class JobBox:
    """The box of one job slot (a worker runs one job a slot at a time): `<root>/<name>/`, its account."""

    def __init__(self, root, name, limits, keep=(), own_network=True, network=None):
        # own_network False: the machine's network (a worker that moves real robots: its testbed's hardware arena
        # talks to them there); the box keeps its mount namespace, folder, account, limits and environment.
        # network: a network namespace to join (a path to it, e.g. /proc/PID/ns/net) instead of one of the job's
        # own: its slot's, where the slot's warm testbed runs (slot_network). Only for a root service (joining
        # a namespace the machine's user namespace owns takes CAP_SYS_ADMIN there); the job's PID and mount
        # namespaces, folder, account and limits stay its own, and its cleanup stops its own processes only.
        self.own_network = own_network
        self.network = network if own_network and isolated() else None
        self.root = Path(root).resolve()
        self.folder = self.root / name
        self.work, self.home, self.tmp = self.folder / "work", self.folder / "home", self.folder / "tmp"
        self.limits = limits
        self.keep = [Path(p) for p in keep]   # more folders the job's command needs (the data folder)
        self.user = account_name(name) if isolated() else pwd.getpwuid(os.geteuid()).pw_name
        self.uid = self.gid = None
        self._held = None   # the box's lock file while a job holds it (prepare .. clean)

    def prepare(self, files_from=None):
        """A fresh folder (files_from's files in work/), owned by the job's account; returns work/. Waits
        while another job holds the box: one job at a time in a box, or the second would stop the first's
        processes as leftovers (kill_account below: a run was killed right after its start while a
        database restart had its worker's cluster handing out work again)."""
        self.root.mkdir(parents=True, exist_ok=True)
        self._held = open(self.root / (self.folder.name + ".lock"), "a")
        fcntl.flock(self._held, fcntl.LOCK_EX)   # let go by clean(), or by the kernel when its holder dies
        if isolated():
            os.chown(self.root, 0, 0)
            self.root.chmod(0o711)   # its boxes reachable by their own accounts, not listable
            self.uid, self.gid = ensure_account(self.user)
            kill_account(self.uid)   # anything a job before it left (a worker killed outright)
        else:
            self.uid, self.gid = os.geteuid(), os.getegid()
        shutil.rmtree(self.folder, ignore_errors=True)
        if files_from is not None:
            shutil.copytree(files_from, self.work, symlinks=False)
        for path in (self.folder, self.work, self.home, self.tmp):
            path.mkdir(exist_ok=True)
        for root, dirs, files in os.walk(self.folder):
            for name in [".", *dirs, *files]:
                path = os.path.join(root, name)
                os.chown(path, self.uid, self.gid)
                os.chmod(path, 0o700 if os.path.isdir(path) else 0o600)
        return self.work

    def environment(self, env):
        from robotarium_core import script_box
        env = scrubbed(env)
        env["TMPDIR"] = str(self.tmp)
        if isolated():
            # Fast DDS's shared memory: the testbed's segments are the service's, the script's account may not
            # write them (localhost-only discovery adds that transport whatever FASTDDS_BUILTIN_TRANSPORTS says).
            # So UDP only, and discovery on the "subnet": in the box's namespace that is its own loopback (on the
            # machine's network, a robots' worker's, discovery stays as the job's environment says).
            env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
            if self.own_network:
                env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
        env[script_box.VARIABLE] = script_box.describe(self.user, self.uid, self.gid, self.home,
                                                       self.limits.script_limits())
        return env

    def entry(self, command):
        """(the command behind the box's door: namespaces made, then the command run (enter()); the door's
        spec, handed in its environment: a command line is every process's to read, the job's too)."""
        home = pwd.getpwuid(os.geteuid()).pw_dir
        repository = os.environ.get("ROBOTARIUM_ROOT") or str(Path(__file__).resolve().parent.parent)
        keep = {os.path.realpath(p) for p in (sys.base_prefix, sys.prefix, repository, self.root, *self.keep)}
        hide = [p for p in (home, *SHARED_TMP) if os.path.isdir(p) and os.path.realpath(p) != "/"]
        private = [os.path.join(repository, p) for p in PRIVATE_IN_REPOSITORY if os.path.isdir(os.path.join(repository, p))]
        spec = {"user_namespace": not isolated(), "hide": hide, "private": private, "keep": sorted(keep),
                "box": str(self.folder), "uid": self.uid, "gid": self.gid, "disk_bytes": self.limits.disk_bytes,
                "own_network": self.own_network, "join_network": self.network}
        return [sys.executable, os.path.abspath(__file__), "enter", "--", *command], json.dumps(spec)

    def run(self, command, env, output_path, timeout, started=None):
        """Run command (in work/) in the box, its output in output_path; started(pid) once it runs.
        Returns an Outcome; the notes are also written at the end of the output, one '[job box]' line each."""
        notes, timed_out = [], False
        with open(output_path, "wb") as output:
            entry, spec = self.entry(command)
            process = subprocess.Popen(entry, cwd=self.work, env=dict(self.environment(env), **{SPEC_VARIABLE: spec}),
                                       stdout=output, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                       process_group=0)
            if started:
                started(process.pid)
            deadline = time.monotonic() + timeout
            # The job's processes: those in its network namespace, or in its PID namespace where it joined one that
            # others share (the slot's warm testbed runs there, and must outlive the job).
            link, kind = ("pid_for_children", "pid") if self.network else ("net", "net")
            own_netns, netns, pin = os.readlink("/proc/self/ns/%s" % kind), None, None
            try:
                while True:
                    try:
                        code = process.wait(timeout=WATCH_PERIOD)
                        break
                    except subprocess.TimeoutExpired:
                        pass
                    if netns is None:   # the door has made the job's namespace (then started the command)
                        netns, pin = pin_namespace(process.pid, own_netns, link)
                    if time.monotonic() > deadline:
                        notes.append("the job did not end within its %d s; it was stopped" % timeout)
                        timed_out = True
                        stop_group(process.pid)
                        code = process.wait()
                        break
                    stopped = self._leftovers(process.pid)
                    if stopped:
                        notes.append(stopped)
                killed = self._stop_script()
                if killed:
                    notes.append("%d processes the script left behind were stopped at the job's end" % killed)
                left = kill_namespace(netns, kind) if netns else 0
                if left:
                    notes.append("%d processes of the job still ran when its command had ended; they were stopped"
                                 % left)
            finally:
                if pin is not None:
                    os.close(pin)
        log = Path(output_path).read_text(errors="replace")
        notes += [n for n in explain(log, self.limits, network=True) if n not in notes]
        with open(output_path, "a") as output:
            output.writelines(NOTE + note + "\n" for note in notes)
        return Outcome(None if timed_out else code, notes)

    def _stop_script(self):
        return kill_account(self.uid) if isolated() else 0

    def _leftovers(self, job_pid):
        """The script's processes, when they reached the job's process limit (a fork bomb: with processes
        dying and forking in turn it would go on) or when their leader (the script's process, a child of
        the job's command) has ended: stopped, and a note saying why. None otherwise."""
        if not isolated():
            return None
        tasks = []
        pids = processes_of(self.uid, tasks)
        if not pids:
            return None
        if tasks[0] >= self.limits.processes:
            return ("the script reached the job's limit of %d processes and threads; all %d of its processes "
                    "were stopped" % (self.limits.processes, kill_account(self.uid)))
        for _pid, parent in pids.items():
            try:
                if parent not in pids and os.getpgid(parent) == job_pid:
                    return None   # the leader still runs
            except OSError:
                continue
        return "the script's process ended leaving %d processes behind; they were stopped" % kill_account(self.uid)

    def _wait_quietly(self, process, timeout):
        try:
            process.wait(timeout=max(0.1, timeout))
        except subprocess.TimeoutExpired:
            pass

    def clean(self):
        """The folder goes; the account's processes too; then the box is free for the next job."""
        if self.uid is not None:
            self._stop_script()
        shutil.rmtree(self.folder, ignore_errors=True)
        if self._held is not None:
            self._held.close()
            self._held = None


def stop_group(pgid, grace=30.0):
    """SIGTERM to the group (./robotarium stops its testbed and writes its results), SIGKILL after grace."""
    for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, 0.0)):
        try:
            os.killpg(pgid, sig)
        except ProcessLookupError:
            return
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline:
            try:
                os.killpg(pgid, 0)
            except ProcessLookupError:
                return
            time.sleep(0.2)


# -- a slot's network namespace -----------------------------------------------------------------------

def start_in_network(command, env, output):
    """Start command (the slot's warm testbed) in a new network namespace of its own, its loopback up, as the
    service: (its Popen, the path of the namespace for JobBox(network=...)). It gets SIGTERM should the
    process that started it die (PR_SET_PDEATHSIG), so it never outlives its slot. Root only."""
    process = subprocess.Popen([sys.executable, os.path.abspath(__file__), "network", "--", *command], env=env,
                               stdout=output, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, process_group=0)
    own = os.readlink("/proc/self/ns/net")
    for _ in range(200):   # until the door has made the namespace
        netns, pin = pin_namespace(process.pid, own)
        if pin is not None:
            os.close(pin)
            return process, "/proc/%d/ns/net" % process.pid
        if process.poll() is not None:
            break
        time.sleep(0.02)
    return process, None


def _network_door(command):
    os.unshare(os.CLONE_NEWNET)
    loopback_up()
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)   # PR_SET_PDEATHSIG
    os.execvp(command[0], command)


# -- the door: run as `python jobbox.py enter SPEC -- COMMAND...` (a fresh process, one thread) ----------

MS_RDONLY, MS_NOSUID, MS_NODEV, MS_NOEXEC, MS_BIND, MS_REC, MS_PRIVATE = 0x1, 0x2, 0x4, 0x8, 0x1000, 0x4000, 0x40000
SIOCGIFFLAGS, SIOCSIFFLAGS, IFF_UP = 0x8913, 0x8914, 0x1
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def _mount(libc, source, target, fstype, flags, data=None):
    if libc.mount(source and source.encode(), target.encode(), fstype and fstype.encode(), flags,
                  data and data.encode()) != 0:
        error = ctypes.get_errno()
        raise OSError(error, "mount %s on %s: %s" % (source or fstype, target, os.strerror(error)))


def loopback_up():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        request = struct.pack("16sH14x", b"lo", 0)
        flags = struct.unpack("16sH14x", fcntl.ioctl(s, SIOCGIFFLAGS, request))[1]
        fcntl.ioctl(s, SIOCSIFFLAGS, struct.pack("16sH14x", b"lo", flags | IFF_UP))


def _box_on_tmpfs(libc, spec):
    """The box folder becomes a tmpfs of exactly the disk quota (the kernel refuses a write past it: ENOSPC),
    with the prepared work/ copied in; its tmp/, shm/ and service-home/ stand for /tmp, /var/tmp, /dev/shm
    and the service's home, so everything the job writes counts against the one quota."""
    box, uid, gid, service = spec["box"], spec["uid"], spec["gid"], os.geteuid()
    prepared = os.open(box, os.O_PATH | os.O_DIRECTORY)
    _mount(libc, "tmpfs", box, "tmpfs", MS_NOSUID | MS_NODEV, "size=%d,mode=0700" % spec["disk_bytes"])
    os.chown(box, uid, gid)
    shutil.copytree("/proc/self/fd/%d/work" % prepared, os.path.join(box, "work"), symlinks=True)
    os.close(prepared)
    for name, mode, owner in (("work", 0o700, uid), ("home", 0o700, uid), ("tmp", 0o1777, service),
                              ("shm", 0o1777, service), ("service-home", 0o711, service)):
        path = os.path.join(box, name)
        os.makedirs(path, exist_ok=True)
        os.chmod(path, mode)
        for root, dirs, files in os.walk(path):
            for entry in [".", *dirs, *files]:
                os.lchown(os.path.join(root, entry), owner, gid if owner == uid else os.getegid())


def enter(spec, command):
    uid, gid = os.geteuid(), os.getegid()
    own_network = spec.get("own_network", True)
    if own_network and spec.get("join_network"):   # the slot's network namespace (its loopback is up already)
        try:
            fd = os.open(spec["join_network"], os.O_RDONLY | os.O_CLOEXEC)
            os.setns(fd, os.CLONE_NEWNET)
            os.close(fd)
            own_network = False
        except OSError as error:   # the slot's namespace is gone: a namespace of the job's own, as ever
            print(NOTE + "the slot's network namespace is gone (%s): the job has one of its own" % error, flush=True)
    flags = ((os.CLONE_NEWNET if own_network else 0) | os.CLONE_NEWNS | os.CLONE_NEWPID
             | (os.CLONE_NEWUSER if spec["user_namespace"] else 0))
    try:
        os.unshare(flags)
    except OSError as error:
        print(NOTE + "no namespaces for this job (%s): it shares this machine's network, processes and files; the "
              "kernel refuses unprivileged user namespaces, or the service lacks the right" % error, flush=True)
        os.execvp(command[0], command)
    if spec["user_namespace"]:   # the same uid inside: the script keeps the service's identity, no more
        with open("/proc/self/setgroups", "w") as f:
            f.write("deny")
        with open("/proc/self/uid_map", "w") as f:
            f.write("%d %d 1" % (uid, uid))
        with open("/proc/self/gid_map", "w") as f:
            f.write("%d %d 1" % (gid, gid))
    libc = ctypes.CDLL(None, use_errno=True)
    _mount(libc, None, "/", None, MS_REC | MS_PRIVATE)   # nothing done here reaches the machine's mounts
    if own_network:
        loopback_up()
    hidden = [os.path.realpath(p) for p in spec["hide"]]
    kept = [(p, os.open(p, os.O_PATH | os.O_DIRECTORY)) for p in spec["keep"] if os.path.isdir(p)]
    _box_on_tmpfs(libc, spec)
    box = os.open(spec["box"], os.O_PATH | os.O_DIRECTORY)   # the box's tmpfs, wherever its path is covered

    def bind_back(covering):
        """The kept folders that lie in `covering` (now covered) bound back where they were."""
        bound = []
        for path, fd in kept:
            if any(path == c or path.startswith(c + "/") for c in covering) and not any(
                    path.startswith(b + "/") for b in bound):   # not inside a folder already bound back
                os.makedirs(path, mode=0o711, exist_ok=True)
                _mount(libc, "/proc/self/fd/%d" % fd, path, None, MS_BIND | MS_REC)
                bound.append(path)

    for path in spec["private"]:   # other runs' recordings and logs: an empty folder of the box's own
        _mount(libc, "tmpfs", path, "tmpfs", MS_NOSUID | MS_NODEV, "size=16m,mode=0755")
    bind_back(spec["private"])   # the service's data folder, where it is the repository's service/
    stand_ins = {"/tmp": "tmp", "/var/tmp": "tmp", "/dev/shm": "shm"}
    for path in hidden:
        _mount(libc, "/proc/self/fd/%d/%s" % (box, stand_ins.get(path, "service-home")), path, None, MS_BIND)
    bind_back(hidden)
    os.chdir(os.path.join(spec["box"], "work"))
    _init(libc, command)


def _init(libc, command):
    """The job's PID namespace: the next process made is its PID 1 (with a /proc of its own: the job's
    processes only), which runs the command and reaps whatever the command leaves to it; when PID 1 ends, the
    kernel stops everything left in the namespace. The door waits and ends as PID 1 ended. Stop signals reach
    the command through its process group; the door and PID 1 let them pass."""
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    first = os.fork()
    if first == 0:   # PID 1 of the job
        _mount(libc, "proc", "/proc", "proc", MS_NOSUID | MS_NODEV | MS_NOEXEC)
        child = os.fork()
        if child == 0:
            for sig in STOP_SIGNALS:
                signal.signal(sig, signal.SIG_DFL)
            os.execvp(command[0], command)
        # PID 1 leaves the job's process group (the command stays in it): a process the script left behind,
        # reparented to PID 1, has no parent in the group any more, so the box's watch sees it left behind.
        os.setpgid(0, 0)
        while True:
            pid, status = os.wait()
            if pid == child:
                code = os.waitstatus_to_exitcode(status)
                os._exit(code if code >= 0 else 128 - code)   # killed by signal N: 128 + N, as a shell says
    _, status = os.waitpid(first, 0)
    code = os.waitstatus_to_exitcode(status)
    if code < 0:   # PID 1 killed (SIGKILL to the job's group): so is the door
        signal.signal(-code, signal.SIG_DFL)
        os.kill(os.getpid(), -code)
    sys.exit(code)


if __name__ == "__main__":
    if sys.argv[1:3] == ["network", "--"] and len(sys.argv) > 3:
        _network_door(sys.argv[3:])
    if len(sys.argv) < 4 or sys.argv[1:3] != ["enter", "--"] or SPEC_VARIABLE not in os.environ:
        sys.exit("usage: %s=SPEC_JSON python jobbox.py enter -- COMMAND... (the job box's door; see its docstring)"
                 % SPEC_VARIABLE)
    enter(json.loads(os.environ.pop(SPEC_VARIABLE)), sys.argv[3:])   # the command gets no spec
