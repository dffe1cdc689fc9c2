"""A testbed node's main (run_node): --help from its module's docstring, the start gate, its claim
on its place, then spin (LeanExecutor) until a signal or its lifeline says stop (StopRequest),
with the watchdogs the node hands it; then wind down while DDS still works, clean up, and exit,
or start afresh in the same process (restart_in_place: same pid, arguments, log and lifeline).
How a node winds down and why: docs/faults.md.
"""
import faulthandler
import os
import signal
import sys
import time

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions

from robotarium_core import claim as claims
from robotarium_core import lifeline, restarts
from robotarium_core.config import DEFAULT, FIELDS
from robotarium_core.dds_settings import init_context, return_freed_memory
from robotarium_core.executor import LeanExecutor
from robotarium_core.topics import DEFAULT_NAMESPACE

# The longest a node spends winding down after it was asked to stop (the simulator ending its
# experiment, the recorder closing the run's bag); then it exits whatever is left.
WIND_DOWN_LIMIT = 2.0
STOP_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")


class StopRequest:
    """Why a node should stop: a signal (SIGINT, SIGTERM, SIGHUP: Ctrl-C, `kill`, a closed
    terminal) or its lifeline (the process that started it is gone, SIGKILL included: see
    robotarium_core.lifeline). Made before the node, so a signal during start-up is kept too; once
    attached to the node either one wakes its executor at once through a guard condition."""

    def __init__(self, name):
        self.name = name
        self.claim_node = None   # the node's claim (attach): a restart keeps its `since`
        self.reason = None
        self.restart = False   # stop, then start afresh in this process (restart_in_place)
        self.signals = 0
        self._wake = None
        for signal_name in STOP_SIGNALS:
            signal.signal(getattr(signal, signal_name), self._on_signal)
        parent = os.getppid()
        lifeline.watch(lambda: self.request("the process that started this testbed (pid %d) is gone" % parent))

    def attach(self, node, claim_node=None):
        self.claim_node = claim_node
        self._wake = node.create_guard_condition(lambda: None)
        if self.reason is not None:
            self._wake.trigger()

    def _on_signal(self, signum, frame):
        self.signals += 1
        self.request("received %s" % signal.Signals(signum).name)

    def request(self, reason, restart=False):
        """Stop (wind down, clean up) for `reason`; with restart, then start afresh (restart_in_place)."""
        if self.reason is None:
            self.reason, self.restart = reason, restart
        if self._wake is not None:
            self._wake.trigger()

    def restart_now(self, reason, cause=None):
        """Start afresh at once (a watchdog found DDS stuck), destroying nothing of DDS: that would wait
        for the stuck threads. Says why on stderr (the node's log; the logger would publish to /rosout,
        through the stuck participant); `cause`, in short, is what the restarted node announces
        (robotarium_core.restarts). Never returns."""
        print("[%s] %s" % (self.name, reason), file=sys.stderr, flush=True)
        restart_in_place(self.claim_node, cause or reason)


def restart_in_place(claim_node=None, cause=None):
    """Start this node afresh in the same process: same pid (so `up`, a launch file or a test still
    holds it), arguments, log and lifeline; a new DDS participant with new ports. Its claim keeps
    its `since`, and it does not wait for older claims again (it was the one running). A node that
    claims a place announces, once back, that it restarted and why (`cause`; robotarium_core.restarts):
    a client whose run it served names that as the run's end."""
    if claim_node is not None:
        os.environ[claims.ENV_SINCE] = repr(claim_node.claim.mine["since"])
        if cause:
            os.environ[restarts.ENV] = restarts.in_place(
                claim_node.claim.mine["who"], cause, restarts.of_this_process()).to_json()
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


def run_node(make_node, name, args=None, before_destroy=None, claim=None, watchdogs=()):
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
    with claim.REFUSED (4), before it offers anything, or as soon as it hears of it later.

    watchdogs: callables watchdog(node, stop), each called from the node's loop at start and every
    `watchdog.period` seconds after (robotarium_core.dds_health.fast_dds_watchdogs: the Fast DDS
    faults a testbed node watches for); one may ask `stop` to stop, restart, or restart_now."""
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
    stop = StopRequest(name)
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
        restarted = restarts.of_this_process()
        if restarted is not None and restarted.by == restarts.IN_PLACE:   # (up announces its own restarts)
            claim_node.restart_announcement = restarts.announce(claim_node, restarted.back())
    stop.attach(node, claim_node)
    watchdogs = list(watchdogs)
    due = [time.monotonic()] * len(watchdogs)   # when each watchdog is called next
    try:
        while stop.reason is None and rclpy.ok():
            executor.spin_once(timeout_sec=0.2)   # a signal's Python handler runs between waits
            for i, watchdog in enumerate(watchdogs):
                if time.monotonic() >= due[i]:
                    due[i] = time.monotonic() + watchdog.period
                    watchdog(node, stop)
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
        restart_in_place(claim_node, stop.reason)
    return 0
