"""Finding a testbed on the DDS domain, or starting one on this machine for a script.

The testbed is three nodes: the simulator, the safety node and the recorder. `LocalTestbed`
runs them as subprocesses (the embedded default of `./robotarium run` and of a script run with
no testbed around) and stops them again; `./robotarium up` keeps one running until Ctrl-C.

A local testbed never outlives the process that started it: each node holds that process's
lifeline (robotarium_core.lifeline) and, when it is gone (SIGKILL included), ends the experiment,
closes the recording and exits. Each local testbed logs into its own folder,
log/testbed/<namespace>_<domain>_<pid>/, and is listed in the registry of the machine's testbeds
(robotarium_bringup.local_testbeds) while it runs.
"""
import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import String

from robotarium_bringup import local_testbeds
from robotarium_core import claim, lifeline, presence, restarts
from robotarium_core.config import DEFAULT, DEFAULT_FILE
from robotarium_core.dds_health import close_unless_stuck
from robotarium_core.dds_settings import init_context
from robotarium_core.discovery import wait_for_quiet_discovery, wait_for_service
from robotarium_core.topics import (
    END_EXPERIMENT,
    RECORDED_RUNS,
    RECORDED_RUNS_QOS,
    START_EXPERIMENT,
    STATUS,
    STATUS_QOS,
    namespace_from_environment,
)
from robotarium_hardware import fleet as fleets
from robotarium_msgs.msg import TestbedStatus
from robotarium_msgs.srv import EndExperiment, StartExperiment

NODES = {
    # name: (module, whether it reads the testbed configuration)
    "simulator": ("robotarium_sim.simulator_node", True),
    "safety": ("robotarium_safety.safety_node", True),
    "recorder": ("robotarium_recording.recorder_node", False),
    # a lab's own robots (./robotarium up --fleet FILE): the hardware arena in the simulator's place, and the
    # tag tracker where the fleet is tracked by a camera
    "arena": ("robotarium_hardware.arena_node", True),
    "tag_tracker": ("robotarium_hardware.tag_tracker_node", False),
}


# The nodes that stop real robots when one fails (the hardware arena; the tag tracker, whose poses say a tag is
# gone) run at a higher scheduling priority where this process may give one (root): on a machine shared with
# other work their reaction is what the 0.2 s to stop every robot is made of (docs/own-robots.md).
REAL_TIME_NODES = ("arena", "tag_tracker")
REAL_TIME_NICE = -10   # as the simulated fleet's processes: CFS gives it about nine times the share of a plain process


def _real_time_priority():
    try:
        os.nice(REAL_TIME_NICE)
    except OSError:
        pass


def repository_root():
    """The checkout this code runs from (./robotarium exports it), else the working directory."""
    return os.environ.get("ROBOTARIUM_ROOT") or os.getcwd()


def node_command(name, ns=None, extra_ros_args=(), config_file=DEFAULT_FILE):
    """The command line of one testbed node; the simulator and the safety node read the same
    testbed configuration file (the packaged testbed.yaml unless another is given)."""
    module, configured = NODES[name]
    cmd = [sys.executable, "-m", module, "--ros-args", "-r", "__ns:=%s" % (ns or namespace_from_environment())]
    if configured:
        cmd += ["--params-file", config_file or DEFAULT_FILE]
    if security_enabled():   # each node in its enclave of sros2/robotarium.policy.xml
        cmd += ["--enclave", "/robotarium/%s" % name]
    return cmd + list(extra_ros_args)


def security_enabled():
    """DDS Security asked for (a ROS install with SROS2: see sros2/README.md)."""
    return os.environ.get("ROS_SECURITY_ENABLE", "").lower() == "true"


# Log folders of stopped local testbeds kept under log/testbed/ (older ones are removed).
KEEP_LOG_DIRS = 20


def owner_command():
    """How the process starting a testbed was started, for `./robotarium status`."""
    argv = list(sys.argv)
    if argv and (argv[0].replace(os.sep, "/").endswith("robotarium_cli/__main__.py")
                 or os.path.basename(argv[0]) == "robotarium"):   # python -m robotarium_cli, the console script
        return " ".join(["./robotarium"] + argv[1:])
    return " ".join([os.path.basename(sys.executable)] + argv)


def default_log_dir(ns):
    """log/testbed/<namespace>_<domain>_<pid>/ of the checkout: one folder per local testbed, so
    that concurrent testbeds never write into each other's logs."""
    base = os.path.join(repository_root(), "log", "testbed")
    name = "%s_%s_%d" % (ns.strip("/").replace("/", "-") or "root", local_testbeds.domain_id(), os.getpid())
    path, k = os.path.join(base, name), 1
    while os.path.exists(path):   # a second testbed of this process in the same namespace and domain
        k += 1
        path = os.path.join(base, "%s_%d" % (name, k))
    _prune_log_dirs(base)
    return path


def _prune_log_dirs(base):
    """Keep the newest KEEP_LOG_DIRS log folders of stopped testbeds; never touch a running one's."""
    try:
        folders = [os.path.join(base, d) for d in os.listdir(base) if os.path.isdir(os.path.join(base, d))]
    except FileNotFoundError:
        return
    in_use = {entry["log_dir"] for _, entry in local_testbeds.registered()}
    old = sorted((f for f in folders if os.path.abspath(f) not in in_use), key=os.path.getmtime)
    for folder in old[:max(0, len(old) - KEEP_LOG_DIRS)]:
        shutil.rmtree(folder, ignore_errors=True)


class LocalTestbed:
    """Simulator, safety node and recorder in subprocesses, stopped together, and tied to this
    process by its lifeline."""

    def __init__(self, log_dir=None, record=True, ns=None, bags_dir=None, quiet=True, config_file=None,
                 hardware=False, looked=False, fleet_file=None):
        self.gate = None
        # The starter looked for a testbed in this namespace already (./robotarium up, run, verify's own
        # namespace): the nodes claim their place without waiting for an older one (robotarium_core.claim).
        self.looked = looked
        self._stop_deadline = None   # set by begin_stop()
        self.ns = ns or namespace_from_environment()
        self.config_file = config_file
        self.root = repository_root()   # the checkout whose nodes these are
        self.log_dir = log_dir   # None: log/testbed/<namespace>_<domain>_<pid>/, chosen at start
        self.hardware = hardware   # every experiment hardware-like (the simulator's `hardware` parameter)
        self.fleet_file = os.path.abspath(fleet_file) if fleet_file else None
        arena = ["simulator"]
        if self.fleet_file:   # the fleet's arena (and its tag tracker) in the simulator's place
            arena = ["arena"] + (["tag_tracker"] if fleets.load(self.fleet_file).tracking == "camera" else [])
        self.names = arena + ["safety"] + (["recorder"] if record else [])
        self.bags_dir = bags_dir
        self.quiet = quiet
        self.processes = {}
        self.registry_entry = None
        self._env, self._pass_fds = None, ()

    def start(self, gated=False):
        """Start the nodes. gated: they import and then wait at a start gate before joining DDS,
        until open() lets them go on (or cancel() ends them): `./robotarium run` starts them so
        while it still looks for a testbed on the domain."""
        self.log_dir = self.log_dir or default_log_dir(self.ns)
        os.makedirs(self.log_dir, exist_ok=True)
        # Each node reads the lifeline's end: it stops when this process is gone, however it went.
        env, pass_fds = lifeline.for_child(os.environ)
        # One testbed per namespace: its nodes claim their places as one testbed (same since, same pid).
        env = dict(env, **{claim.ENV_SINCE: repr(time.time()), claim.ENV_TESTBED: str(os.getpid()),
                           claim.ENV_OWNER: "%s (pid %d)" % (owner_command(), os.getpid()),
                           claim.ENV_CHECKED: "1" if self.looked else "0"})
        self._env, self._pass_fds = env, pass_fds   # a node restarted later starts as its siblings did (restart)
        self.gate = lifeline.StartGate() if gated else None
        if self.gate is not None:
            env, pass_fds = self.gate.for_child(env, pass_fds)
        for name in self.names:
            self.processes[name] = self._spawn(name, env, pass_fds, "wb")
        if self.gate is None:
            self.registry_entry = local_testbeds.register(self, owner_command())
        else:
            self.gate.close_read_end()
        return self

    def _spawn(self, name, env, pass_fds, log_mode):
        """Start node `name`: (its Popen, its log file or None)."""
        extra = ["-p", "bags_dir:=%s" % self.bags_dir] if name == "recorder" and self.bags_dir else []
        if name in ("simulator", "arena"):   # a run's first steps wait for the recorder's readers where it records
            extra = (["-p", "hardware:=true"] if self.hardware else []) + (
                ["-p", "wait_for_recorder:=true"] if "recorder" in self.names else [])
        if name in ("arena", "tag_tracker"):
            extra += ["-p", "fleet_file:=%s" % self.fleet_file]
        log = open(os.path.join(self.log_dir, name + ".log"), log_mode) if self.quiet else None
        return subprocess.Popen(
            node_command(name, self.ns, extra, self.config_file), stdout=log, stderr=subprocess.STDOUT if log else None,
            env=env, pass_fds=pass_fds, start_new_session=True,
            preexec_fn=_real_time_priority if name in REAL_TIME_NODES else None), log

    def restart(self, name, restart):
        """Start node `name`, which exited, again (./robotarium up's supervisor: robotarium_bringup.supervisor):
        the same command line, lifeline and claim (it takes its place again at once), `restart` (a
        robotarium_core.restarts.Restart) in its environment; its log goes on. The registry names its new pid."""
        old, log = self.processes[name]
        old.wait()
        if log:
            log.close()
        env = dict(self._env, **{restarts.ENV: restart.to_json(), claim.ENV_CHECKED: "1"})
        self.processes[name] = self._spawn(name, env, self._pass_fds, "ab")
        if self.registry_entry is not None:
            self.registry_entry = local_testbeds.register(self, owner_command())

    def open(self):
        """Let the nodes of a gated start go on (they join DDS now)."""
        self.registry_entry = local_testbeds.register(self, owner_command())
        self.gate.open(len(self.processes))
        self.gate = None
        return self

    def cancel(self):
        """End the nodes of a gated start that was not opened: they never joined DDS (no
        experiment, no recording), so they are killed at once rather than waited for."""
        self.gate.close()
        self.gate = None
        for process, log in self.processes.values():
            _kill_group(process)
            if log:
                log.close()
        self.processes = {}
        shutil.rmtree(self.log_dir, ignore_errors=True)   # nothing ran: no logs to keep

    def failed(self):
        """Names of nodes that exited, with their exit codes."""
        return {name: p.returncode for name, (p, _) in self.processes.items() if p.poll() is not None}

    def begin_stop(self, grace=5.0):
        """SIGINT everyone (the simulator ends a running experiment, the recorder closes its bag:
        node_main.run_node's wind-down, at most 2 s); stop() then waits for them. Between the two
        the caller may do other work (./robotarium run makes the results once the bag is closed,
        while the nodes exit)."""
        if self.gate is not None or self._stop_deadline is not None:
            return
        for process, _ in self.processes.values():
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGINT)
        self._stop_deadline = time.monotonic() + grace

    def stop(self, grace=5.0):
        """begin_stop() (if not done yet), then SIGKILL what is left `grace` seconds after it."""
        if self.gate is not None:   # never let through: nothing to wind down
            self.cancel()
            return
        self.begin_stop(grace)
        deadline, self._stop_deadline = self._stop_deadline, None
        for process, log in self.processes.values():
            try:
                process.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
            if log:
                log.close()
        self.processes = {}
        local_testbeds.unregister(self.registry_entry)
        self.registry_entry = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


def _kill_group(process):
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.wait()


def testbed_answers(ns=None, timeout=3.0, stop=None):
    """True when a simulator on this DDS domain offers <ns>/start_experiment within `timeout` (False at once
    once stop() is true)."""
    with probe_node("robotarium_probe") as (node, _):
        client = node.create_client(StartExperiment, "%s/start_experiment" % (ns or namespace_from_environment()))
        return wait_for_service(client, timeout, stop)


def nodes_seen(domain=None, discovery_range=None):
    """The nodes (full names, sorted) this process's probe context sees on the DDS graph of `domain`,
    its own probes left out: what a "no testbed answers" can name, so that a testbed in another
    namespace, one without its simulator, or a graph with nothing at all (discovery not reaching
    this process) tell themselves apart."""
    with probe_node("robotarium_probe", domain, discovery_range) as (node, _):
        own = "_%d" % os.getpid()
        return sorted("%s/%s" % (ns.rstrip("/"), name) for name, ns in node.get_node_names_and_namespaces()
                      if not name.endswith(own) and not name.startswith("robotarium_graph_"))


RECORDING_LOOKUP_WAIT = 10.0   # s to wait for the recorder to say where a run is recorded (announced_recording)
RECORDER_SEEN_WAIT = 3.0       # s of it, at most, where the graph shows no recorder at all


def announced_recording(run_id, ns=None, timeout=RECORDING_LOOKUP_WAIT):
    """The folder the recorder of `ns` recorded run `run_id` in (its hidden <ns>/_recording/runs), waiting
    up to `timeout` seconds for it: a script killed outright may die before its own client heard the
    announcement (a busy recorder opens the bag a few steps late), and a recorder starved of CPU
    answers discovery seconds late, after the run closed; the testbed lost, its recorder may still
    record. "" when none announced it in time, or no recorder shows in RECORDER_SEEN_WAIT s."""
    found = []

    def heard(msg):
        try:
            run = json.loads(msg.data)
            if run["run_id"] == run_id and run["path"]:
                found.append(str(run["path"]))
        except (ValueError, TypeError, KeyError):
            pass   # not an announcement
    # Named as the client's nodes are (robotarium_client_<pid>...): SROS2's policy lets them read it.
    with probe_node("robotarium_client_recorded_runs") as (node, executor):
        topic = "%s/%s" % ((ns or namespace_from_environment()).rstrip("/"), RECORDED_RUNS)
        node.create_subscription(String, topic, heard, RECORDED_RUNS_QOS)
        start = time.monotonic()
        while not found and time.monotonic() < start + timeout:
            if time.monotonic() > start + RECORDER_SEEN_WAIT and not node.count_publishers(topic):
                break   # no recorder (a testbed started with --no-record, or gone with the testbed)
            executor.spin_once(timeout_sec=0.05)
        return found[-1] if found else ""


def running_testbed(ns=None, timeout=3.0):
    """The testbed that runs in `ns` on this domain, if any: the identity (robotarium_core.claim) of
    the first of its simulator, safety node or recorder heard within `timeout` seconds, or
    {"who": "testbed", ...} with what is known where only a simulator without a claim answers; None
    when nothing answered (then it took the whole timeout)."""
    ns = (ns or namespace_from_environment()).rstrip("/")
    heard = []
    with probe_node("robotarium_claims") as (node, executor):
        for who in (presence.SIMULATOR, presence.SAFETY, presence.RECORDER):
            node.create_subscription(String, "%s/%s" % (ns, claim.claim_topic(who)),
                                     lambda msg: heard.append(claim.parse(msg.data)), claim.QOS)
        service = node.create_client(StartExperiment, "%s/%s" % (ns, START_EXPERIMENT))
        deadline = time.monotonic() + timeout
        while not any(heard) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
        found = [ident for ident in heard if ident]
        if found:
            return min(found, key=lambda ident: (claim.order(ident), ident["who"] != presence.SIMULATOR))
        if service.service_is_ready():   # a simulator that does not claim (another version)
            return {"who": "simulator", "host": "unknown host", "pid": 0, "since": 0.0, "testbed": 0,
                    "owner": "a version without claims"}
        return None


_probe_contexts = {}   # (domain, discovery range) -> (context, its anchor node)


def _probe_context(domain=None, discovery_range=None):
    """The rclpy context this process looks at the DDS graph from, on `domain` (default:
    ROS_DOMAIN_ID) with the given discovery range (default: ROS_AUTOMATIC_DISCOVERY_RANGE, which rcl
    reads when the context starts). Made once and kept for the process's life, with an anchor node:
    rmw destroys a context's DDS participant with its last node, and Fast DDS 2.14 can deadlock
    destroying a participant while discovery callbacks run, spinning for ever (a ./robotarium run
    once spun at 100 % CPU for 28 minutes in rcl_node_fini right after a probe, under load). The
    probes' own nodes come and go; the command ends with os._exit (robotarium_cli.main), never tearing it down."""
    # What rcl will read: the environment's, unless given (a test changes ROS_DOMAIN_ID in process).
    key = (str(domain) if domain is not None else os.environ.get("ROS_DOMAIN_ID", "").strip() or "0",
           discovery_range or os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", ""))
    if key in _probe_contexts:
        return _probe_contexts[key][0]
    saved = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE")
    if discovery_range:
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery_range
    try:
        context = Context()
        init_context(context=context, args=[], domain_id=None if domain is None else int(domain), node=False)
    finally:
        if discovery_range:
            if saved is None:
                os.environ.pop("ROS_AUTOMATIC_DISCOVERY_RANGE", None)
            else:
                os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = saved
    anchor = Node("robotarium_graph_%d_%d" % (os.getpid(), len(_probe_contexts)), context=context,
                  start_parameter_services=False)
    _probe_contexts[key] = (context, anchor)
    return context


def probe_context():
    """The probe context of this process's domain (see _probe_context): for a node a command keeps for its life
    (./robotarium up's restart announcements)."""
    return _probe_context()


def close_probe_contexts():
    """Tear down the probe contexts (for a long-lived process that leaves a domain, such as the tests)."""
    while _probe_contexts:
        _, (context, anchor) = _probe_contexts.popitem()

        def close(context=context, anchor=anchor):
            anchor.destroy_node()   # the participant goes with the anchor
            rclpy.try_shutdown(context=context)
        close_unless_stuck(close, "the probe context of %s" % anchor.get_name(),   # not for ever in a deadlock
                           settle=lambda anchor=anchor: wait_for_quiet_discovery(anchor))


@contextlib.contextmanager
def probe_node(name, domain=None, discovery_range=None):
    """A node (with an executor to spin it) named `name`_<pid> on the probe context of `domain` and
    `discovery_range` (see _probe_context), destroyed again on leaving; the context stays."""
    context = _probe_context(domain, discovery_range)
    node = Node("%s_%d" % (name, os.getpid()), context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()


SAFETY_PRESENCE_WAIT = 2.0   # s a testbed that answers has to show its safety node's presence (testbed_status)


def testbed_status(targets, timeout=3.0, safety=None):
    """The newest status of the testbed in each (domain, namespace, discovery range) of `targets`:
    {(domain, namespace): robotarium_msgs TestbedStatus, or None where no testbed answered within
    `timeout` seconds}. The status topic keeps its last messages (transient local), so a testbed
    answers as soon as discovery matched it; all domains are probed at once.

    safety: a dict {(domain, namespace): whether its safety node is there} to complete: a key set
    True already (a safety node in this machine's process table) is taken as it is; the others get
    whether the safety node's presence (robotarium_core.presence) was seen, a testbed that answers
    being given SAFETY_PRESENCE_WAIT s more for it from its first status (discovery of another process
    may take that long on a loaded machine), so an incomplete one takes that long."""
    newest = {}
    heard_at = {}  # (domain, namespace): when its first status came
    watches = {}   # (domain, namespace): presence.Watch of its safety node
    executors = []
    by_domain = {}
    for domain, ns, discovery_range in targets:   # one probe per domain (the first discovery range given)
        probe = by_domain.setdefault(str(domain), [discovery_range, set()])
        probe[1].add(ns)
    with contextlib.ExitStack() as probes:
        for domain, (discovery_range, namespaces) in by_domain.items():
            node, executor = probes.enter_context(probe_node("robotarium_status_%s" % domain, domain, discovery_range))
            executors.append(executor)
            for ns in namespaces:
                newest[(domain, ns)] = None

                def keep(msg, key=(domain, ns)):
                    heard_at.setdefault(key, time.monotonic())
                    old = newest[key]
                    stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
                    if old is None or stamp >= (old.header.stamp.sec, old.header.stamp.nanosec):
                        newest[key] = msg
                node.create_subscription(TestbedStatus, "%s/%s" % (ns.rstrip("/"), STATUS), keep, STATUS_QOS)
                if safety is not None and not safety.get((domain, ns)):
                    watches[(domain, ns)] = presence.Watch(
                        node, "%s/%s" % (ns.rstrip("/"), presence.alive_topic(presence.SAFETY)), DEFAULT.node_lease)

        deadline = time.monotonic() + timeout

        def waiting():
            now = time.monotonic()
            return any((v is None and now < deadline)
                       or (v is not None and key in watches and not watches[key].seen
                           and now < heard_at[key] + SAFETY_PRESENCE_WAIT)
                       for key, v in newest.items())
        while waiting():
            for executor in executors:
                executor.spin_once(timeout_sec=0.02)
        # a moment more, for anything newer still on its way
        settle = time.monotonic() + 0.2
        while time.monotonic() < settle:
            for executor in executors:
                executor.spin_once(timeout_sec=0.02)
        if safety is not None:
            safety.update({key: watch.seen for key, watch in watches.items()})
    return newest


def end_experiment(ns=None, timeout=10.0, force=False, outcome=0, detail=""):
    """Call <ns>/end_experiment on this domain; returns the response (raises TimeoutError when no
    testbed answers). Without `force` the testbed refuses: an experiment is ended by its own client
    (with its token), or by an operator who says so. `outcome` and `detail`: how the run ended, as
    its recording will say (robotarium_core.outcomes; 0: the testbed says an operator ended it)."""
    ns = ns or namespace_from_environment()
    with probe_node("robotarium_end") as (node, executor):
        client = node.create_client(EndExperiment, "%s/%s" % (ns.rstrip("/"), END_EXPERIMENT))
        if not client.wait_for_service(timeout_sec=timeout):
            raise TimeoutError("no testbed answers in %s on ROS_DOMAIN_ID %s" % (ns, os.environ.get("ROS_DOMAIN_ID", "0")))
        future = client.call_async(EndExperiment.Request(force=force, outcome=outcome, detail=detail))
        executor.spin_until_future_complete(future, timeout_sec=timeout)
        if not future.done():
            raise TimeoutError("the testbed in %s did not answer end_experiment within %.0f s" % (ns, timeout))
        return future.result()


# The node kinds whose restart a run in progress hears of (the arena takes the simulator's place).
ANNOUNCED = {"simulator": "simulator", "arena": "simulator", "safety": "safety", "recorder": "recorder"}


class RestartAnnouncer:
    """up's own node (on its probe context, kept for its life), with a latched writer on each announced kind's
    restart topic, made at the start so that clients have matched them before anything restarts."""

    def __init__(self, ns, names):
        context = probe_context()
        if security_enabled():   # a participant of its own, in the policy's supervisor enclave (sros2/)
            context = Context()
            init_context(context=context, node=False, args=["--ros-args", "--enclave", "/robotarium/supervisor"])
        self.node = Node("robotarium_up_%d" % os.getpid(), namespace=ns, context=context,
                         start_parameter_services=False)
        self.publishers = {ANNOUNCED[name]: self.node.create_publisher(String, restarts.topic(ANNOUNCED[name]),
                                                                        restarts.QOS)
                           for name in names if name in ANNOUNCED}

    def announce(self, restart):
        publisher = self.publishers.get(restart.who)
        if publisher is not None:
            publisher.publish(String(data=restart.to_json()))
