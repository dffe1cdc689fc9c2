"""What every testbed node does the same way: the testbed configuration as ROS parameters, and a
main() that spins (robotarium_core.executor.LeanExecutor: a fraction of the cost per callback
of rclpy's default executor) until a signal or its lifeline says stop, then winds down cleanly.

Kept apart from model.py and config.py (no ROS there); the nodes themselves stay thin shells.
"""
import ctypes
import math
import os
import signal
import sys
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

    def request(self, reason):
        if self.reason is None:
            self.reason = reason
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


def dds_defaults(node=True):
    """The testbed's Fast DDS settings (dds_profile.xml; a profile file the user set is kept, and with
    it their choice), for its nodes and a script's client alike: a participant announced every 0.2 s,
    so a process that joins later finds it at once; writers that send a heartbeat every 0.1 s, so a
    lost packet is sent again at once. A node's readers also allocate a sample's buffer when it arrives
    and free it when it is taken (issue 22: a flood costs no memory that stays), for which rmw_fastrtps
    must take the policies it would set itself from the file (RMW_FASTRTPS_USE_QOS_FROM_XML), data
    sharing among them; a client (node=False) keeps rmw's, data sharing off: a script in a job box runs
    as an account that may not open the testbed's shared segments. Called before rclpy.init."""
    # (ours, inherited from a client that started a testbed for its script, is not the user's choice)
    if os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", DDS_PROFILE) == DDS_PROFILE:
        os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = DDS_PROFILE
        if node:
            os.environ["RMW_FASTRTPS_USE_QOS_FROM_XML"] = "1"   # only for the policies our code leaves to it


def return_freed_memory():
    """A node's freed large blocks go back to the system (issue 22): the C allocator maps every block of
    more than MMAP_THRESHOLD for itself and unmaps it when it is freed (glibc raises that threshold by
    itself after the first large block was freed, and then keeps freed 2.4 MB arrays in the process).
    Not for a script's process: its own large numpy arrays would be mapped and unmapped every time."""
    try:
        ctypes.CDLL("libc.so.6").mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
    except (OSError, AttributeError):
        pass   # not glibc: its own rules apply


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
    if not lifeline.pass_start_gate():
        return 0
    dds_defaults()
    return_freed_memory()
    # rclpy's own handlers would shut the context down at the first signal, before the wind-down.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
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
    try:
        while stop.reason is None and rclpy.ok():
            executor.spin_once(timeout_sec=0.2)   # a signal's Python handler runs between waits
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
    return 0
