"""What every testbed node does the same way: the testbed configuration as ROS parameters, and a
main() that spins (robotarium_core.executor.LeanExecutor: a fraction of the cost per callback
of rclpy's default executor) until a signal or its lifeline says stop, then winds down cleanly.

Kept apart from model.py and config.py (no ROS there); the nodes themselves stay thin shells.
"""
import ctypes
import faulthandler
import hashlib
import math
import os
import re
import signal
import sys
import tempfile
import time

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions

from robotarium_core import claim as claims
from robotarium_core import lifeline
from robotarium_core.config import DEFAULT, FIELDS, TestbedConfig
from robotarium_core.executor import LeanExecutor
from robotarium_core.topics import DEFAULT_NAMESPACE


def _descriptor(description, value, low=-math.inf, high=math.inf, integer=False, read_only=True):
    """A ParameterDescriptor that `ros2 param describe` explains and that refuses values out of
    range, or any change at all where the node reads the value only at start-up (read_only)."""
    if isinstance(value, bool):
        kind = ParameterType.PARAMETER_BOOL
    elif isinstance(value, (list, tuple)) and value and all(isinstance(v, str) for v in value):
        kind = ParameterType.PARAMETER_STRING_ARRAY
    elif isinstance(value, (list, tuple)):
        kind = ParameterType.PARAMETER_DOUBLE_ARRAY
    elif isinstance(value, str):
        kind = ParameterType.PARAMETER_STRING
    elif integer:
        kind = ParameterType.PARAMETER_INTEGER
    else:
        kind = ParameterType.PARAMETER_DOUBLE
    descriptor = ParameterDescriptor(description=description, type=kind, read_only=read_only)
    # ROS ranges are closed; an open lower bound (> 0) is checked by the config, not here.
    if kind == ParameterType.PARAMETER_INTEGER and (math.isfinite(low) or math.isfinite(high)):
        descriptor.integer_range = [IntegerRange(from_value=int(max(low, -2**31)), to_value=int(min(high, 2**31)))]
    elif kind == ParameterType.PARAMETER_DOUBLE and math.isfinite(low) and math.isfinite(high):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high))]
    return descriptor


def declare_parameter(node, name, default, description, **range_and_mode):
    """Declare one parameter with its descriptor and return its value; a value given out of its
    range or of the wrong type raises ValueError saying which parameter and what a valid one is."""
    descriptor = _descriptor(description, default, **range_and_mode)
    try:
        return node.declare_parameter(name, default, descriptor).value
    except (ParameterException, rclpy.exceptions.InvalidParameterTypeException) as error:
        low, high = range_and_mode.get("low", -math.inf), range_and_mode.get("high", math.inf)
        valid = "" if not (math.isfinite(low) or math.isfinite(high)) else " in [%g, %g]" % (low, high)
        raise ValueError("parameter %s must be a %s%s (%s); %s" % (
            name, type(default).__name__, valid, description, error)) from None


def declare_config(node, role=None):
    """Declare the testbed configuration's values that `role` ("simulator" or "safety") reads, or
    all of them (role None: the simulator, which publishes the whole configuration of a run), as
    read-only parameters with their meaning and range, defaults from the packaged testbed.yaml
    (a params file given with --params-file overrides them). Returns the checked TestbedConfig;
    a bad value raises ConfigError naming it, which run_node turns into a clear exit."""
    values = {}
    for name, field in FIELDS.items():
        if role is not None and role not in field.used_by:
            continue
        default = getattr(DEFAULT, name)
        if isinstance(default, tuple):
            default = list(default) if field.names else [float(v) for v in default]
        values[name] = declare_parameter(
            node, name, default, "%s (testbed configuration)" % field.description,
            low=field.low, high=field.high, integer=field.integer)
    return TestbedConfig.from_dict(values, base=DEFAULT)


# The longest a node spends winding down after it was asked to stop (the simulator ending its
# experiment, the recorder closing the run's bag); then it exits whatever is left.
WIND_DOWN_LIMIT = 2.0
STOP_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")


class StopRequest:
    """Why a node should stop: a signal (SIGINT, SIGTERM, SIGHUP: Ctrl-C, `kill`, a closed
    terminal) or its lifeline (the process that started it is gone, SIGKILL included: see
    robotarium_core.lifeline). Made before the node, so a signal during start-up is kept too; once
    attached to the node either one wakes its executor at once through a guard condition."""

    def __init__(self):
        self.reason = None
        self.restart = False   # stop, then start afresh in this process (restart_in_place)
        self.signals = 0
        self._wake = None
        for name in STOP_SIGNALS:
            signal.signal(getattr(signal, name), self._on_signal)
        parent = os.getppid()
        lifeline.watch(lambda: self.request("the process that started this testbed (pid %d) is gone" % parent))

    def attach(self, node):
        self._wake = node.create_guard_condition(lambda: None)
        if self.reason is not None:
            self._wake.trigger()

    def _on_signal(self, signum, frame):
        self.signals += 1
        self.request("received %s" % signal.Signals(signum).name)

    def request(self, reason, restart=False):
        if self.reason is None:
            self.reason, self.restart = reason, restart
        if self._wake is not None:
            self._wake.trigger()


SERVICE_POLL = 0.01   # s between looks at the DDS graph while waiting for a service


def wait_for_service(client, timeout):
    """Client.wait_for_service without its 0.25 s steps (rclpy sleeps that long between looks at
    the graph): True as soon as the service is there, False after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while client.context.ok():
        if client.service_is_ready():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(SERVICE_POLL)
    return False


# Discovery counts as settled after this long without news (s), waited for at most QUIET_DISCOVERY_WAIT.
QUIET_DISCOVERY = 0.1
QUIET_DISCOVERY_WAIT = 1.0


def discovery_graph(node):
    """What discovery has told `node`'s participant: nodes, and each topic's publisher and subscriber
    counts."""
    return (tuple(sorted(node.get_node_names_and_namespaces())),
            tuple((name, node.count_publishers(name), node.count_subscribers(name))
                  for name, _ in sorted(node.get_topic_names_and_types())))


def wait_for_quiet_discovery(node, still=QUIET_DISCOVERY, timeout=QUIET_DISCOVERY_WAIT):
    """Wait (at most `timeout`) until discovery has told `node` nothing new for `still` seconds. Before
    a participant is destroyed: Fast DDS can hang for good destroying one while one of its discovery
    callbacks runs (DomainParticipant::set_listener spins holding the lock the callback needs to
    end), and an experiment's end makes the simulator drop that run's endpoints just then (a test
    worker hung in destroy_node that way)."""
    last, since, end = discovery_graph(node), time.monotonic(), time.monotonic() + timeout
    while time.monotonic() - since < still and time.monotonic() < end:
        time.sleep(0.01)
        now = discovery_graph(node)
        if now != last:
            last, since = now, time.monotonic()


def take_waiting(subscription, limit=10_000, with_info=False):
    """The messages waiting in `subscription`'s queue, taken now (raw bytes for a raw=True one; with
    with_info, (message, its message info) as rclpy hands a callback that takes both).

    rclpy's executor hands a callback one message per turn of its wait loop, a few hundred
    microseconds each on a loaded machine; under a flood of 1000 arrays a second a node then falls
    behind until its queue is full and the oldest array, perhaps the client's, is pushed out. A
    callback that takes the rest of the queue at once (a few microseconds an array) keeps up."""
    with subscription.handle:
        for _ in range(limit):
            taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
            if taken is None:
                return
            yield taken if with_info else taken[0]


DDS_PROFILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "dds_profile.xml")
MMAP_THRESHOLD = 256 * 1024   # bytes: larger blocks are mapped for themselves and go back to the system when freed
_M_MMAP_THRESHOLD = -3         # glibc's mallopt parameter


def localhost_profile():
    """dds_profile.xml with its LOCALHOST blocks in force (loopback locators, localhost as the initial
    peer), written once per content to the temporary directory; None where it cannot be written."""
    with open(DDS_PROFILE, encoding="utf-8") as f:
        text = f.read().replace("<!--LOCALHOST", "").replace("LOCALHOST-->", "")
    path = os.path.join(tempfile.gettempdir(), "robotarium-dds-localhost-%s.xml"
                        % hashlib.sha256(text.encode()).hexdigest()[:16])
    if not os.path.exists(path):
        try:
            with tempfile.NamedTemporaryFile("w", dir=os.path.dirname(path), delete=False, suffix=".tmp") as f:
                f.write(text)
            os.replace(f.name, path)   # whole or not at all, for a process that reads it meanwhile
        except OSError:
            return None
    return path


def _ours(profile):
    """Whether a FASTRTPS_DEFAULT_PROFILES_FILE value is one of ours (inherited from a process of the
    testbed that started this one), not the user's choice."""
    return profile == DDS_PROFILE or os.path.basename(profile).startswith("robotarium-dds-localhost-")


def _localhost_only():
    """Whether rcl would start a participant with the LOCALHOST discovery range and nothing else
    (no static peers; not the deprecated ROS_LOCALHOST_ONLY, which rcl lets prevail)."""
    return (os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper() == "LOCALHOST"
            and not os.environ.get("ROS_STATIC_PEERS", "").strip() and os.environ.get("ROS_LOCALHOST_ONLY") != "1")


def init_context(context=None, args=None, domain_id=None, node=True, **options):
    """rclpy.init with the testbed's Fast DDS settings (dds_profile.xml; a profile file the user set is
    kept, and with it their choice), for its nodes and a script's client alike: UDP only (never the
    shared-memory transport, see the file); a participant announced every 0.2 s, so a process that
    joins later finds it at once; writers that send a heartbeat every 0.1 s, so a lost packet is sent
    again at once. A node's readers also allocate a sample's buffer when it arrives and free it when
    it is taken (issue 22: a flood costs no memory that stays), for which rmw_fastrtps must take the
    policies it would set itself from the file (RMW_FASTRTPS_USE_QOS_FROM_XML), data sharing among
    them; a client (node=False) keeps rmw's, data sharing off: a script in a job box runs as an
    account that may not open the testbed's shared segments.

    Under ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST rmw_fastrtps would put its own transports in place
    (shared memory among them): the participant starts with the range SYSTEM_DEFAULT and
    localhost_profile() instead, which keeps discovery on this machine just as well; the range is as
    it was afterwards (the profile file stays: a child process is to find it). Fast DDS reads its
    profile file once, when a process makes its first participant, so every participant of ours
    starts here (tests/test_lint.py checks that no other rclpy.init remains)."""
    saved = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE")
    if _ours(os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", DDS_PROFILE)):
        localhost = localhost_profile() if _localhost_only() else None
        os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = localhost or DDS_PROFILE
        if localhost is not None:
            os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"
        if node:
            os.environ["RMW_FASTRTPS_USE_QOS_FROM_XML"] = "1"   # only for the policies our code leaves to it
    try:
        rclpy.init(context=context, args=args, domain_id=domain_id, **options)
    finally:
        if saved is None:
            os.environ.pop("ROS_AUTOMATIC_DISCOVERY_RANGE", None)
        else:
            os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = saved


def return_freed_memory():
    """A node's freed large blocks go back to the system (issue 22): the C allocator maps every block of
    more than MMAP_THRESHOLD for itself and unmaps it when it is freed (glibc raises that threshold by
    itself after the first large block was freed, and then keeps freed 2.4 MB arrays in the process).
    Not for a script's process: its own large numpy arrays would be mapped and unmapped every time."""
    try:
        ctypes.CDLL("libc.so.6").mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
    except (OSError, AttributeError):
        pass   # not glibc: its own rules apply


# -- a shared-memory port Fast DDS took away ------------------------------------------------------
# A process that opens another's shared-memory port (to send to it, or while looking for a free
# one) first checks that its listeners answer; when they do not within healthy_check_timeout
# (1 s, which rmw_fastrtps does not let a profile change under ROS_AUTOMATIC_DISCOVERY_RANGE=
# LOCALHOST), Fast DDS deletes the port's file and makes a new one. A listener that was only slow
# (a machine stalled for a second, a busy 2-core CI box) keeps reading the deleted one: whoever
# joins later writes into the new file and is never heard ("no testbed answers" for a minute, then
# for every later run), while everyone it already knew still reaches it. The node cannot reopen its
# port inside rmw, so it starts afresh once it holds no run (restart_in_place). Our profile keeps
# the testbed off shared memory altogether; this is for a user's own profile (run_node watches only then).

PORT_CHECK_PERIOD = 1.0   # s between looks at this process's shared-memory ports
_PORT_LOCK = re.compile(r"^/dev/shm/fastrtps_port(\d+)_el(?: \(deleted\))?$")   # held while listening
_PORT_MAP = re.compile(r"/dev/shm/fastrtps_port(\d+) \(deleted\)$")


def shared_memory_ports(pid="self"):
    """(listening, lost): the Fast DDS shared-memory ports process `pid` listens on, and those of
    them whose file was deleted under it (no process that opens the port from now on reaches it);
    read from /proc, so (set(), set()) where there is none."""
    listening = set()
    try:
        for fd in os.listdir("/proc/%s/fd" % pid):
            try:
                found = _PORT_LOCK.match(os.readlink("/proc/%s/fd/%s" % (pid, fd)))
            except OSError:
                continue   # closed meanwhile
            if found:
                listening.add(int(found.group(1)))
        if not listening:
            return set(), set()
        with open("/proc/%s/maps" % pid) as maps:
            deleted = {int(found.group(1)) for found in map(_PORT_MAP.search, maps.read().splitlines()) if found}
    except OSError:
        return set(), set()
    return listening, listening & deleted


def restart_in_place(claim_node=None):
    """Start this node afresh in the same process: same pid (so `up`, a launch file or a test still
    holds it), arguments, log and lifeline; a new DDS participant with new ports. Its claim keeps
    its `since`, and it does not wait for older claims again (it was the one running)."""
    if claim_node is not None:
        os.environ[claims.ENV_SINCE] = repr(claim_node.claim.mine["since"])
    os.environ[claims.ENV_CHECKED] = "1"
    keep = lifeline.hand_on(os.environ)
    sys.stdout.flush()
    sys.stderr.flush()
    for fd in map(int, os.listdir("/proc/self/fd")):   # Fast DDS's locks and sockets must not survive
        if fd > 2 and fd not in keep:
            try:
                os.close(fd)
            except OSError:
                pass
    os.execv(sys.executable, sys.orig_argv)


def restart_stuck(name, stuck, claim_node):
    """A participant deadlocked inside Fast DDS (DdsStallWatch): say so on stderr (the node's log; the
    logger would publish to /rosout, through the stuck participant) and start afresh in place, without
    destroying anything of DDS (that would wait for the stuck threads). Never returns."""
    print("[%s] Fast DDS stopped in this process: %s (a deadlock inside Fast DDS, docs/faults.md); "
          "starting afresh in the same process; a run it held is lost" % (name, stuck), file=sys.stderr, flush=True)
    restart_in_place(claim_node)


def check_ports(node, stop, noticed):
    """Look at this process's shared-memory ports (PORT_CHECK_PERIOD): one that Fast DDS took away
    is said once, and the node asks to restart as soon as it is at rest (node.at_rest(): no run to
    lose; a node without at_rest only says so). Returns whether a loss was noticed."""
    lost = sorted(shared_memory_ports()[1])
    if not lost:
        return noticed
    at_rest = getattr(node, "at_rest", None)
    if not noticed:
        node.get_logger().error(
            "Fast DDS deleted this node's shared-memory port %s (another process found it unresponsive "
            "for over a second, as when the machine stalls): processes that start from now on cannot "
            "reach this node; %s" % (", ".join(map(str, lost)), "it restarts as soon as it holds no run"
                                     if at_rest is not None else "restart it"))
    if at_rest is not None and at_rest():
        stop.request("restarting: its shared-memory port %s was deleted" % ", ".join(map(str, lost)), restart=True)
    return True


# -- a Fast DDS participant deadlocked inside --------------------------------------------------------
# Fast DDS 2.14 can deadlock a participant for good (gdb on a stuck simulator, 2026-11-28, load 6 on
# 2 cores; eProsima/Fast-DDS#6502 is the same cycle): a receive thread that removes a remote
# endpoint (a client leaving) holds the discovery (PDP) mutex while it waits, in
# ResourceEvent::unregister_timer, for the event thread to finish its timers, and the event thread's
# timer (WLP::automatic_liveliness_assertion: our presence writers' liveliness) waits for that mutex.
# The node's Python goes on, DDS does not: no announcements, no liveliness, no discovery; the other
# receive threads queue on the same mutex. Processes that start later never find the node, and its
# peers lose it once its lease ends ("no safety node answers", run after run). The event thread
# wakes several times a second (our profile's announcements every 0.2 s, presence liveliness every
# 0.17-0.25 s), so one that has not run for DDS_STALL_LIMIT while the node's own loop has is stuck:
# the node says so and starts afresh (restart_in_place) without touching DDS, which would wait for
# ever. Under a user's own profile (announcements maybe rarer) run_node does not watch.

DDS_STALL_LIMIT = 5.0   # s an event thread may go without running before its participant counts as stuck
DDS_STALL_CHECK = 0.5   # s between looks


def _task_file(tid, name, pid="self"):
    try:
        with open("/proc/%s/task/%d/%s" % (pid, tid, name)) as f:
            return f.read()
    except OSError:
        return None   # the thread ended


def dds_event_threads(pid="self"):
    """{thread id: name} of process `pid`'s Fast DDS event threads ("dds.ev.N", one per participant)."""
    threads = {}
    for entry in os.listdir("/proc/%s/task" % pid):
        comm = _task_file(int(entry), "comm", pid)
        if comm is not None and comm.startswith("dds.ev."):
            threads[int(entry)] = comm.strip()
    return threads


def context_switches(tid):
    """How often thread `tid` of this process gave up or lost the processor (it changes each time the
    thread runs), or None when it ended."""
    status = _task_file(tid, "status")
    if status is None:
        return None
    return sum(int(line.split()[1]) for line in status.splitlines() if "ctxt_switches:" in line)


class DdsStallWatch:
    """Tells when a Fast DDS event thread of this process has stopped running: check() (every
    DDS_STALL_CHECK or so, from the node's loop) returns what is stuck, or None. A gap in the checks
    themselves (the whole process stopped or starved) starts the count again."""

    def __init__(self, limit=DDS_STALL_LIMIT, gap=4 * DDS_STALL_CHECK):
        self.limit = limit
        self.gap = gap    # s between two checks that makes a gap
        self.seen = {}    # thread id -> (context switches, since when unchanged)
        self.last = None  # time of the previous check

    def check(self, now=None):
        now = time.monotonic() if now is None else now
        if self.last is not None and now - self.last > self.gap:
            self.seen.clear()   # this loop did not run either: nothing can be said of the gap
        self.last = now
        stuck = []
        for tid, name in dds_event_threads().items():
            switches = context_switches(tid)
            if switches is None:
                continue
            switched, since = self.seen.get(tid, (None, now))
            if switches != switched:
                self.seen[tid] = (switches, now)
            elif now - since >= self.limit:
                stuck.append("%s (thread %d) has not run for %.1f s" % (name, tid, now - since))
        return "; ".join(stuck) or None


def claim_place(who, name, stop):
    """Claim this node's place in its domain and namespace (robotarium_core.claim) on a small node
    of its own, before the real node offers anything: returns (claim node, identity of an older
    node of this kind or None). Unless the starter looked already, it waits DEFAULT.claim_wait for
    an older claim; one heard later asks `stop` to stop (run_node then exits REFUSED)."""
    node = rclpy.create_node(name + "_claim", namespace=DEFAULT_NAMESPACE)   # as the nodes; __ns:= remaps both

    def older(ident):
        node.refusal = claims.refusal(ident, node.get_namespace(), node.context.get_domain_id())
        stop.request(node.refusal)
    node.refusal = None
    place = claims.Claim(node, who, on_older=older)
    if os.environ.get(claims.ENV_CHECKED) != "1":
        deadline = time.monotonic() + DEFAULT.claim_wait
        while place.older is None and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=max(0.0, deadline - time.monotonic()))
    node.claim = place
    return node, place.older


def help_requested(args=None):
    """Whether the command line (args, or sys.argv; its first entry the program) asks for -h/--help
    before any --ros-args: then a node prints its usage and starts nothing."""
    given = list(sys.argv if args is None else args)[1:]
    if "--ros-args" in given:
        given = given[:given.index("--ros-args")]
    return "-h" in given or "--help" in given


def node_usage(make_node, name):
    """A node's --help: how to start it, what it is (its module's first paragraph), what it reads."""
    from robotarium_core.config import FIELDS
    module = sys.modules.get(getattr(make_node, "__module__", ""), None)
    about = ((module.__doc__ or "").strip().split("\n\n")[0] if module is not None else "").replace("\n", " ")
    spec = getattr(module, "__spec__", None)   # python -m runs the module as __main__; its spec keeps its name
    module_name = spec.name if spec is not None else getattr(module, "__name__", "<module>")
    package = module_name.split(".")[0]
    read = [field for field, spec in FIELDS.items() if name in spec.used_by]
    lines = ["usage: ros2 run %s %s [--ros-args [-r __ns:=/NAMESPACE] [--params-file FILE] [-p NAME:=VALUE ...]]"
             % (package, name), "       python -m %s [the same]" % module_name, "", about]
    if read:
        lines += ["", "Parameters: the testbed configuration's (robotarium_core/testbed.yaml, every value explained "
                      "there; ./robotarium up --config FILE): " + ", ".join(read) + "."]
    lines += ["", "./robotarium up starts it with the rest of the testbed (ros2 launch robotarium_bringup "
                  "testbed.launch.py too)."]
    return "\n".join(lines)


def run_node(make_node, name, args=None, before_destroy=None, claim=None):
    """rclpy.init, make the node (a bad parameter exits with code 2 and its message), spin until a
    stop is requested (StopRequest), wind down, then clean up. Returns the process exit code.

    Winding down, while DDS still works: a node with a `wind_down(reason)` method is told why it
    stops; it may return a predicate "done", and the node keeps spinning until that holds or
    WIND_DOWN_LIMIT passed (a second signal cuts it short). So on Ctrl-C, `kill`, or the death of
    the process that started the testbed, the simulator ends the running experiment and the recorder
    records that end and closes the bag before anything exits. Nodes started with `ros2 run` get
    no lifeline and stop on the signals alone. A node started behind a start gate
    (lifeline.StartGate: ./robotarium run, while it looks for a testbed) waits there first and
    exits at once (0) when the gate is closed without opening.

    claim: the node's kind (robotarium_core.presence.SIMULATOR, ...): one of each per domain and
    namespace (claim_place); a node that finds an older one prints one line naming it and exits
    with claim.REFUSED (4), before it offers anything, or as soon as it hears of it later."""
    if help_requested(args):
        print(node_usage(make_node, name))
        return 0
    if not lifeline.pass_start_gate():
        return 0
    return_freed_memory()
    # kill -USR1 PID: every thread's Python stack into the node's log (where is a node that stopped answering?)
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    # rclpy's own handlers would shut the context down at the first signal, before the wind-down.
    init_context(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = StopRequest()
    claim_node = None
    if claim is not None:
        claim_node, older = claim_place(claim, name, stop)
        if older is not None:
            print("%s: %s" % (name, claim_node.refusal), file=sys.stderr, flush=True)
            claim_node.destroy_node()
            rclpy.try_shutdown()
            return claims.REFUSED
    try:
        node = make_node()
    except (ValueError, AssertionError, ParameterException) as error:
        print("%s: %s" % (name, error), file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    executor = LeanExecutor()
    executor.add_node(node)
    if claim_node is not None:
        executor.add_node(claim_node)
    stop.attach(node)
    # Only a user's own profile brings the shared-memory transport back: ours has no port to lose.
    # Ours has the event thread announce every 0.2 s: only then is 5 s without it running a stall.
    ours = _ours(os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", DDS_PROFILE))
    watch_ports, watch_stalls = not ours, ours
    ports_lost, next_check = False, time.monotonic() + PORT_CHECK_PERIOD
    stalls, next_stall_check = DdsStallWatch(), time.monotonic()
    try:
        while stop.reason is None and rclpy.ok():
            executor.spin_once(timeout_sec=0.2)   # a signal's Python handler runs between waits
            if watch_ports and time.monotonic() >= next_check:
                ports_lost, next_check = check_ports(node, stop, ports_lost), time.monotonic() + PORT_CHECK_PERIOD
            if watch_stalls and time.monotonic() >= next_stall_check:
                next_stall_check = time.monotonic() + DDS_STALL_CHECK
                stuck = stalls.check()
                if stuck is not None:
                    restart_stuck(name, stuck, claim_node)
        if stop.reason is not None and rclpy.ok():
            node.get_logger().info("stopping: %s" % stop.reason)
            wind_down = getattr(node, "wind_down", None)
            done = wind_down(stop.reason) if wind_down is not None else None
            deadline = time.monotonic() + WIND_DOWN_LIMIT
            while (done is not None and not done() and stop.signals < 2 and rclpy.ok()
                   and time.monotonic() < deadline):
                executor.spin_once(timeout_sec=0.05)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if before_destroy is not None:
            before_destroy(node)
        executor.shutdown()
        node.destroy_node()
        if claim_node is not None:
            claim_node.destroy_node()
        rclpy.try_shutdown()
    if claim_node is not None and claim_node.refusal is not None:
        print("%s: %s" % (name, claim_node.refusal), file=sys.stderr, flush=True)
        return claims.REFUSED
    if stop.restart:
        restart_in_place(claim_node)
    return 0
