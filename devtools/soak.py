"""The soak (issue 41): one testbed started as `./robotarium up` starts it, driven for many runs with faults
injected at random (seeded), each run through `./robotarium run --no-local-testbed`, and every run's end
checked against the fault injected into it. bench/bench_soak.py prints what it found; tests/test_soak.py runs
a short one and asserts that no run was lost.

The runs: a mix of the guide's listings (examples/guide/) and the Robotarium simulator 2.1.0's examples
(examples/rps2/), numpy seeded as devtools/run_seeded.py does, in lockstep and in real time, short and long
(long loops shortened with run_seeded's --set, as tests/test_safe_scripts.py and tests/test_rps2_examples.py
do); each from a copy of the examples in the soak's own folder (a data-saving listing writes beside itself).

The faults, each logged with the run it went into:
  client_sigkill  SIGKILL to the script's process (robotarium_cli.runner) at a random step of its run
  run_sigint      SIGINT to `./robotarium run` (Ctrl-C) at a random step
  run_sigkill     SIGKILL to `./robotarium run` at a random step (the next `run` finishes its folder)
  flood           devtools/flood.py during the run: foreign, malformed and forged arrays (the run's token
                  copied off the wire) on both command topics
  kill:NODE       SIGKILL to the simulator, the safety node or the recorder at a random step; `up` restarts the
                  node (its supervisor) and the soak waits for it to be ready again (a node restart, counted); a
                  testbed that stopped instead is started again, counted as unexpected
  freeze:NODE     SIGSTOP to the node for FREEZE seconds (longer than node_lease and client_lease), SIGCONT; the
                  run ends naming the node, or (a client that heard it back in time) completes whole
  disk_full       the recorder's bags folder on a small tmpfs for one run (root only; else skipped, saying so)
The node faults come about every `node_every` runs, the disk once, the others at random; each kind comes at
least once where there are runs enough.

Each run's end is read from its run.json (robotarium_core.run_record.read) and its report.txt, and judged:
  completed   no fault (or one that came after its run's experiment ended): outcome completed, exit code 0,
              the recording whole
  by fault    the fault hit the run, and run.json names that fault's true cause (EXPECTED below)
  lost        anything else: no run folder, no run.json, a run that hung, another cause than the fault's, or
              a run with no fault that did not complete
"""
import dataclasses
import glob
import json
import os
import platform
import random
import re
import shutil
import signal
import subprocess
import sys
import threading
import time

from devtools import REPO
from devtools.rosutil import node_env, processes_on_domain, unique_domain_id

NAMESPACE = "/robotarium"
NODES = {"simulator": "robotarium_sim.simulator_node", "safety": "robotarium_safety.safety_node",
         "recorder": "robotarium_recording.recorder_node"}
RUN_SEEDED = os.path.join(REPO, "devtools", "run_seeded.py")
EXAMPLES = os.path.join(REPO, "examples")
CLIENT_FAULTS = ("client_sigkill", "run_sigint", "run_sigkill", "flood")
NODE_FAULTS = tuple("%s:%s" % (kind, node) for kind in ("kill", "freeze") for node in NODES)
FREEZE = 3.0          # s a frozen node stays stopped: node_lease (0.75 s) twice over and client_lease (2 s)
RUN_TIMEOUT = 300.0   # s a run may take from its start to its exit before it counts as hung
UP_TIMEOUT = 120.0    # s for `up` to say its three nodes are ready
TMPFS_SIZE = "256k"   # the full disk: a bag of a long 10-robot run outgrows it near step 800


# -- the scripts --------------------------------------------------------------------------------------------

@dataclasses.dataclass
class Script:
    path: str          # relative to examples/
    api: str           # "guide" or "2.x"
    iterations: bool   # a top-level `iterations = N` line (run_seeded --iterations sets it)
    sets: tuple = ()   # run_seeded --set NAME=VALUE for a short run of a loop with no iteration count
    args: tuple = ()   # the script's own arguments
    robots: int = 0    # its N, where the file says (the disk-full run wants many)


# Loops without an iteration count, read shorter for a short run (a coarser grid, fewer rounds): the tests'.
SHORTER = {"rps2/sensors/sensor_readings.py": ("resolution_x=1.2", "resolution_y=0.6"),
           "rps2/plotting/dead_reckoning_with_plotting.py": ("final_count=1",),
           "rps2/plotting/barriers_with_plotting.py": ("count=2",),
           "guide/3_5_1_single_integrator_barrier_certificate.py": ("num_cycles=1",),
           "guide/3_8_1_circle_switch_positions_with_plotting.py": ("num_cycles=1",)}
SCRIPT_ARGS = {"rps2/state_estimation/extended_kalman_filter/ekf_experiment.py": ("--cycles", "1")}
# Loops of 70-150 s of testbed time even shortened (2000-4000 steps; a stuck robot never ends): lockstep only.
LOCKSTEP_ONLY = {"rps2/state_estimation/extended_kalman_filter/ekf_experiment.py", "rps2/sensors/distance_sensor_avoidance.py"}
# Iterations of a run by mode and length (scripts with an iteration count): lockstep at a few hundred steps
# a second, real time at 30.
ITERATIONS = {("lockstep", "short"): 120, ("lockstep", "long"): 1000,
              ("real-time", "short"): 60, ("real-time", "long"): 240}


def catalog():
    """Every guide listing and every 2.x example (but the EKF's module), as Scripts."""
    scripts = []
    for api, folder in (("guide", "guide"), ("2.x", "rps2")):
        for path in sorted(glob.glob(os.path.join(EXAMPLES, folder, "**", "*.py"), recursive=True)):
            rel = os.path.relpath(path, EXAMPLES)
            if rel.endswith("uni_ekf.py"):   # a module ekf_experiment.py imports
                continue
            with open(path) as f:
                source = f.read()
            robots = re.search(r"(?m)^N *= *(\d+)", source)
            scripts.append(Script(rel, api, "\niterations = " in source, SHORTER.get(rel, ()),
                                  SCRIPT_ARGS.get(rel, ()), int(robots.group(1)) if robots else 0))
    return scripts


# -- the plan -----------------------------------------------------------------------------------------------

@dataclasses.dataclass
class Planned:
    n: int                 # 1, 2, ...
    script: Script
    mode: str              # "lockstep" or "real-time"
    length: str            # "short" or "long"
    fault: str = ""        # "" or a kind above
    at_step: int = 0       # the step of its experiment at which the fault is injected (mid-run faults)
    iterations: int = 0    # the script's iteration count read as this (scripts that have one)

    def run_seeded_args(self):
        """run_seeded.py's arguments before SEED SCRIPT: how long this run is. A loop with no iteration
        count runs shortened in real time (a coarse grid of goals takes minutes at 30 Hz)."""
        args = []
        if self.script.iterations:
            args += ["--iterations", str(self.iterations)]
        elif self.length == "short" or self.mode == "real-time":
            args += [a for s in self.script.sets for a in ("--set", s)]
        return args


def plan(runs, seed, node_every=50, real_time=0.3, long=0.3, client_faults=0.16, disk=True, node_faults=None,
         iterations=None, leave_out=(), real_time_uncounted=True):
    """The runs of a soak, drawn from `seed`: a node fault about every `node_every` runs (kill and freeze
    in turn, the node at random), the full disk once (if `disk`), a client fault or a flood in about
    `client_faults` of the other runs, each client fault at least once where there are runs enough
    (node_faults: the node faults to take in turn instead, e.g. ["kill:safety", "freeze:recorder"]); a run
    with a fault runs long enough to be hit: a script with an iteration count, long. iterations: {(mode,
    length): count} in place of ITERATIONS (a fault's step is drawn from the first 40 % of a long run).
    leave_out: scripts (paths under examples/) not drawn. real_time_uncounted: whether a loop with no iteration
    count may run in real time (shortened, it still runs to its end at 30 Hz: 15-25 s)."""
    iterations = {**ITERATIONS, **(iterations or {})}
    rng = random.Random(seed)
    scripts = [s for s in catalog() if s.path not in leave_out]
    plans = [Planned(n, rng.choice(scripts), "real-time" if rng.random() < real_time else "lockstep",
                     "long" if rng.random() < long else "short") for n in range(1, runs + 1)]
    for p in plans:   # loops of minutes at 30 Hz run in lockstep (the same draws otherwise)
        if p.mode == "real-time" and (p.script.path in LOCKSTEP_ONLY
                                      or not (real_time_uncounted or p.script.iterations)):
            p.mode = "lockstep"
    free = list(range(1, runs))   # (the first run never has a fault: the baseline of the nodes' sizes)
    rng.shuffle(free)
    # node faults: one in each stretch of node_every runs, kill and freeze in turn
    kinds = ["kill", "freeze"]
    for k, first in enumerate(range(0, runs, node_every)):
        stretch = [i for i in free if first <= i < min(runs, first + node_every)]
        if not stretch:
            continue
        i = stretch[0]
        free.remove(i)
        plans[i].fault = node_faults[k % len(node_faults)] if node_faults else "%s:%s" % (
            kinds[k % 2], rng.choice(sorted(NODES)))
    # the full disk once and each client fault at least once, early (the first quarter, the first 50 runs at
    # most): a soak cut short by --minutes has them
    early = [i for i in free if i < min(max(2, runs // 4), 50)]
    for kind in (["disk_full"] if disk else []) + list(CLIENT_FAULTS):
        slot = early.pop(0) if early else (free[0] if free else None)
        if slot is not None:
            free.remove(slot)
            plans[slot].fault = kind
    for i in free:
        if rng.random() < client_faults:
            plans[i].fault = rng.choice(CLIENT_FAULTS)
    counted = [s for s in scripts if s.iterations]
    for p in plans:
        if p.fault == "disk_full":   # a long lockstep run of many robots: its bag outgrows the small disk
            many = [s for s in counted if s.robots >= 10] or counted
            p.script, p.mode, p.length = rng.choice(many), "lockstep", "long"
        elif p.fault:
            # a run that lasts (1000 lockstep steps, 240 real-time ones: 8 s), so that the fault comes
            # mid-run: the flood's process has started and matched the testbed by then
            p.script, p.length = rng.choice(counted), "long"
            if p.fault != "flood":
                p.at_step = rng.randint(20, max(21, int(0.4 * iterations[(p.mode, "long")])))
    for p in plans:
        p.iterations = iterations[(p.mode, p.length)]
    return plans


# -- what ends a run, by fault ------------------------------------------------------------------------------

NODE_WORDS = {"simulator": "The simulator is gone", "safety": "The safety node is gone"}
RESTARTED = "testbed node restarted at step"   # a killed simulator's run (robotarium_core.restarts)
RECORDER_RESTARTED = "the recorder was restarted: the recorder exited (killed by SIGKILL)"
NODE_RESTART_WAIT = 60.0   # s for up to restart a killed node and for it to say it is ready


def expected(fault):
    """How a run this fault hit must end: a list of alternatives, each (outcome, exit code, words its cause in
    run.json names, how its recording ended: None whole, else recording_stopped_because, words the first line of
    its report.txt has)."""
    if fault in ("", "flood"):   # (a goal loop that never converges: stopped at the time limit, as it says)
        return [("completed", 0, "", None, "Run completed."),
                ("time_limit", 5, "Stopped at the time limit", None, "Stopped at the time limit")]
    if fault == "client_sigkill":   # the testbed ends it (client_lease), run.json says what killed it
        return [("interrupted", 128 + signal.SIGKILL, "killed by SIGKILL", None, "its client was gone")]
    if fault == "run_sigint":
        return [("interrupted", 128 + signal.SIGINT, "SIGINT", None, "SIGINT")]
    if fault == "run_sigkill":
        return [("interrupted", 128 + signal.SIGKILL, "the loss of ./robotarium run", None,
                 "the loss of ./robotarium run")]
    if fault == "disk_full":
        return [("completed", 4, "", "disk full", "disk full")]
    kind, node = fault.split(":")
    if node == "recorder" and kind == "kill":   # up restarts it; the run goes on, its recording stopped there
        return [("completed", 4, "", RECORDER_RESTARTED, "the recorder was restarted")]
    if node == "recorder":   # the run goes on; its recording stops, or (frozen) the recorder comes back
        return [("completed", 4, "", "the recorder is gone", "the recorder is gone"),
                ("completed", 0, "", None, "Run completed.")]
    if kind == "kill" and node == "safety":   # up restarts it, the simulator arms it again: the run goes on
        return [("completed", 0, "the safety node exited (killed by SIGKILL) and ./robotarium up restarted it", None,
                 "Run completed.")]
    if kind == "kill":   # up restarts it; the run ends naming the restart and the node
        return [("testbed_lost", 4, "the %s exited (killed by SIGKILL) and ./robotarium up restarted it" % node, None,
                 RESTARTED)]
    # Frozen: the run ends naming the node, or, where the client heard the node's presence back before it had
    # confirmed the lapse (a client starved on the loaded machine: a whole-suite run, 2026-11-30), it goes on and
    # completes whole, the testbed having waited (lockstep) or stopped the robots on the command timeout.
    return [("testbed_lost", 4, NODE_WORDS[node], None, NODE_WORDS[node]),
            ("completed", 0, "", None, "Run completed.")]


def wrong_causes(fault, record, report_line, whole):
    """What is wrong with how a run this fault hit says it ended ("" nothing): run.json (a
    run_record.RunRecord) and the first line of its report.txt; whole: whether its bag holds the run from
    step 0 to its end (its closing status)."""
    problems = []
    for outcome, code, words, stopped, report_words in expected(fault):
        wrong = []
        if record.outcome != outcome:
            wrong.append("outcome %s, not %s" % (record.outcome, outcome))
        if record.exit_code != code:
            wrong.append("exit code %s, not %s" % (record.exit_code, code))
        if words and words not in record.detail and not any(words in said for said in record.safety_restarts):
            wrong.append("run.json's cause does not name %r" % words)
        if not (record.recording_stopped_because or "").startswith(stopped or "") or (
                bool(record.recording_stopped_because) != bool(stopped)):
            wrong.append("recording stopped: %s, not %s" % (record.recording_stopped_because, stopped))
        elif stopped and whole:
            wrong.append("it says the recording stopped at step %s (%s), but its bag holds the whole run"
                         % (record.recording_stopped_at_step, stopped))
        if report_words not in report_line:
            wrong.append("report.txt's first line does not name %r" % report_words)
        if not wrong:
            return ""
        problems.append(", ".join(wrong))
    return " / ".join(problems)


def whole_recording(path, run_id, steps):
    """Whether the bag at `path` holds run `run_id` whole: the poses of every step from 0 to `steps` and the
    IDLE status that closed the run. False where there is no bag (a full disk's is gone with its tmpfs)."""
    try:
        from robotarium_recording.bag import Bag
        bag = Bag(path)
        closed = any(s.run_id == run_id and s.state == 0 for s in bag.statuses())
        poses = [int(k) for k in bag.poses().steps]
    except Exception:   # noqa: BLE001 - no bag, or none readable
        return False
    return closed and bool(poses) and poses == list(range(poses[-1] + 1)) and poses[-1] >= steps


# -- the testbed ---------------------------------------------------------------------------------------------

def proc_children(pid):
    """Pids of the processes whose parent is `pid`."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open("/proc/%s/stat" % entry) as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == pid:
                        found.append(int(entry))
            except (OSError, IndexError, ValueError):
                continue
    return found


def cmdline(pid):
    try:
        with open("/proc/%d/cmdline" % pid, "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def sizes(pid):
    """(RSS in MB, open file descriptors, threads) of a process, None where it is gone."""
    try:
        with open("/proc/%d/status" % pid) as f:
            status = dict(line.split(":", 1) for line in f if ":" in line)
        fds = len(os.listdir("/proc/%d/fd" % pid))
        return int(status["VmRSS"].split()[0]) / 1024.0, fds, int(status["Threads"])
    except (OSError, KeyError, ValueError):
        return None


NOTEWORTHY = ("WARN", "ERROR", "recording run", "closed ", "exited", "Traceback")


def _size(path):
    try:
        return os.path.getsize(path)
    except OSError:
        return 0


class Up:
    """`./robotarium up --bags-dir BAGS` (python -m robotarium_cli up) in the soak's folder, on its domain;
    start() again after it stopped is a testbed restart."""

    def __init__(self, work, env):
        self.work, self.env = work, env
        self.bags = os.path.join(work, "bags")
        os.makedirs(self.bags, exist_ok=True)
        self.log_path = os.path.join(work, "up.log")
        self.process = None
        self.starts = 0
        self._log_start = 0
        self.restarts_counted = 0

    def start(self):
        self._log_start = _size(self.log_path)
        self.restarts_counted = 0   # of this start's node restarts (Soak._node_restarted)
        with open(self.log_path, "ab") as log:
            self.process = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "up", "--bags-dir", self.bags],
                                            env=self.env, cwd=self.work, stdout=log, stderr=subprocess.STDOUT,
                                            start_new_session=True)
        self.starts += 1
        deadline = time.monotonic() + UP_TIMEOUT
        while self.log().count(" ready") < 3:
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("./robotarium up did not come up (exit code %s):\n%s"
                                   % (self.process.poll(), self.log()[-3000:]))
            time.sleep(0.1)
        return self

    def log(self, whole=False):
        try:
            with open(self.log_path, "rb") as f:
                if not whole:
                    f.seek(self._log_start)
                return f.read().decode(errors="replace")
        except OSError:
            return ""

    def said_since(self, offset, lines=12):
        """The lines of note the nodes wrote to up's console since `offset` (warnings, errors, the recorder's
        bags, exits): a lost run's summary shows them (CI keeps no temporary folders)."""
        try:
            with open(self.log_path, "rb") as f:
                f.seek(offset)
                text = f.read().decode(errors="replace")
        except OSError:
            return ""
        noted = [line[:400] for line in text.splitlines() if any(word in line for word in NOTEWORTHY)]
        return "\n".join(noted[-lines:])

    def nodes(self):
        """{node name: pid} of the testbed's nodes (the children of up)."""
        found = {}
        if self.process is None or self.process.poll() is not None:
            return found
        for pid in proc_children(self.process.pid):
            line = cmdline(pid)
            for name, module in NODES.items():
                if module in line:
                    found[name] = pid
        return found

    def healthy(self):
        return self.process is not None and self.process.poll() is None and len(self.nodes()) == len(NODES)

    def stop(self):
        if self.process is None:
            return
        if self.process.poll() is None:
            os.kill(self.process.pid, signal.SIGINT)
            try:
                self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.kill(self.process.pid, signal.SIGKILL)
                self.process.wait()


class StatusWatch:
    """The testbed's status as a probe of this process hears it (robotarium_core's latched status topic),
    spun in a thread: per run id, when it was first heard RUNNING, its newest step and its end."""

    KEEP = 50   # run ids remembered

    def __init__(self, domain):
        from devtools.rosutil import RosProbe
        from robotarium_core.topics import STATUS, STATUS_QOS
        from robotarium_msgs.msg import TestbedStatus
        self.probe = RosProbe(domain, name="soak_watch")
        self.lock = threading.Lock()
        self.runs = {}   # run_id: {"running": monotonic, "step": k, "idle": monotonic or None, "end_reason": str}
        self.order = []
        self._running = TestbedStatus.STATE_RUNNING
        self.probe.node.create_subscription(TestbedStatus, "%s/%s" % (NAMESPACE, STATUS), self._heard, STATUS_QOS)
        self._stop = False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self._stop:
            try:
                self.probe.executor.spin_once(timeout_sec=0.1)
            except Exception:   # noqa: BLE001 - a shut-down context at the end
                if self._stop:
                    return
                time.sleep(0.1)

    def _heard(self, msg):
        now = time.monotonic()
        if not msg.run_id:
            return
        with self.lock:
            run = self.runs.get(msg.run_id)
            if run is None:
                if msg.state != self._running:
                    return   # an old run's closing status (latched): not news
                run = self.runs[msg.run_id] = {"running": now, "step": 0, "idle": None, "end_reason": ""}
                self.order.append(msg.run_id)
                for old in self.order[:-self.KEEP]:
                    self.runs.pop(old, None)
                del self.order[:-self.KEEP]
            run["step"] = max(run["step"], int(msg.step))
            if msg.state != self._running and run["idle"] is None:
                run["idle"], run["end_reason"] = now, msg.end_reason

    def started_since(self, since):
        """(run id, its record) of the first run heard RUNNING at or after monotonic `since`, else (None, None)."""
        with self.lock:
            for run_id in self.order:
                run = self.runs.get(run_id)
                if run and run["running"] >= since:
                    return run_id, dict(run)
        return None, None

    def get(self, run_id):
        with self.lock:
            run = self.runs.get(run_id)
            return dict(run) if run else None

    def close(self):
        self._stop = True
        self.thread.join(timeout=2)
        try:
            self.probe.close()
        except Exception:   # noqa: BLE001 - the end of the soak
            pass


# -- one run -------------------------------------------------------------------------------------------------

@dataclasses.dataclass
class Result:
    n: int
    script: str
    mode: str
    length: str
    fault: str
    injected: str = ""          # "" not injected (none, or the run ended first), else what was done
    injected_at_step: int = 0
    run_id: str = ""
    exit_code: int | None = None
    outcome: str = ""
    detail: str = ""
    recording_stopped: str = ""
    safety_restarts: str = ""   # what the run went on through (run.json's safety_restarts)
    report_first_line: str = ""
    folder: str = ""
    verdict: str = ""           # "completed", "by fault", "lost"
    why_lost: str = ""
    output: str = ""            # a lost run's ./robotarium run output, kept in the soak's folder
    testbed_said: str = ""      # a lost run's: what the testbed's nodes logged of note meanwhile (up's console)
    start_latency: float | None = None   # s from the run's process start to its experiment heard RUNNING
    wall: float = 0.0           # s from the run's process start to its exit


class Soak:
    """One testbed (`up`) on a domain of its own in `work`, and the runs of a plan on it."""

    def __init__(self, work, seed=1, keep=False, video=False, say=print, time_limit=150):
        self.work = os.path.abspath(work)
        os.makedirs(self.work, exist_ok=True)
        self.seed, self.keep, self.video, self.say = seed, keep, video, say
        # s of testbed time: a goal loop that never converges (a listing's random goals, now and then) is
        # stopped at it, as the Robotarium stops one at its slot's end; that is no fault of the testbed
        self.time_limit = time_limit
        self.domain = unique_domain_id()
        self.results_dir = os.path.join(self.work, "results")
        self.scripts_dir = os.path.join(self.work, "scripts")
        self.env = node_env(self.domain, ROBOTARIUM_ROOT=self.work, ROBOTARIUM_PROGRESS="0",
                            ROBOTARIUM_NAMESPACE=NAMESPACE)
        if not os.path.isdir(self.scripts_dir):
            shutil.copytree(EXAMPLES, self.scripts_dir)
        self.up = Up(self.work, self.env)
        self.watch = None
        self.results = []
        self.restarts = []          # (after run n, why, expected: False) ./robotarium up started again: it stopped
        self.node_restarts = []     # (after run n, up's line) a node up restarted (its supervisor)
        self.samples = []           # (label, {node: (pid, (rss, fds, threads))})
        self.unfinished = []        # Results whose folder the next run finishes (run_sigkill)
        self.disk_note = ""
        self.log = open(os.path.join(self.work, "soak.jsonl"), "a")

    # -- the testbed

    def start(self):
        self.up.start()
        self.watch = StatusWatch(self.domain)
        return self

    def ensure_testbed(self, after, expected_restart):
        """After a node was killed, wait until up restarted it and it is ready again (counted); start `up` again
        where it stopped (never expected: counted as a testbed restart)."""
        if expected_restart:
            line = self._node_restarted()
            if line:
                self.node_restarts.append((after, line))
        if self.up.healthy():
            return
        expected_restart = False
        why = ""
        if self.up.process.poll() is None:   # up runs but a node is missing: stop it first
            why = "a node is missing (%s) while up runs" % sorted(set(NODES) - set(self.up.nodes()))
            self.up.stop()
        lines = [line for line in self.up.log().splitlines() if "exited" in line or "Traceback" in line]
        why = why or (lines[-1].strip() if lines else "up exited with code %s" % self.up.process.returncode)
        self.restarts.append((after, why, expected_restart))
        self.say("  [testbed] restarting ./robotarium up after run %d: %s" % (after, why))
        self.up.start()

    def _node_restarted(self):
        """up's line saying it restarted a node, once the node said it is ready again ("" if not within
        NODE_RESTART_WAIT s, or up stopped)."""
        deadline = time.monotonic() + NODE_RESTART_WAIT
        while time.monotonic() < deadline and self.up.process.poll() is None:
            log = self.up.log()
            lines = [line for line in log.splitlines() if "; restarted it (restart" in line]
            done = lines and log[log.rindex(lines[-1]):].count(" ready") >= 1
            # (counted by number: after `up` started again its lines say "restart 1" again)
            if done and len(lines) > self.up.restarts_counted:
                self.up.restarts_counted = len(lines)
                return lines[-1].strip()
            time.sleep(0.1)
        return ""

    def sample(self, label):
        self.samples.append((label, {name: (pid, sizes(pid)) for name, pid in sorted(self.up.nodes().items())}))

    def in_place_restarts(self):
        """Lines where a node said it started afresh in the same process (its DDS stall watch, or a lost
        shared-memory port)."""
        return [line.strip() for line in self.up.log(whole=True).splitlines() if "starting afresh" in line]

    # -- the runs

    def run(self, p):
        """Run one Planned run, inject its fault, judge its end; returns its Result."""
        result = Result(p.n, p.script.path, p.mode, p.length, p.fault)
        mounted = False
        if p.fault == "disk_full":
            mounted = self._mount_small_disk()
            if not mounted:
                result.fault = ""   # skipped: said once in disk_note
        script = os.path.join(self.scripts_dir, p.script.path)
        command = [sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--no-verdict",
                   "--results-dir", self.results_dir, "--%s" % p.mode, "--time-limit", str(self.time_limit)]
        if not self.video:
            command.append("--no-video")
        command += [RUN_SEEDED, *p.run_seeded_args(), str(self.seed * 100003 + p.n), script, *p.script.args]
        out_path = os.path.join(self.work, "run.out")
        flood = None
        log_at = _size(self.up.log_path)
        began = time.monotonic()
        with open(out_path, "wb") as out:
            process = subprocess.Popen(command, env=self.env, cwd=os.path.dirname(script), stdout=out,
                                       stderr=subprocess.STDOUT, start_new_session=True)
        try:
            if result.fault == "flood":
                flood = subprocess.Popen([sys.executable, "-m", "devtools.flood", "--namespace", NAMESPACE, "--rate",
                                          "300", "--seconds", "4", "--forge", "--burst", "3", "--huge-every", "200"],
                                         env=self.env, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                         start_new_session=True)
            self._follow(p, result, process, began)
        finally:
            if flood is not None:
                _kill(flood)
                result.injected = result.injected or "flood started"
            if mounted:
                result.injected = "a %s tmpfs under the recorder's bags folder for this run" % TMPFS_SIZE
            if mounted:
                self._unmount()
        result.wall = round(time.monotonic() - began, 3)
        result.exit_code = process.returncode
        with open(out_path, errors="replace") as f:
            output = f.read()
        self._finished_folders(output)
        if result.fault == "run_sigkill" and result.injected:
            self.unfinished.append(result)   # the next run (or status) finishes its folder
            result.verdict = "pending"
        else:
            self._judge(result, output)
        if result.verdict == "lost":   # what ./robotarium run said, kept (run.out is the next run's)
            result.output = os.path.join(self.work, "lost-run-%d.out" % p.n)
            shutil.copyfile(out_path, result.output)
            result.testbed_said = self.up.said_since(log_at)
        return result

    def _follow(self, p, result, process, began):
        """Wait for the run's process, watching its experiment; inject a mid-run fault at its step."""
        run_id = None
        deadline = began + RUN_TIMEOUT
        while process.poll() is None:
            if run_id is None:
                run_id, run = self.watch.started_since(began)
                if run_id is not None:
                    result.run_id = run_id
                    result.start_latency = round(run["running"] - began, 3)
            if run_id is not None and p.at_step and not result.injected:
                run = self.watch.get(run_id)
                if run and run["idle"] is None and run["step"] >= p.at_step:
                    result.injected, result.injected_at_step = self._inject(p.fault, process), run["step"]
                elif run and run["idle"] is not None:
                    p.at_step = 0   # ended before the fault's step: it runs as if no fault came
            if time.monotonic() > deadline:
                result.why_lost = "hung: no exit within %.0f s" % RUN_TIMEOUT
                os.killpg(process.pid, signal.SIGINT)
                try:
                    process.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    os.killpg(process.pid, signal.SIGKILL)
                break
            time.sleep(0.02)
        process.wait()
        if result.run_id == "":
            run_id, run = self.watch.started_since(began)
            if run_id is not None:
                result.run_id = run_id
                result.start_latency = round(run["running"] - began, 3)

    def _inject(self, fault, process):
        """Do it; returns what was done (logged)."""
        if fault == "client_sigkill":
            runner = [pid for pid in proc_children(process.pid) if "robotarium_cli.runner" in cmdline(pid)]
            if not runner:
                return ""
            os.kill(runner[0], signal.SIGKILL)
            return "SIGKILL to the script's process %d" % runner[0]
        if fault == "run_sigint":
            os.kill(process.pid, signal.SIGINT)
            return "SIGINT to ./robotarium run %d" % process.pid
        if fault == "run_sigkill":
            os.kill(process.pid, signal.SIGKILL)
            return "SIGKILL to ./robotarium run %d" % process.pid
        kind, node = fault.split(":")
        pid = self.up.nodes().get(node)
        if pid is None:
            return ""
        if kind == "kill":
            os.kill(pid, signal.SIGKILL)
            return "SIGKILL to the %s %d" % (node, pid)
        os.kill(pid, signal.SIGSTOP)
        time.sleep(FREEZE)
        os.kill(pid, signal.SIGCONT)
        return "SIGSTOP to the %s %d for %.1f s, then SIGCONT" % (node, pid, FREEZE)

    def _mount_small_disk(self):
        if os.geteuid() != 0:
            self.disk_note = "disk_full skipped: mounting a small tmpfs under the recorder needs root"
            return False
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=%s" % TMPFS_SIZE, "tmpfs", self.up.bags],
                              stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            self.disk_note = "disk_full skipped: cannot mount a tmpfs here: %s" % done.stderr.strip()
            return False
        return True

    def _unmount(self):
        for _ in range(50):   # the recorder may still hold the bag it wrote: lazily, then wait
            if subprocess.run(["umount", "-l", self.up.bags], stderr=subprocess.DEVNULL).returncode == 0:
                return
            time.sleep(0.1)

    def _finished_folders(self, output):
        """A run whose ./robotarium run was killed is finished by the next run: judge it now."""
        if not self.unfinished:
            return
        for result in list(self.unfinished):
            if self._folder_of(result.run_id) or "its folder is finished now" in output:
                self.unfinished.remove(result)
                self._judge(result, "")

    def finish_unfinished(self):
        """`./robotarium status` finishes what the last run left (as the next run would)."""
        if self.unfinished:
            subprocess.run([sys.executable, "-m", "robotarium_cli", "status"], env=self.env, cwd=self.work,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=120)
            for result in list(self.unfinished):
                self.unfinished.remove(result)
                self._judge(result, "")

    def _folder_of(self, run_id):
        """The run folder whose run.json has this run id (bags/ for recorded runs, results/ for the rest)."""
        if not run_id:
            return ""
        for base in (self.up.bags, self.results_dir):
            direct = os.path.join(base, run_id, "run.json")
            if os.path.isfile(direct):
                return os.path.dirname(direct)
            for path in glob.glob(os.path.join(base, "*", "run.json")):
                try:
                    with open(path) as f:
                        if ('"run_id": "%s"' % run_id) in f.read():
                            return os.path.dirname(path)
                except OSError:
                    continue
        return ""

    def _judge(self, result, output):
        from robotarium_core import run_record
        folder = self._folder_of(result.run_id)
        if not folder:
            folder = _named_folder(output)
        record = run_record.read(folder) if folder else None
        result.folder = folder
        if record is not None:
            result.outcome, result.detail = record.outcome, record.detail
            result.recording_stopped = record.recording_stopped_because or ""
            result.safety_restarts = "; ".join(record.safety_restarts)
            if result.exit_code is None or result.fault == "run_sigkill":
                result.exit_code = record.exit_code
        try:
            with open(os.path.join(folder, "report.txt"), errors="replace") as f:
                result.report_first_line = f.readline().strip()
        except OSError:
            pass
        fault = result.fault if result.injected or result.fault == "disk_full" else ""
        if result.why_lost:
            result.verdict = "lost"
        elif record is None:
            result.verdict, result.why_lost = "lost", ("no run folder with run.json" if not folder else
                                                       "no readable run.json in %s" % folder)
        elif not os.path.isfile(os.path.join(folder, "report.txt")) or not os.path.isfile(
                os.path.join(folder, "index.html")):
            result.verdict, result.why_lost = "lost", "its results are missing (report.txt, index.html)"
        else:
            if fault == "disk_full" and not result.recording_stopped:
                fault = ""   # the run ended before the disk filled: a run like any other
            if fault == "flood":
                fault = ""   # a flood must change nothing
            wrong = wrong_causes(fault, record, result.report_first_line,
                                 whole_recording(record.recording, record.run_id, record.steps)
                                 if record.recording_stopped_because else False)
            if wrong:
                result.verdict = "lost"
                result.why_lost = wrong
            else:
                result.verdict = "by fault" if fault else (
                    "time limit" if record.outcome == "time_limit" else "completed")
        if result.fault == "flood" and record is not None:
            dropped = sum(sum(v.values()) for v in (record.dropped or {}).values() if isinstance(v, dict))
            result.injected = "flood: %d arrays dropped by the testbed" % dropped if dropped else result.injected
        self.log.write(json.dumps(dataclasses.asdict(result)) + "\n")
        self.log.flush()
        if result.verdict != "lost" and not self.keep and folder and os.path.isdir(folder):
            shutil.rmtree(folder, ignore_errors=True)

    # -- the whole soak

    def soak(self, plans, sample_every=100, progress=25, minutes=None):
        """Run the plans in order (no new one after `minutes`, if given); returns the Results (in self.results)."""
        started = time.monotonic()
        for p in plans:
            if minutes and time.monotonic() - started > 60.0 * minutes:
                self.say("  %.0f minutes are up: %d of the %d runs planned ran" % (minutes, p.n - 1, len(plans)))
                break
            self.ensure_testbed(p.n - 1, self._killed_before(p.n))
            result = self.run(p)
            self.results.append(result)
            if p.n == 1 or p.n % sample_every == 0:
                self.sample("run %d" % p.n)
            if result.injected or result.verdict == "lost" or (progress and p.n % progress == 0):
                self.say("  run %d/%d %-60s %-9s %-5s %s -> %s%s (%.0f s in)" % (
                    p.n, len(plans), result.script, result.mode, result.length,
                    ("fault %s: %s" % (result.fault, result.injected or "not injected (the run ended first)"))
                    if result.fault else "no fault", result.verdict or "pending",
                    (": " + result.why_lost) if result.why_lost else "", time.monotonic() - started))
        last = len(self.results)
        self.ensure_testbed(last, self._killed_before(last + 1))
        self.finish_unfinished()
        if not self.samples or self.samples[-1][0] != "run %d" % last:
            self.sample("end (run %d)" % last)
        return self.results

    def _killed_before(self, n):
        """Whether the run before run n killed a node (up then stopped the testbed, as it should)."""
        previous = [r for r in self.results if r.n == n - 1]
        return bool(previous and previous[0].fault.startswith("kill:") and previous[0].injected)

    def close(self):
        """Stop everything the soak started; nothing of it stays running."""
        if self.watch is not None:
            self.watch.close()
        self.up.stop()
        if os.path.ismount(self.up.bags):
            self._unmount()
        for pid in processes_on_domain(self.domain):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.log.close()


def _named_folder(output):
    found = re.findall(r"results in (\S+) \(open", output or "")
    return found[-1] if found and os.path.isdir(found[-1]) else ""


def _kill(process):
    if process.poll() is None:
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    process.wait()


# -- what it found -------------------------------------------------------------------------------------------

def machine():
    return "%s, %s, %d cores, Python %s" % (platform.node(), platform.machine(), os.cpu_count() or 0,
                                            platform.python_version())


def load():
    return "load average %.2f %.2f %.2f" % os.getloadavg()


def percentile(values, q):
    values = sorted(values)
    if not values:
        return None
    return values[min(len(values) - 1, int(round(q / 100.0 * (len(values) - 1))))]


def summary(soak, plans):
    """What the soak found, as lines to print."""
    results = soak.results
    lines = []
    modes = {m: sum(r.mode == m for r in results) for m in ("lockstep", "real-time")}
    lengths = {x: sum(r.length == x for r in results) for x in ("short", "long")}
    apis = {a: sum(r.script.startswith(a) for r in results) for a in ("guide", "rps2")}
    lines.append("runs: %d (lockstep %d, real time %d; short %d, long %d; guide listings %d, 2.x examples %d)"
                 % (len(results), modes["lockstep"], modes["real-time"], lengths["short"], lengths["long"],
                    apis["guide"], apis["rps2"]))
    completed = [r for r in results if r.verdict == "completed"]
    by_fault = [r for r in results if r.verdict == "by fault"]
    limited = [r for r in results if r.verdict == "time limit"]
    lost = [r for r in results if r.verdict not in ("completed", "by fault", "time limit")]
    missed = [r for r in completed if r.fault and r.fault != "flood"]
    floods = [r for r in completed if r.fault == "flood"]
    lines.append("runs completed: %d (%d with a flood during the run, %d with a fault that came after the run's "
                 "end or not at all)" % (len(completed), len(floods), len(missed)))
    if limited:
        lines.append("runs stopped at the time limit (%d s of testbed time; no fault): %d: %s" % (
            soak.time_limit, len(limited), ", ".join("run %d %s %s (numpy seed %d)" % (
                r.n, r.script, r.mode, soak.seed * 100003 + r.n) for r in limited)))
    lines.append("runs ended by a fault: %d, each cause checked against the fault injected:" % len(by_fault))
    kinds = sorted({r.fault for r in results if r.fault and r.fault != "flood"})
    for kind in kinds:
        hit = [r for r in results if r.fault == kind and (r.injected or kind == "disk_full")]
        right = [r for r in hit if r.verdict == "by fault"]
        causes = {}
        for r in right:
            key = re.sub(r"\d+", "k", " ".join(filter(None, (r.report_first_line or r.detail, r.safety_restarts))))[:150]
            causes[key] = causes.get(key, 0) + 1
        lines.append("  %-16s planned %3d, hit %3d, right cause %3d%s" % (
            kind, sum(r.fault == kind for r in results), len(hit), len(right),
            "" if hit else "  (never hit)"))
        for cause, count in sorted(causes.items(), key=lambda c: -c[1]):
            lines.append("      %3d x %s" % (count, cause))
    if soak.disk_note:
        lines.append("  " + soak.disk_note)
    wrong = [r for r in lost if r.fault and r.injected and r.outcome]
    lines.append("runs lost: %d (of them a wrong cause for the fault injected: %d)" % (len(lost), len(wrong)))
    for r in lost:
        lines.append("  run %d %s %s %s, fault %s (%s at step %d): %s;\n      run.json: outcome %r, exit code %s, "
                     "detail %r%s;\n      report.txt: %r" % (
                         r.n, r.script, r.mode, r.length, r.fault or "none", r.injected or "not injected",
                         r.injected_at_step, r.why_lost, r.outcome, r.exit_code, r.detail[:300],
                         (", recording stopped: %s" % r.recording_stopped) if r.recording_stopped else "",
                         r.report_first_line[:300]) + ("\n      its output: %s" % r.output if r.output else "")
                     + ("\n      the testbed meanwhile:\n        %s" % r.testbed_said.replace("\n", "\n        ")
                        if r.testbed_said else ""))
    lines.append("node restarts by ./robotarium up (its supervisor): %d%s" % (
        len(soak.node_restarts), "".join("\n  after run %d: %s" % (after, line[:200])
                                         for after, line in soak.node_restarts)))
    lines.append("testbed restarts (./robotarium up stopped and the soak started it again): %d" % len(soak.restarts))
    for after, why, _ in soak.restarts:
        lines.append("  after run %d (UNEXPECTED): %s" % (after, why[:200]))
    in_place = soak.in_place_restarts()
    lines.append("  nodes that restarted in place (DDS stall watch): %d%s" % (
        len(in_place), "".join("\n    " + line[:200] for line in in_place)))
    latencies = [r.start_latency for r in results if r.start_latency is not None]
    if latencies:
        worst = max(results, key=lambda r: r.start_latency or 0)
        lines.append("start latency (the run's process started -> its experiment heard RUNNING), %d runs: max %.2f s "
                     "(run %d, %s, %s), p99 %.2f s, median %.2f s" % (
                         len(latencies), worst.start_latency, worst.n, worst.script, worst.mode,
                         percentile(latencies, 99), percentile(latencies, 50)))
    walls = [r.wall for r in results]
    if walls:
        lines.append("wall per run (process start to exit): median %.1f s, max %.1f s" % (
            percentile(walls, 50), max(walls)))
    lines.append("nodes (RSS MB / open fds / threads; pid changes at a restart):")
    names = sorted(NODES)
    lines.append("  %-16s " % "at" + "".join("%-28s" % n for n in names))
    for label, nodes in soak.samples:
        cells = []
        for n in names:
            pid, size = nodes.get(n, (None, None))
            cells.append("%-28s" % ("%.1f / %d / %d (pid %d)" % (size + (pid,)) if size else "-"))
        lines.append("  %-16s " % label + "".join(cells))
    lines.append("growth within one process (its first sample to its last):")
    for n in names:
        spans = {}
        for label, nodes in soak.samples:
            pid, size = nodes.get(n, (None, None))
            if size:
                spans.setdefault(pid, []).append((label, size))
        for pid, seen in spans.items():
            if len(seen) > 1:
                (first, a), (last, b) = seen[0], seen[-1]
                lines.append("  %-10s pid %-7d %s -> %s: RSS %+.1f MB, fds %+d, threads %+d" % (
                    n, pid, first, last, b[0] - a[0], b[1] - a[1], b[2] - a[2]))
    return lines


def run_soak(work, runs, seed, node_every=50, sample_every=100, keep=False, video=False, say=print, progress=25,
             time_limit=150, minutes=None, **plan_args):
    """Plan, run and summarise a soak in `work`; returns (Soak, plans, summary lines). Everything it
    started is stopped when it returns or fails."""
    plans = plan(runs, seed, node_every=node_every, **plan_args)
    soak = Soak(work, seed=seed, keep=keep, video=video, say=say, time_limit=time_limit)
    try:
        soak.start()
        soak.soak(plans, sample_every=sample_every, progress=progress, minutes=minutes)
        return soak, plans, summary(soak, plans)
    finally:
        soak.close()
