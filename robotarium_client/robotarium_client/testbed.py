"""Finding a testbed on the DDS domain, or starting one on this machine for a script.

The testbed is three nodes: the simulator, the safety node and the recorder. `LocalTestbed`
runs them as subprocesses (the embedded default of `./robotarium run` and of a script run with
no testbed around) and stops them again; `./robotarium up` keeps one running until Ctrl-C.
"""
import os
import signal
import subprocess
import sys
import time

from robotarium_core.config import DEFAULT_FILE
from robotarium_core.topics import DEFAULT_NAMESPACE

NODES = {
    # name: (module, whether it reads the testbed configuration)
    "simulator": ("robotarium_sim.simulator_node", True),
    "safety": ("robotarium_safety.safety_node", True),
    "recorder": ("robotarium_recording.recorder_node", False),
}


def repository_root():
    """The checkout this code runs from (./robotarium exports it), else the working directory."""
    return os.environ.get("ROBOTARIUM_ROOT") or os.getcwd()


def namespace():
    ns = os.environ.get("ROBOTARIUM_NAMESPACE", DEFAULT_NAMESPACE).strip("/")
    return "/" + ns


def node_command(name, ns=None, extra_ros_args=(), config_file=DEFAULT_FILE):
    """The command line of one testbed node; the simulator and the safety node read the same
    testbed configuration file (the packaged testbed.yaml unless another is given)."""
    module, configured = NODES[name]
    cmd = [sys.executable, "-m", module, "--ros-args", "-r", "__ns:=%s" % (ns or namespace())]
    if configured:
        cmd += ["--params-file", config_file or DEFAULT_FILE]
    return cmd + list(extra_ros_args)


class LocalTestbed:
    """Simulator, safety node and recorder in subprocesses, stopped together."""

    def __init__(self, log_dir=None, record=True, ns=None, bags_dir=None, quiet=True, config_file=None):
        self.ns = ns or namespace()
        self.config_file = config_file
        self.log_dir = log_dir or os.path.join(repository_root(), "log", "testbed")
        self.names = ["simulator", "safety"] + (["recorder"] if record else [])
        self.bags_dir = bags_dir
        self.quiet = quiet
        self.processes = {}

    def start(self):
        os.makedirs(self.log_dir, exist_ok=True)
        for name in self.names:
            extra = ["-p", "bags_dir:=%s" % self.bags_dir] if name == "recorder" and self.bags_dir else []
            log = open(os.path.join(self.log_dir, name + ".log"), "wb") if self.quiet else None
            self.processes[name] = (subprocess.Popen(
                node_command(name, self.ns, extra, self.config_file), stdout=log, stderr=subprocess.STDOUT if log else None,
                start_new_session=True), log)
        return self

    def failed(self):
        """Names of nodes that exited, with their exit codes."""
        return {name: p.returncode for name, (p, _) in self.processes.items() if p.poll() is not None}

    def stop(self, grace=5.0):
        """SIGINT everyone (the recorder closes its bag), then SIGKILL what is left."""
        for process, _ in self.processes.values():
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGINT)
        deadline = time.monotonic() + grace
        for process, log in self.processes.values():
            try:
                process.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
            if log:
                log.close()
        self.processes = {}

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


def testbed_answers(ns=None, timeout=3.0):
    """True when a simulator on this DDS domain offers <ns>/start_experiment within `timeout`."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    from robotarium_msgs.srv import StartExperiment

    context = Context()
    rclpy.init(context=context, args=[])
    try:
        node = Node("robotarium_probe_%d" % os.getpid(), context=context)
        client = node.create_client(StartExperiment, "%s/start_experiment" % (ns or namespace()))
        found = client.wait_for_service(timeout_sec=timeout)
        node.destroy_node()
        return found
    finally:
        rclpy.try_shutdown(context=context)
