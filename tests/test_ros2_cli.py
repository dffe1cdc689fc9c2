"""The ROS 2 user's way in, with the real ros2 command line (../shared/ros2-tools: ros2cli and
ros2 launch, Jazzy) against the real nodes: ros2 run with the packaged parameters file, parameters
described and refused, an experiment started and ended with ros2 service call and driven with
ros2 topic pub at its default QoS, ros2 topic hz, ros2 launch of the testbed that
ros2 robotarium run --no-local-testbed then uses, and the ros2 robotarium command itself.

The CLI is slow to start (1-3 s a call on 2 cores), so the checks share one testbed per test.
Skipped, saying why, where ../shared/ros2-tools is absent (a user's clone)."""
import json
import os
import re
import signal
import subprocess
import time

import numpy as np
import pytest

from devtools.rosutil import REPO, RosProbe, node_env, unique_domain_id
from robotarium_msgs.msg import RobotPoses

pytestmark = pytest.mark.e2e   # the real ros2 CLI against a launched testbed

TOOLS = os.path.normpath(os.path.join(REPO, "..", "shared", "ros2-tools"))
ROS2 = os.path.join(TOOLS, "ros2")
PARAMS = os.path.join(REPO, "install", "share", "robotarium_core", "config", "testbed.yaml")


@pytest.fixture(scope="module")
def ros2():
    """The ros2 command in .ros2-tools/, which ./robotarium test builds with the shared setup.sh
    before the tests start (~40 s once); here a stamp check (under a second), or the build where a
    plain pytest runs without it."""
    if not os.path.isfile(ROS2):
        pytest.skip("the ROS 2 command-line tools are not here (%s is missing: a clone without ../shared); "
                    "these tests need the real ros2 CLI" % TOOLS)
    built = subprocess.run([os.path.join(TOOLS, "setup.sh"), REPO], capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, "building the ros2 tools failed:\n%s" % built.stderr[-3000:]
    return ROS2


class Cli:
    """ros2 commands on one private domain (localhost discovery), and the processes left running."""

    def __init__(self, ros2, domain, **env):
        self.ros2 = ros2
        self.env = node_env(domain, ROS2_TOOLS_PROJECT=REPO, **env)
        self.running = []

    def run(self, *args, timeout=60):
        """Run `ros2 ARGS` to its end; its stdout and stderr together."""
        return self.gather([args], timeout)[0]

    def gather(self, commands, timeout=60):
        """Run several `ros2` commands at once (each takes seconds to start) to their ends; their
        outputs. A node the daemon has not discovered yet ("Node not found": it learns names 1-2 s
        after it starts) is asked again."""
        deadline = time.monotonic() + 15
        outputs = [None] * len(commands)
        while None in outputs:
            todo = [k for k, out in enumerate(outputs) if out is None]
            started = time.monotonic()
            running = {k: subprocess.Popen([self.ros2, *commands[k]], env=self.env, stdout=subprocess.PIPE,
                                           stderr=subprocess.STDOUT, text=True) for k in todo}
            for k, process in running.items():
                try:
                    out = process.communicate(timeout=max(0.1, started + timeout - time.monotonic()))[0]
                except subprocess.TimeoutExpired:
                    for other in running.values():
                        other.kill()
                        other.wait()
                    raise AssertionError("ros2 %s did not finish within %g s" % (" ".join(commands[k]), timeout)) from None
                if process.returncode == 0 or "Node not found" not in out or time.monotonic() > deadline:
                    assert process.returncode == 0, "ros2 %s failed (%d):\n%s" % (
                        " ".join(commands[k]), process.returncode, out)
                    outputs[k] = out
        return outputs

    def start(self, *args, log=None, command=None):
        """Start `ros2 ARGS` (or `command`) in a session of its own: a terminal's Ctrl-C reaches its
        whole process group, as stop() does."""
        out = open(log, "w") if log else subprocess.DEVNULL
        process = subprocess.Popen(command or [self.ros2, *args], env=self.env, stdout=out, stderr=subprocess.STDOUT,
                                   start_new_session=True, cwd=REPO)
        self.running.append(process)
        return process

    @staticmethod
    def stop(process, timeout=15):
        """Ctrl-C to its process group; SIGKILL what is left after `timeout`. Its exit code."""
        if process.poll() is None:
            try:
                os.killpg(process.pid, signal.SIGINT)
                process.wait(timeout=timeout)
            except (subprocess.TimeoutExpired, ProcessLookupError):
                pass
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        return process.wait()

    def close(self):
        for process in reversed(self.running):
            self.stop(process)
        # the daemon that ros2 node/param/topic start for this domain would outlive the test
        subprocess.run([self.ros2, "daemon", "stop"], env=self.env, capture_output=True, timeout=30)


def field(response, name):
    """A field of a service response as `ros2 service call` prints it (Response(name='value', ...))."""
    match = re.search(r"\b%s=('(?:[^'\\]|\\.)*'|[^,)]+)" % name, response)
    assert match, "no %s in:\n%s" % (name, response)
    value = match.group(1)
    return value[1:-1] if value.startswith("'") else value


def test_ros2_run_param_service_call_topic_pub_and_hz(ros2, tmp_path):
    domain = unique_domain_id()
    cli = Cli(ros2, domain)
    probe = RosProbe(domain)
    try:
        bags = tmp_path / "bags"
        for package, executable in (("robotarium_sim", "simulator"), ("robotarium_safety", "safety"),
                                    ("robotarium_recording", "recorder")):
            cli.start("run", package, executable, "--ros-args", "--params-file", PARAMS, "-p", "bags_dir:=%s" % bags,
                      log=tmp_path / ("%s.log" % executable))
        cli.start("daemon", "start")   # while the nodes start: ros2 param asks it for the node names
        poses = probe.collect(RobotPoses, "/robotarium/poses")

        # Every start-up parameter explains itself, and is refused when set on a running node; an
        # experiment started from the command line (its token is in the response).
        describe, refused, started = cli.gather([
            ("param", "describe", "/robotarium/simulator", "rate", "command_timeout"),
            ("param", "set", "/robotarium/simulator", "rate", "10.0"),
            ("service", "call", "/robotarium/start_experiment", "robotarium_msgs/srv/StartExperiment",
             "{name: cli, number_of_robots: 2, real_time: true, x: [-0.5, 0.5], y: [0.0, 0.3], theta: [0.0, 0.0]}")])
        assert "Description: Hz of the real-time loop" in describe and "Read only: true" in describe
        assert "Description: s; a robot whose last command is older stops" in describe
        assert "Setting parameter failed" in refused and "read-only" in refused, repr(refused)
        assert field(started, "success") == "True", started
        token, alive = field(started, "token"), field(started, "client_alive_topic")
        # The client's presence, held as a CLI user would (else the testbed ends the run as "client lost")
        cli.start("topic", "pub", alive, "std_msgs/msg/Empty", "{}", "--rate", "1", "--qos-liveliness", "automatic",
                  "--qos-liveliness-lease-duration-seconds", "1")
        hz = cli.start("topic", "hz", "/robotarium/poses", "--window", "30", log=tmp_path / "hz.log")
        assert probe.spin_until(lambda: poses and poses[-1].run_id == field(started, "run_id"), 20)
        x_before = np.array(poses[-1].x)

        # Driven with ros2 topic pub at its default QoS (reliable, volatile): the robots move. It
        # publishes until they do: the safety node's side of the match may come a heartbeat or more
        # after the publisher's (1-3 s on a loaded machine), and a volatile publisher that had already
        # sent its last array and exited (as with --times 30) delivered nothing at all.
        pub = cli.start("topic", "pub", "--rate", "30", "/robotarium/cmd_requested", "robotarium_msgs/msg/TwistArray",
                        "{token: '%s', ids: [0, 1], twists: [{linear: {x: 0.1}}, {linear: {x: 0.1}}]}" % token,
                        log=tmp_path / "pub.log")
        moved = lambda: np.array(poses[-1].x) - x_before   # noqa: E731
        assert probe.spin_until(lambda: np.all(moved() > 0.03), 30), (
            "ros2 topic pub did not move the robots (moved %s)\npub log: %s\nsafety log: %s" % (
                moved(), (tmp_path / "pub.log").read_text(), (tmp_path / "safety.log").read_text()))
        cli.stop(pub)

        # ros2 topic hz of the poses: the 30 Hz real-time loop (only a sane range: the machine is shared)
        assert probe.spin_until(lambda: "average rate" in (tmp_path / "hz.log").read_text(), 20), (
            (tmp_path / "hz.log").read_text())
        cli.stop(hz)
        rates = [float(r) for r in re.findall(r"average rate: ([0-9.]+)", (tmp_path / "hz.log").read_text())]
        assert rates and 10 < rates[-1] < 60, (tmp_path / "hz.log").read_text()

        ended = cli.run("service", "call", "/robotarium/end_experiment", "robotarium_msgs/srv/EndExperiment",
                        "{token: '%s'}" % token)
        assert field(ended, "success") == "True" and int(field(ended, "steps")) > 30, ended
        assert "ended by its client" in field(ended, "end_reason")
        assert (bags / field(started, "run_id") / "metadata.yaml").is_file() or probe.spin_until(
            lambda: (bags / field(started, "run_id") / "metadata.yaml").is_file(), 10), "the recorder recorded nothing"
    finally:
        probe.close()
        cli.close()


SCRIPT = '''
import numpy as np
import rps.robotarium as robotarium

r = robotarium.Robotarium(number_of_robots=2, show_figure=False, sim_in_real_time=False,
                          initial_conditions=np.array([[-0.4, 0.4], [0.0, 0.0], [0.0, np.pi]]))
for _ in range(20):
    r.get_poses()
    r.set_velocities(np.arange(2), np.array([[0.1, 0.1], [0.0, 0.0]]))
    r.step()
r.call_at_scripts_end()
'''


def test_ros2_robotarium_lists_the_verbs_and_refuses_a_bad_one(ros2, tmp_path):
    """`ros2 robotarium` is the robotarium command (robotarium_cli.command): its help lists every verb,
    a verb's help is the command's own, a bad argument is refused with exit code 2."""
    from robotarium_cli.verb import VERBS
    cli = Cli(ros2, unique_domain_id())
    listed, run_help, status = cli.gather([("robotarium", "--help"), ("robotarium", "run", "--help"),
                                           ("robotarium", "status", "--json", "--timeout", "0.5")])
    assert all(re.search(r"^\s+%s\s+\S" % verb, listed, re.MULTILINE) for verb in VERBS), listed
    assert "--no-local-testbed" in run_help and "Exit codes" in run_help, run_help
    assert '"local_testbeds"' in status, status
    refused = subprocess.run([ros2, "robotarium", "verify", "x.py", "--robots", "zero"], env=cli.env, cwd=tmp_path,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=60)
    assert refused.returncode == 2 and "--robots" in refused.stdout, refused.stdout


def test_ros2_launch_starts_the_testbed_that_robotarium_run_uses(ros2, tmp_path):
    domain = unique_domain_id()
    cli = Cli(ros2, domain, ROBOTARIUM_NAMESPACE="/launched")
    try:
        bags = tmp_path / "bags"
        launch = cli.start("launch", "robotarium_bringup", "testbed.launch.py", "namespace:=launched",
                           "bags_dir:=%s" % bags, log=tmp_path / "launch.log")
        script = tmp_path / "two_robots.py"
        script.write_text(SCRIPT)
        # ./robotarium run as a ROS user has it: ros2 robotarium run (our own flags after the script too)
        run = subprocess.run([ros2, "robotarium", "run", "--no-local-testbed", str(script), "--no-video"],
                             env=cli.env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                             timeout=180)
        assert run.returncode == 0, run.stdout + (tmp_path / "launch.log").read_text()
        assert "run.mp4" not in run.stdout, run.stdout   # --no-video, given after the script, was taken
        assert "using the testbed that answers in /launched" in run.stdout
        runs = list(bags.glob("two_robots_*"))
        assert len(runs) == 1 and (runs[0] / "report.txt").is_file(), run.stdout   # recorded by the launched recorder
        # One testbed per namespace: a second launch there refuses, naming the first, and ends with an error.
        second = cli.start("launch", "robotarium_bringup", "testbed.launch.py", "namespace:=launched",
                           log=tmp_path / "second.log")
        assert second.wait(timeout=120) != 0, (tmp_path / "second.log").read_text()
        refused = (tmp_path / "second.log").read_text()
        # Whichever of its nodes looks first refuses (launch then stops the others); it names the first testbed's node.
        first_pids = set(re.findall(r"process started with pid \[(\d+)\]", (tmp_path / "launch.log").read_text()))
        named = re.findall(r"not starting a second testbed: a (?:simulator|safety node|recorder) already runs in "
                           r"/launched on ROS_DOMAIN_ID %d: host \S+, pid (\d+)" % domain, refused)
        assert named and set(named) <= first_pids, (first_pids, refused)
        # Its parameters on the nodes' command lines: no file of them left in /tmp (launch_ros never removes one)
        lines = {pid: open("/proc/%s/cmdline" % pid, "rb").read().replace(b"\0", b" ").decode() for pid in first_pids}
        assert len(lines) == 3 and not [line for line in lines.values() if "launch_params_" in line], lines
        assert any("bags_dir:=%s" % json.dumps(str(bags)) in line for line in lines.values()), lines
        assert launch.poll() is None, "the first testbed stopped"
        assert cli.stop(launch) == 0
        log = (tmp_path / "launch.log").read_text()
        assert all("process has finished cleanly" in line for line in log.splitlines() if "[INFO] [" in line
                   and "process has finished" in line), log
    finally:
        cli.close()


def test_ros2_launch_with_a_fleet_moves_the_fleets_robots(ros2, tmp_path):
    """`ros2 launch ... fleet:=FILE` (issue 38): the hardware arena stands in the simulator's place, and a
    script run against it drives the simulated fleet's robots (a process each) and is recorded."""
    from robotarium_hardware.sim_fleet import SimulatedFleet
    domain = unique_domain_id()
    cli = Cli(ros2, domain)
    fleet = SimulatedFleet(2, "mocap", str(tmp_path / "fleet.yaml"), env=node_env(domain), log_dir=str(tmp_path),
                           answer_timeout=1.0, lost_after=1.0, lost_behind=1.0)
    fleet.start(say=lambda line: None)
    try:
        assert fleet.wait_ready(), fleet.failed()
        bags = tmp_path / "bags"
        launch = cli.start("launch", "robotarium_bringup", "testbed.launch.py", "fleet:=%s" % fleet.fleet_file,
                           "bags_dir:=%s" % bags, log=tmp_path / "launch.log")
        script = tmp_path / "on_robots.py"
        script.write_text(SCRIPT)
        run = subprocess.run([ros2, "robotarium", "run", "--no-local-testbed", "--no-video", "--no-verdict",
                              str(script)], env=cli.env, cwd=tmp_path, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, timeout=180)
        log = (tmp_path / "launch.log").read_text()
        assert run.returncode == 0, run.stdout + log
        assert "the testbed moves real robots" in run.stdout, run.stdout   # the arena, not the simulator
        assert re.search(r"\[arena-\d+\]: process started", log) and "[simulator" not in log, log
        runs = list(bags.glob("on_robots_*"))
        assert len(runs) == 1 and (runs[0] / "report.txt").is_file(), run.stdout
        assert cli.stop(launch) == 0
    finally:
        cli.close()
        fleet.stop()



def test_ros2_topic_echo_once_shows_the_newest_status_and_no_old_stream_sample(ros2, tmp_path):
    """The status is the testbed's state (issue 23): after two runs, `ros2 topic echo --once` prints
    the second run's end, not a status from before it (the topic kept a history of 50, and a late
    joiner got its oldest). The streams are volatile: echo on poses, cmd_safe, safety_report or the
    status stream after the runs prints nothing (it got a run's poses from a history of 1000)."""
    from robotarium_msgs.srv import EndExperiment, StartExperiment
    domain = unique_domain_id()
    cli = Cli(ros2, domain)
    probe = RosProbe(domain)
    try:
        for package, executable in (("robotarium_sim", "simulator"), ("robotarium_safety", "safety")):
            cli.start("run", package, executable, "--ros-args", "--params-file", PARAMS,
                      log=tmp_path / ("%s.log" % executable))
        run_ids = []
        for name in ("first", "second"):
            started = probe.hold_client_presence(probe.call(
                StartExperiment, "/robotarium/start_experiment",
                StartExperiment.Request(name=name, number_of_robots=2, real_time=False, x=[-0.5, 0.5], y=[0.0, 0.0],
                                        theta=[0.0, 0.0]), timeout=60))
            assert started.success, started.message
            ended = probe.call(EndExperiment, "/robotarium/end_experiment", EndExperiment.Request(token=started.token))
            assert ended.success, ended.message
            run_ids.append(started.run_id)
        # as echo matches a latched publisher it has discovered: transient local, reliable
        echoed = cli.run("topic", "echo", "--once", "--qos-durability", "transient_local", "--qos-reliability",
                         "reliable", "/robotarium/status", "robotarium_msgs/msg/TestbedStatus")
        assert "run_id: %s" % run_ids[1] in echoed and "state: 0" in echoed, echoed   # IDLE after the second run
        streams = (("poses", "RobotPoses"), ("cmd_safe", "TwistArray"), ("safety_report", "SafetyReport"),
                   ("_status/stream", "TestbedStatus"))
        # echo's own choice of QoS (it asks for transient local where every publisher offers it); the
        # status stream goes on with the idle testbed's heartbeat: only a sample stamped after the
        # echo started may come
        asked = time.time()
        outputs = cli.gather([("topic", "echo", "--once", "--timeout", "3", "/robotarium/" + topic,
                               "robotarium_msgs/msg/" + type_name) for topic, type_name in streams])
        for (topic, _), out in zip(streams, outputs):
            stamps = [int(sec) + int(nanosec) * 1e-9   # (the header's: a status's `started` is its run's start)
                      for sec, nanosec in re.findall(r"header:\s+stamp:\s+sec: (\d+)\s+nanosec: (\d+)", out)]
            assert all(stamp > asked for stamp in stamps), (topic, asked, out)
            assert topic == "_status/stream" or not stamps, (topic, out)
    finally:
        probe.close()
        cli.close()
