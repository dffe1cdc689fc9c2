"""Helpers for node-level tests: real nodes in subprocesses, each test on its own DDS domain.

- `unique_domain_id()` hands out a ROS_DOMAIN_ID no other process on this machine holds (a file
  lock); discovery is localhost-only, so tests cannot hear each other or the network.
- `NodeProcess` starts `python -m MODULE` from the source tree in its own process group and always
  kills the whole group on close (SIGINT, then SIGKILL).
- `RosProbe` is an rclpy node in a private context on a given domain, with small synchronous
  helpers (call a service, wait for messages).
- `SafetyStandIn` plays the safety node's part on a probe, for tests of the simulator alone.
"""
import ctypes
import os
import signal
import subprocess
import sys
import time

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from devtools import PACKAGE_SOURCES, REPO
from robotarium_bringup.domains import unique_domain_id  # noqa: F401 - the tests' own domains, from here
from robotarium_core.dds_health import close_unless_stuck
from robotarium_core.dds_settings import init_context
from robotarium_core.discovery import wait_for_quiet_discovery
from robotarium_core.topics import CMD_SAFE, SAFETY_ARM, SAFETY_REPORT, SAFETY_REPORT_QOS, TESTBED_QOS


def node_env(domain_id, **extra):
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)
    env["PYTHONPATH"] = os.pathsep.join(PACKAGE_SOURCES + [REPO, env.get("PYTHONPATH", "")])
    env["PYTHONUNBUFFERED"] = "1"
    env["MPLBACKEND"] = "Agg"
    env.update({k: str(v) for k, v in extra.items()})
    return env


class NodeProcess:
    """A node (or any `python -m` module) in a subprocess of its own process group."""

    def __init__(self, module, domain_id, args=(), ros_args=(), log_path=None, env=None):
        self.module = module
        cmd = [sys.executable, "-m", module, *args]
        if ros_args:
            cmd += ["--ros-args", *ros_args]
        self.log_path = log_path
        self._log = open(log_path, "wb") if log_path else subprocess.DEVNULL
        # the lifeline: a node winds down when this process is gone, also when a test run crashes
        from robotarium_core import lifeline
        env, pass_fds = lifeline.for_child(env or node_env(domain_id))
        self.proc = subprocess.Popen(cmd, env=env, stdout=self._log, stderr=subprocess.STDOUT,
                                     start_new_session=True, cwd=REPO, pass_fds=pass_fds)

    def alive(self):
        return self.proc.poll() is None

    def kill(self, sig=signal.SIGKILL):
        if self.alive():
            os.killpg(self.proc.pid, sig)

    def close(self, grace=3.0):
        if self.alive():
            try:
                os.killpg(self.proc.pid, signal.SIGINT)
                self.proc.wait(timeout=grace)
            except (subprocess.TimeoutExpired, ProcessLookupError):
                pass
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait()
        if self._log is not subprocess.DEVNULL:
            self._log.close()

    def output(self):
        if not self.log_path:
            return ""
        with open(self.log_path, "rb") as f:
            return f.read().decode(errors="replace")

    def stacks(self, wait=0.5):
        """Every thread's Python stack of a node started by node_main.run_node (SIGUSR1 makes it
        write them to its log), as its log has them; for the message of a test that found it stuck."""
        if not self.alive() or not self.log_path:
            return ""
        before = len(self.output())
        os.kill(self.proc.pid, signal.SIGUSR1)
        time.sleep(wait)
        return self.output()[before:]


class FrozenThread:
    """One thread of another process stopped for real, as a deadlock stops it: ptrace's PTRACE_SEIZE,
    then PTRACE_INTERRUPT stops that thread alone while the rest of its process runs on. A traced
    thread that ends (its process execs or exits) waits for its tracer: gone() reaps it."""

    _SEIZE, _INTERRUPT, _DETACH = 0x4206, 0x4207, 17
    _WALL = 0x40000000   # waitpid's __WALL: threads too

    def __init__(self, tid):
        self.tid = tid
        self._libc = ctypes.CDLL(None, use_errno=True)
        self._libc.ptrace.argtypes = [ctypes.c_long, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
        for request in (self._SEIZE, self._INTERRUPT):
            if self._libc.ptrace(request, tid, None, None) != 0:
                raise OSError(ctypes.get_errno(), "ptrace(%#x) of thread %d failed" % (request, tid))

    def gone(self):
        """Whether the thread has ended (and is reaped)."""
        try:
            while True:
                tid, status = os.waitpid(self.tid, os.WNOHANG | self._WALL)
                if tid == 0:
                    return False
                if os.WIFEXITED(status) or os.WIFSIGNALED(status):
                    return True
        except ChildProcessError:
            return True

    def release(self):
        """Let it run on, if it is still there."""
        if not self.gone():
            self._libc.ptrace(self._DETACH, self.tid, None, None)


class RosProbe:
    """An rclpy node in its own context on `domain_id`, spun by hand from the test."""

    def __init__(self, domain_id, name="probe"):
        self.context = Context()
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        # as the testbed's processes start theirs (UDP only): Fast DDS reads its profile once per process
        init_context(context=self.context, domain_id=domain_id, node=False)
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._subscriptions = []
        self._presences = []
        self._clients = {}

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))

    def spin_until(self, predicate, timeout):
        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > end:
                return False
            self.executor.spin_once(timeout_sec=0.05)
        return True

    def call(self, srv_type, name, request, timeout=10.0, resend=None):
        """The service's answer to `request`. With `resend` (seconds; only for a request that is the
        same however often it is done, as ArmSafety or a refused start is) it is sent again while
        unanswered, as the simulator does: a service found a moment ago may not yet have matched this
        client's reply reader, and rmw_fastrtps then drops the reply (it waits 100 ms for that match;
        seen on a loaded machine: no answer in 10 s). One client per service is kept, so that a reply
        path matched once (see start_experiment) stays matched for the calls after it."""
        key = (srv_type, name)
        if key not in self._clients:
            self._clients[key] = self.node.create_client(srv_type, name)
        client = self._clients[key]
        if not client.wait_for_service(timeout_sec=timeout):
            raise TimeoutError("service %s did not appear within %.0f s" % (name, timeout))
        deadline = time.monotonic() + timeout
        while True:
            future = client.call_async(request)
            wait = deadline - time.monotonic() if resend is None else min(resend, deadline - time.monotonic())
            if self.spin_until(future.done, max(wait, 0.0)):
                return future.result()
            client.remove_pending_request(future)
            if time.monotonic() >= deadline:
                raise TimeoutError("service %s did not answer within %.0f s" % (name, timeout))

    def start_experiment(self, request, namespace="/robotarium"):
        """Start an experiment as its client (see hold_client_presence). A successful start must not be
        sent twice, so its reply must not be dropped (see call): the first time, a start the simulator
        refuses however often it comes (an invalid name) is sent until answered, which leaves this
        probe's reply reader matched for the real one."""
        from robotarium_msgs.srv import StartExperiment
        service = namespace.rstrip("/") + "/start_experiment"
        if (StartExperiment, service) not in self._clients:
            self.call(StartExperiment, service, StartExperiment.Request(name="!"), timeout=30.0, resend=1.0)
        # The streams are volatile: the run's first poses wait for our reader of them, if we have one.
        ns = namespace.rstrip("/")
        topics = {s.topic_name for s in self._subscriptions}
        if not request.client_node and ns + "/poses" in topics and (request.api != "2" or ns + "/sensors" in topics):
            request.client_node = self.node.get_fully_qualified_name()
        return self.hold_client_presence(self.call(StartExperiment, service, request))

    def hold_client_presence(self, response):
        """Be the client of the experiment a StartExperiment `response` started: hold the presence
        the testbed watches (else it ends the experiment as "client lost" after a few seconds)."""
        from robotarium_core.presence import Presence
        if response.success:
            self._presences.append(Presence(self.node, response.client_alive_topic, response.client_lease))
        return response

    def drop_client_presences(self):
        """Stop being the client of the experiments this probe started: their liveliness ends."""
        for held in self._presences:
            held.destroy()
        self._presences.clear()

    def collect(self, msg_type, topic, qos=TESTBED_QOS):
        """Subscribe and return the list that received messages are appended to. With the
        testbed's QoS (volatile streams) what comes once matched: subscribe before the run starts."""
        received = []
        self._subscriptions.append(self.node.create_subscription(msg_type, topic, received.append, qos))
        return received

    def wait_for_publishers(self, timeout=15.0):
        """Wait until discovery matched every subscription made with collect() to a publisher:
        messages published before that are not delivered."""
        if not self.spin_until(lambda: all(s.get_publisher_count() > 0 for s in self._subscriptions), timeout):
            missing = [s.topic_name for s in self._subscriptions if s.get_publisher_count() == 0]
            raise TimeoutError("no publisher matched %s within %.0f s" % (missing, timeout))

    def close(self):
        """The node and its context go; a participant Fast DDS deadlocked is left behind instead of
        hanging the test (dds_health.close_unless_stuck: the test goes on, the process says so).
        Returns whether it was closed."""
        def close():
            self.executor.shutdown()
            self.node.destroy_node()
            rclpy.try_shutdown(context=self.context)
        return close_unless_stuck(close, "the test's probe %s" % self.node.get_name(), settle=lambda: (
            wait_for_quiet_discovery(self.node, still=0.2, timeout=2.0)))   # before the participant goes


def processes_on_domain(domain_id):
    """{pid: command line} of every live process on this machine whose environment has this
    ROS_DOMAIN_ID: with a domain of one's own (unique_domain_id), every process a test started
    there, however it was started or orphaned, and nothing else."""
    return processes_with_env("ROS_DOMAIN_ID", domain_id)


def processes_with_env(name, value):
    """{pid: command line} of every live process on this machine whose environment has name=value."""
    wanted = ("%s=%s" % (name, value)).encode()
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open("/proc/%s/environ" % entry, "rb") as f:
                if wanted not in f.read().split(b"\0"):
                    continue
            with open("/proc/%s/cmdline" % entry, "rb") as f:
                found[int(entry)] = f.read().replace(b"\0", b" ").decode(errors="replace").strip()
        except OSError:   # gone meanwhile, or not ours to read
            continue
    return found


class CliRun:
    """`./robotarium run ARGS` (python -m robotarium_cli) in a session of its own, its
    output collected line by line; wait_for(text) waits until a line contains text."""

    def __init__(self, args, env, cwd):
        import threading
        self.lines = []
        self._changed = threading.Condition()
        self.proc = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "run", *args], env=env, cwd=cwd,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for raw in iter(self.proc.stdout.readline, b""):
            with self._changed:
                self.lines.append(raw.decode(errors="replace").rstrip("\n"))
                self._changed.notify_all()
        with self._changed:
            self.lines.append(None)   # end of output
            self._changed.notify_all()

    def wait_for(self, text, timeout):
        with self._changed:
            return self._changed.wait_for(lambda: any(line is None or text in line for line in self.lines),
                                          timeout) and any(line is not None and text in line for line in self.lines)

    def output(self):
        return "\n".join(line for line in self.lines if line is not None)

    def wait(self, timeout):
        code = self.proc.wait(timeout=timeout)
        self._reader.join(timeout)
        return code

    def close(self):
        """Never leave it behind: SIGKILL the whole session if it still runs."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.proc.wait()


class SafetyStandIn:
    """The safety node's part, played by a probe, for tests that drive the simulator alone: it
    answers <ns>/safety/arm (so the simulator starts experiments and hands it the safety key) and
    publishes command arrays on cmd_safe carrying that key, each with its SafetyReport (a pass-through),
    as the safety node does. A real-time array sent unnumbered (step 0) is marked as the safety node
    marks it: the newest poses' step plus one (robotarium_core.model.StepGate takes nothing else)."""

    def __init__(self, probe, ns="/robotarium"):
        from robotarium_msgs.msg import RobotPoses, SafetyReport, TwistArray
        from robotarium_msgs.srv import ArmSafety
        self.probe = probe
        self.armed = ArmSafety.Request()
        self.arms = []    # every ArmSafety request received
        self.service = probe.node.create_service(ArmSafety, "%s/%s" % (ns, SAFETY_ARM), self._on_arm)
        self.publisher = probe.node.create_publisher(TwistArray, "%s/%s" % (ns, CMD_SAFE), TESTBED_QOS)
        self.reports = probe.node.create_publisher(SafetyReport, "%s/%s" % (ns, SAFETY_REPORT), SAFETY_REPORT_QOS)
        self.poses_step = -1
        self.poses = probe.node.create_subscription(RobotPoses, "%s/poses" % ns, self._on_poses, TESTBED_QOS, raw=True)

    def _on_poses(self, data):
        from robotarium_core import cdr
        msg = cdr.ROBOT_POSES.parse(data)
        if msg.key == self.armed.poses_key:
            self.poses_step = max(self.poses_step, msg.step)

    def _on_arm(self, request, response):
        self.armed = request
        self.poses_step = -1
        self.arms.append(request)
        response.success = True
        return response

    def wait_for_simulator(self, timeout=30.0):
        """Until the simulator listens on cmd_safe and safety_report."""
        if not self.probe.spin_until(lambda: self.publisher.get_subscription_count() > 0
                                     and self.reports.get_subscription_count() > 0, timeout):
            raise TimeoutError("the simulator did not subscribe to cmd_safe and safety_report within %.0f s" % timeout)

    def publish(self, msg, report=True):
        """Publish `msg` (a TwistArray) on cmd_safe with the safety key of the armed experiment, and its
        SafetyReport (without `report`, the test sends it: publish_report)."""
        msg.token = self.armed.safety_key
        if self.armed.real_time and msg.step == 0:
            from robotarium_core.subscriptions import take_waiting
            for data in take_waiting(self.poses):
                self._on_poses(data)
            if self.poses_step < 0 and not self.probe.spin_until(lambda: self.poses_step >= 0, 10):
                raise TimeoutError("no poses of the armed experiment within 10 s")
            msg.step = self.poses_step + 1
        self.publisher.publish(msg)
        if report:
            self.publish_report(msg.step)

    def publish_report(self, step, status=None, max_change=0.0):
        """The SafetyReport of the array for `step` (a pass-through unless `status` says otherwise)."""
        from robotarium_msgs.msg import SafetyReport
        self.reports.publish(SafetyReport(step=step, max_change=max_change,
                                          status=SafetyReport.STATUS_PASSTHROUGH if status is None else status))
