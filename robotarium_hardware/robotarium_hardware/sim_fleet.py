"""A simulated fleet that behaves as separate machines: `./robotarium fleet --robots N [--tracking mocap|camera]
[--fleet FILE]`.

N robot processes (robot_node: each its own ROS node and process, its own cmd_vel, the GTernal's wheel
model and its own command timeout), and a motion-capture stand-in (mocap_node: PoseStamped per robot at
120 Hz, noise, dropouts) or a camera stand-in (camera_node: 30 Hz images of the arena with each robot's
ArUco tag). They share only the world (robotarium_hardware.world: where the bodies really are, the
truth) and talk DDS. The fleet file it serves is written first; then one line per robot
("robot r2 pid 12345"), the stand-in's line, and "fleet ready". It runs until Ctrl-C (or SIGTERM, SIGHUP,
or its starter's death): then every process of it stops.
"""
import argparse
import dataclasses
import os
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

from robotarium_core import lifeline
from robotarium_core.config import DEFAULT
from robotarium_hardware import fleet as fleets
from robotarium_hardware import robot_node
from robotarium_hardware.world import World

READY_WAIT = 60.0   # s for every process to come up
SPACING = 0.4       # m between the robots where they stand at first (a grid in the arena's middle)
FIRST_TAG = 10      # robot k wears ArUco tag FIRST_TAG + k (the corners wear 0-3)
# The motion capture's frame in the arena (the fleet file's calibration): its origin at the arena's corner,
# turned, so that a fleet file without the right calibration puts every robot in the wrong place.
MOCAP_FRAME = fleets.Calibration(x=-1.6, y=-1.0, yaw=0.3)


def start_poses(number, config=DEFAULT):
    """3 x number poses on a grid SPACING apart around the arena's middle, facing +x."""
    x_min, x_max, y_min, y_max = config.arena
    columns = max(1, int((x_max - x_min - 2 * SPACING) / SPACING) + 1)
    rows = int(np.ceil(number / columns))
    k = np.arange(number)
    x = (x_min + x_max) / 2 + (k % columns - (min(number, columns) - 1) / 2) * SPACING
    y = (y_min + y_max) / 2 + (k // columns - (rows - 1) / 2) * SPACING
    return np.vstack([x, y, np.zeros(number)])


def fleet_of(number, tracking):
    """The fleet file of a simulated fleet of `number` robots."""
    robots = tuple(fleets.Robot(name="r%d" % k, cmd_type="TwistStamped" if k % 2 else "Twist",
                                tag=FIRST_TAG + k, battery_topic="/r%d/battery_state" % k, answer_topic="/r%d/odom" % k)
                   for k in range(number))
    latency = robot_node.COMMAND_LATENCY + robot_node.COMMAND_JITTER
    if tracking == "camera":
        # 30 Hz frames: a robot missing from one frame is forgiven, from two in a row not (tracking.Roster counts frames)
        return fleets.Fleet(robots=robots, name="simulated", tracking="camera", lost_after=0.15, lost_behind=0.06,
                            answer_timeout=0.06, command_latency=latency, tracking_latency=0.05)
    return fleets.Fleet(robots=robots, name="simulated", tracking="mocap", lost_after=0.06, answer_timeout=0.06,
                        command_latency=latency, tracking_latency=0.01, calibration=MOCAP_FRAME)


class SimulatedFleet:
    """The processes of a simulated fleet (robots, then the stand-in), tied to this process by its lifeline.
    env: their environment (a test's domain); log_dir: one log per process (default: beside the fleet file,
    fleet-logs/ for fleet.yaml: where its user finds them, and no folder left behind in /tmp)."""

    def __init__(self, number, tracking="mocap", fleet_file=None, env=None, log_dir=None, **fleet_fields):
        # fleet_fields: fields of the fleet file it writes other than fleet_of's (a test's thresholds)
        self.fleet = dataclasses.replace(fleet_of(number, tracking), **fleet_fields)
        self.fleet_file = os.path.abspath(fleet_file or "fleet.yaml")
        self.env = dict(env or os.environ)
        self.log_dir = os.path.abspath(log_dir or os.path.splitext(self.fleet_file)[0] + "-logs")
        os.makedirs(self.log_dir, exist_ok=True)
        self.world_file = os.path.join("/dev/shm" if os.path.isdir("/dev/shm") else tempfile.gettempdir(),
                                       "robotarium-world-%d-%d" % (os.getpid(), int(time.time() * 1000) % 10**9))
        self.processes = {}   # name -> Popen
        self.commands = {}    # name -> (module, ROS arguments)
        self.world = None

    def _start(self, name, module, ros_args):
        self.commands[name] = (module, ros_args)
        env, pass_fds = lifeline.for_child(self.env)
        log = open(os.path.join(self.log_dir, name + ".log"), "wb")
        self.processes[name] = subprocess.Popen(
            [sys.executable, "-m", module, "--ros-args", *ros_args], env=env, pass_fds=pass_fds,
            stdout=log, stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=_as_a_machine_of_its_own)
        log.close()
        return self.processes[name]

    def start(self, say=print):
        with open(self.fleet_file, "w") as f:
            f.write("# A simulated fleet (./robotarium fleet): its robots, their topics, the tracking and calibration.\n")
            f.write(self.fleet.to_yaml())
        self.world = World(self.world_file, len(self.fleet.robots), create=True)
        poses = start_poses(len(self.fleet.robots))
        for k, robot in enumerate(self.fleet.robots):
            process = self._start_robot(k, poses[:, k])
            say("robot %s pid %d" % (robot.name, process.pid))
        names = "[%s]" % ",".join(self.fleet.names)
        if self.fleet.tracking == "mocap":
            c = self.fleet.calibration
            process = self._start("mocap", "robotarium_hardware.mocap_node", [
                "-p", "world:=%s" % self.world_file, "-p", "robots:=%s" % names,
                "-p", "calibration:=[%r,%r,%r]" % (c.x, c.y, c.yaw)])
        else:
            process = self._start("camera", "robotarium_hardware.camera_node", [
                "-p", "world:=%s" % self.world_file, "-p", "robots:=%s" % names,
                "-p", "tags:=[%s]" % ",".join(str(r.tag) for r in self.fleet.robots)])
        say("%s pid %d" % (self.fleet.tracking, process.pid))
        return self

    def wait_ready(self, timeout=READY_WAIT):
        """True once every robot stands in the world and the stand-in says it is ready; False (and
        which exited) when not within `timeout`."""
        deadline = time.monotonic() + timeout
        stand_in = os.path.join(self.log_dir, self.fleet.tracking + ".log")
        while time.monotonic() < deadline:
            if self.failed():
                return False
            if self.world.placed().all() and _says(stand_in, "ready"):
                return True
            time.sleep(0.05)
        return False

    def failed(self):
        return {name: p.returncode for name, p in self.processes.items() if p.poll() is not None}

    def pid(self, name):
        return self.processes[name].pid

    def kill(self, name, sig=signal.SIGKILL):
        os.killpg(self.processes[name].pid, sig)

    def _start_robot(self, k, pose):
        """Robot k's process, standing at `pose` (x, y, theta)."""
        robot = self.fleet.robots[k]
        x, y, theta = (float(v) for v in pose)
        return self._start(robot.name, "robotarium_hardware.robot_node", [
            "-r", "__node:=%s" % robot.name, "-p", "name:=%s" % robot.name, "-p", "index:=%d" % k,
            "-p", "world:=%s" % self.world_file, "-p", "cmd_type:=%s" % robot.cmd_type,
            "-p", "x:=%r" % x, "-p", "y:=%r" % y, "-p", "theta:=%r" % theta, "-p", "seed:=%d" % (k + 1)])

    def restart(self, name, timeout=READY_WAIT):
        """Start robot `name` again where its body stands, or the stand-in (after a kill); returns its process
        once it says it is ready, as start's wait_ready waits (a run begun before found it missing: the
        drive-on failed, "lost tracking" or "stopped answering", on a loaded machine)."""
        self.processes[name].wait()
        if name not in self.fleet.names:
            process = self._start(name, *self.commands[name])
        else:
            k = self.fleet.names.index(name)
            process = self._start_robot(k, self.world.poses_at()[:, k])
        log = os.path.join(self.log_dir, name + ".log")
        deadline = time.monotonic() + timeout
        while not _says(log, "ready"):
            if process.poll() is not None or time.monotonic() > deadline:
                with open(log, errors="replace") as f:
                    raise RuntimeError("%s did not say it is ready again (%s):\n%s" % (
                        name, "exit code %d" % process.returncode if process.poll() is not None
                        else "%g s" % timeout, f.read()[-2000:]))
            time.sleep(0.05)
        return process

    def stop(self, grace=3.0):
        for process in self.processes.values():
            if process.poll() is None:
                try:
                    os.killpg(process.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
        deadline = time.monotonic() + grace
        for process in self.processes.values():
            try:
                process.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
        self.processes = {}
        try:
            os.unlink(self.world_file)
        except OSError:
            pass


PRIORITY = -10   # nice value of the fleet's processes (where this process may raise priority: root)


def _as_a_machine_of_its_own():
    """A robot (or stand-in) runs on a computer of its own: here it shares the machine with the testbed, the
    script and whatever else runs, so it gets a higher scheduling priority, as if the CPU were its own. Its
    work is small (a robot: about 2 % of a core), so the others lose little; without it a robot starved for
    60 ms on a loaded 2-core machine fell silent long enough to count as gone. Where the priority cannot be
    raised (not root) it runs as it is."""
    try:
        os.nice(PRIORITY)
    except OSError:
        pass


def _says(path, text):
    try:
        with open(path, errors="replace") as f:
            return text in f.read()
    except FileNotFoundError:
        return False


def add_arguments(parser):
    parser.add_argument("--robots", type=int, required=True, metavar="N", help="how many robots (1 to 50)")
    parser.add_argument("--tracking", choices=fleets.TRACKING, default="mocap",
                        help="mocap: a motion-capture stand-in (PoseStamped per robot at 120 Hz, noise, dropouts); "
                             "camera: a camera stand-in (30 Hz images with each robot's ArUco tag; ./robotarium up "
                             "--fleet starts the tag tracker)")
    parser.add_argument("--fleet", metavar="FILE", default="fleet.yaml",
                        help="where to write the fleet file it serves (default: fleet.yaml here); give it to "
                             "./robotarium up --fleet FILE")
    parser.add_argument("--logs", metavar="DIR", default=None,
                        help="where each robot and the stand-in write their log (default: beside the fleet file, "
                             "fleet-logs/ for fleet.yaml)")


def run(args):
    if not 1 <= args.robots <= DEFAULT.max_robots:
        print("[robotarium] error: --robots must be 1 to %d; received %d" % (DEFAULT.max_robots, args.robots),
              file=sys.stderr)
        return 2
    stop = []
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        signal.signal(getattr(signal, name), lambda signum, frame: stop.append(signum))
    lifeline.watch(lambda: stop.append("lifeline"))
    fleet = SimulatedFleet(args.robots, args.tracking, args.fleet, log_dir=args.logs)
    print("fleet file %s (give it to ./robotarium up --fleet %s)" % (fleet.fleet_file, args.fleet), flush=True)
    print("logs in %s" % fleet.log_dir, flush=True)
    fleet.start(say=lambda line: print(line, flush=True))
    try:
        if not fleet.wait_ready():
            print("[robotarium] error: the fleet did not come up (exited: %s); logs in %s"
                  % (fleet.failed() or "none, too slow", fleet.log_dir), file=sys.stderr)
            return 1
        print("world %s (where the bodies really are)" % fleet.world_file, flush=True)
        print("fleet ready", flush=True)
        said = set()
        while not stop:
            for name, code in fleet.failed().items():
                if name not in said:   # a robot or the stand-in that exited (killed?) stays down: said once
                    said.add(name)
                    print("[robotarium] %s exited (code %s); its log: %s" % (
                        name, code, os.path.join(fleet.log_dir, name + ".log")), file=sys.stderr, flush=True)
            time.sleep(0.2)
    finally:
        fleet.stop()
    print("fleet stopped", flush=True)
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(prog="./robotarium fleet", description=__doc__.split("\n\n")[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
