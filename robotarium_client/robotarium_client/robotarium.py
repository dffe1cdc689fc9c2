"""The Robotarium Python API (rps.robotarium.Robotarium) over ROS 2 topics.

A script written for the Robotarium simulator runs unchanged: the constructor starts an
experiment on the testbed (the start_experiment service), set_velocities() + step() publish the
requested commands to the safety node and wait for the simulator's next poses, and
call_at_scripts_end() ends the experiment and prints the simulator's debug report.

Modes: sim_in_real_time=True paces the loop at the testbed's 30 Hz (the simulator's timer;
a robot stops when its command is older than 0.5 s, as on the real testbed); False runs in
lockstep, one simulator step per step() call, as fast as the nodes allow, deterministically.
Environment overrides (set by ./robotarium run): ROBOTARIUM_REAL_TIME=0/1 forces a mode,
ROBOTARIUM_NAMESPACE picks the testbed, ROBOTARIUM_EMBEDDED=0 forbids starting a local testbed,
ROBOTARIUM_RUN_INFO names a JSON file where the run id, report and recording are written,
ROBOTARIUM_PROGRESS=S prints a progress line to stderr every S seconds (./robotarium run: 10).
"""
import atexit
import json
import os
import re
import sys
import time

import numpy as np

from robotarium_sim import model
from robotarium_sim.model import RobotariumError

CONNECT_WAIT = 3.0    # s to wait for an existing testbed to answer before starting one here
STARTUP_WAIT = 60.0   # s for a testbed started here to come up
STEP_TIMEOUT = 10.0   # s without poses after a step() before we give up with an explanation


def _progress_interval():
    value = os.environ.get("ROBOTARIUM_PROGRESS", "")
    try:
        seconds = float(value) if value else 0.0
    except ValueError:
        raise RobotariumError("ROBOTARIUM_PROGRESS must be a number of seconds (0: no progress lines); "
                              "received %r." % value) from None
    return seconds if seconds > 0 and np.isfinite(seconds) else 0.0


def _env_flag(name):
    value = os.environ.get(name)
    return None if value in (None, "") else value.lower() not in ("0", "false", "no", "off")


class Robotarium:
    """Same constructor, defaults, attributes and call-order rules as rps.robotarium.Robotarium."""

    def __init__(self, number_of_robots=-1, show_figure=True, sim_in_real_time=True, initial_conditions=np.array([])):
        # Argument checks of rps (RobotariumABC), with messages that say what to do.
        if isinstance(number_of_robots, bool) or not isinstance(number_of_robots, (int, np.integer)):
            raise RobotariumError(
                "The number of robots used argument (number_of_robots) provided to create the Robotarium object "
                "must be an integer type. Received type %s." % type(number_of_robots).__name__)
        if not isinstance(initial_conditions, np.ndarray):
            raise RobotariumError(
                "The initial conditions array argument (initial_conditions) provided to create the Robotarium "
                "object must be a numpy ndarray. Received type %s." % type(initial_conditions).__name__)
        if not isinstance(show_figure, bool):
            raise RobotariumError(
                "The display figure window argument (show_figure) provided to create the Robotarium object must "
                "be boolean type. Received type %s." % type(show_figure).__name__)
        if not isinstance(sim_in_real_time, bool):
            raise RobotariumError(
                "The simulation running at 0.033s per loop (sim_in_real_time) provided to create the Robotarium "
                "object must be boolean type. Received type %s." % type(sim_in_real_time).__name__)
        if not model.MIN_ROBOTS <= number_of_robots <= model.MAX_ROBOTS:
            raise RobotariumError(
                "Requested %r robots to be used when creating the Robotarium object. The deployed number of robots "
                "must be between %d and %d: pass number_of_robots=N." % (number_of_robots, model.MIN_ROBOTS,
                                                                        model.MAX_ROBOTS))
        if initial_conditions.size > 0 and initial_conditions.shape != (3, number_of_robots):
            raise RobotariumError(
                "Initial conditions provided when creating the Robotarium object must of size 3xN, where N is the "
                "number of robots used. Expected a 3 x %d array but received a %s array."
                % (number_of_robots, " x ".join(map(str, initial_conditions.shape))))

        self.number_of_robots = int(number_of_robots)
        self.show_figure = show_figure
        forced = _env_flag("ROBOTARIUM_REAL_TIME")
        self.sim_in_real_time = sim_in_real_time if forced is None else forced

        # The constants of rps, from the model (one source for every part of the stack).
        self.boundaries = list(model.BOUNDARIES)
        self.time_step = model.TIME_STEP
        self.robot_diameter = model.ROBOT_DIAMETER
        self.robot_radius = model.ROBOT_RADIUS
        self.wheel_radius = model.WHEEL_RADIUS
        self.base_length = model.BASE_LENGTH
        self.max_linear_velocity = model.MAX_LINEAR_VELOCITY
        self.max_angular_velocity = model.MAX_ANGULAR_VELOCITY
        self.max_wheel_velocity = model.MAX_WHEEL_VELOCITY
        self.file_path = None
        self.current_file_size = 0

        if initial_conditions.size == 0:
            # rps draws these in the script's process from numpy's global generator, so a script
            # that seeds numpy gets the same start as on the Robotarium simulator.
            from rps.utilities.misc import generate_initial_conditions
            initial_conditions = generate_initial_conditions(self.number_of_robots, spacing=0.2, width=2.5,
                                                             height=1.5)
        self.initial_conditions = model.validate_initial_conditions(initial_conditions, self.number_of_robots)
        self.velocities = np.zeros((2, self.number_of_robots))
        self.poses = self.initial_conditions.copy()

        self._called_step_already = True
        self._checked_poses_already = False
        self._iterations = 0
        self._progress_every = _progress_interval()
        self._started = self._next_progress = None   # set by the first step()
        self._errors = {}
        self._ended = False
        self._embedded = None
        self._report = None
        self._connect()
        self._start_experiment()
        atexit.register(self._end_quietly)

        self.figure, self.axes = [], []
        if self.show_figure:
            from robotarium_client.figure import ArenaFigure
            self._arena_figure = ArenaFigure(self.boundaries, self.robot_radius, self.poses)
            self.figure, self.axes = self._arena_figure.figure, self._arena_figure.axes

    # -- the rps API ---------------------------------------------------------------------------

    def get_poses(self):
        """Returns the states of the agents: a 3xN numpy array (x, y, theta of each robot)."""
        if self._checked_poses_already:
            raise RobotariumError("Can only call get_poses() once per call of step().")
        self._called_step_already = False
        self._checked_poses_already = True
        return self.poses.copy()

    def set_velocities(self, ids, velocities):
        """Set unicycle commands: velocities is 2 x len(ids) (v in m/s, omega in rad/s).

        The testbed thresholds them to the wheel limits keeping the commanded arc, and the
        safety node filters them through the barrier certificate before they reach the robots.
        """
        ids = np.asarray(ids).reshape(-1)
        if not isinstance(velocities, np.ndarray):
            raise RobotariumError("set_velocities: velocities must be a 2 x N numpy array; received %s."
                                  % type(velocities).__name__)
        velocities = np.asarray(velocities, dtype=float)
        if velocities.ndim != 2 or velocities.shape[0] != 2 or velocities.shape[1] != ids.size:
            raise RobotariumError(
                "set_velocities: velocities must be 2 x %d (one column per id in ids); received shape %s."
                % (ids.size, velocities.shape))
        if ids.size and (not np.issubdtype(ids.dtype, np.integer) and not np.all(ids == np.round(ids))):
            raise RobotariumError("set_velocities: ids must be integers 0..%d; received %s."
                                  % (self.number_of_robots - 1, ids.tolist()))
        ids = ids.astype(int)
        if ids.size and (ids.min() < 0 or ids.max() >= self.number_of_robots or len(np.unique(ids)) != ids.size):
            raise RobotariumError("set_velocities: ids must be distinct robot ids from 0 to %d; received %s."
                                  % (self.number_of_robots - 1, ids.tolist()))
        if not np.all(np.isfinite(velocities)):
            bad = ids[~np.all(np.isfinite(velocities), axis=0)]
            raise RobotariumError("set_velocities: velocities of robots %s are NaN or inf; compute finite "
                                  "commands (the testbed would refuse them)." % bad.tolist())
        self.velocities[:, ids] = velocities

    def step(self):
        """Send the commands and advance one step (0.033 s) of the testbed."""
        if self._called_step_already:
            raise RobotariumError("Make sure to call get_poses before calling step() again.")
        if self._ended:
            raise RobotariumError("The experiment has ended (call_at_scripts_end was called); start a new "
                                  "Robotarium to run another.")
        self._called_step_already = True
        self._checked_poses_already = False
        self._iterations += 1
        if self.sim_in_real_time:
            self._send(0)  # unnumbered: the simulator's 30 Hz timer applies it at its next tick
            target = self._last_step + 1
        else:
            self._send(self._iterations)
            target = self._iterations
        self._wait_for_step(target)
        if self.show_figure:
            self._arena_figure.update(self.poses)
        if self._progress_every:
            self._progress(time.monotonic())

    def _progress(self, now):
        if self._started is None:
            self._started, self._next_progress = now, now + self._progress_every
        elif now >= self._next_progress:
            self._next_progress = now + self._progress_every
            elapsed = now - self._started
            print("[robotarium] step %d: %.1f s of testbed time in %.0f s (%.0f steps/s, %s)" % (
                self._iterations, self._iterations * self.time_step, elapsed, (self._iterations - 1) / elapsed,
                "real time" if self.sim_in_real_time else "lockstep"), file=sys.stderr, flush=True)

    def call_at_scripts_end(self):
        """End the experiment and print the debug report (as rps does), and where it was recorded."""
        if self._ended:
            print(self._report, end="")
            return
        from robotarium_msgs.srv import EndExperiment
        response = self._call(self._end_client, EndExperiment.Request())
        self._ended = True
        if not response.success:
            raise RuntimeError("The testbed could not end the experiment: %s" % response.message)
        self._errors = {k: v for k, v in (("boundary", response.boundary_violations), ("collision", response.collisions),
                                          ("actuator", response.actuator_limit_iterations)) if v}
        self._report = response.report
        print(response.report, end="")
        if response.recording:
            print("Run %s recorded in %s" % (response.run_id, response.recording))
        else:
            print("Run %s ended (no recorder was running, so it was not recorded)." % response.run_id)
        self._write_run_info(response)
        self._shutdown()

    # -- talking to the testbed ------------------------------------------------------------------

    def _connect(self):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from robotarium_client.testbed import LocalTestbed, namespace
        from robotarium_msgs.msg import RobotPoses, TwistArray
        from robotarium_msgs.srv import EndExperiment, StartExperiment
        from robotarium_sim.topics import CMD_REQUESTED, END_EXPERIMENT, POSES, START_EXPERIMENT, TESTBED_QOS

        self._ns = namespace()
        self._context = Context()
        rclpy.init(context=self._context, args=[])
        self._node = Node("robotarium_client_%d" % os.getpid(), namespace=self._ns, context=self._context)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self._latest = None
        self._run_id = None
        self._command_pub = self._node.create_publisher(TwistArray, CMD_REQUESTED, TESTBED_QOS)
        self._node.create_subscription(RobotPoses, POSES, self._on_poses, TESTBED_QOS)
        self._start_client = self._node.create_client(StartExperiment, START_EXPERIMENT)
        self._end_client = self._node.create_client(EndExperiment, END_EXPERIMENT)

        embedded_allowed = _env_flag("ROBOTARIUM_EMBEDDED") is not False
        # Told a testbed is there (./robotarium run found one): give discovery its time.
        if not self._start_client.wait_for_service(timeout_sec=CONNECT_WAIT if embedded_allowed else STARTUP_WAIT):
            if not embedded_allowed:
                self._shutdown()
                raise RuntimeError(
                    "No Robotarium testbed answers in namespace %s on ROS_DOMAIN_ID %s. Start one with "
                    "'./robotarium up' (here or on another machine of the domain)."
                    % (self._ns, os.environ.get("ROS_DOMAIN_ID", "0")))
            print("[robotarium] no testbed answers in %s: starting one on this machine" % self._ns, file=sys.stderr)
            self._embedded = LocalTestbed(ns=self._ns).start()
            if not self._start_client.wait_for_service(timeout_sec=STARTUP_WAIT):
                failed = self._embedded.failed()
                self._shutdown()
                raise RuntimeError("The local testbed did not come up (exited: %s); see log/testbed/*.log." % failed)

        # Twist objects reused every step: only their two numbers change.
        from geometry_msgs.msg import Twist
        self._command = TwistArray()
        self._command.header.frame_id = "arena"
        self._command.ids = list(range(self.number_of_robots))
        self._command.twists = [Twist() for _ in range(self.number_of_robots)]

    def _start_experiment(self):
        from robotarium_msgs.srv import StartExperiment
        name = os.environ.get("ROBOTARIUM_EXPERIMENT_NAME") or os.path.splitext(
            os.path.basename(sys.argv[0] if sys.argv and sys.argv[0] else "experiment"))[0]
        name = re.sub(r"[^A-Za-z0-9_-]", "_", name)[:64] or "experiment"
        request = StartExperiment.Request(name=name, number_of_robots=self.number_of_robots,
                                          real_time=self.sim_in_real_time)
        request.x, request.y, request.theta = (row.tolist() for row in self.initial_conditions)
        response = self._call(self._start_client, request)
        if not response.success:
            self._shutdown()
            raise RobotariumError("The testbed refused to start the experiment: %s" % response.message)
        self._run_id = response.run_id
        self._last_step = 0
        self.poses = np.array([response.x, response.y, response.theta])
        # Without a safety node nothing can move: say so now rather than at the first step's timeout.
        # (Commands sent before it matched us wait in our writer's history: the QoS is transient-local.)
        if not self._spin_until(self._safety_node_listens, STEP_TIMEOUT):
            self._end_quietly()
            raise RuntimeError("No safety node listens on %s/cmd_requested: without it the robots cannot move. "
                               "Is the testbed complete (./robotarium up starts all of it)?" % self._ns)

    def _safety_node_listens(self):
        topic = self._command_pub.topic_name
        return any(info.node_name == "safety" for info in self._node.get_subscriptions_info_by_topic(topic))

    def _on_poses(self, msg):
        if msg.run_id == self._run_id:
            self._latest = msg

    def _send(self, step):
        v, w = self.velocities
        for twist, vi, wi in zip(self._command.twists, v.tolist(), w.tolist()):
            twist.linear.x, twist.angular.z = vi, wi
        self._command.step = step
        self._command.header.stamp = self._node.get_clock().now().to_msg()
        self._command_pub.publish(self._command)

    def _wait_for_step(self, target):
        if not self._spin_until(lambda: self._latest is not None and self._latest.step >= target, STEP_TIMEOUT):
            raise RuntimeError(
                "The testbed sent no poses for step %d within %.0f s. Is the safety node running (robots cannot "
                "move without it)? Node logs are in log/testbed/ when ./robotarium started the testbed."
                % (target, STEP_TIMEOUT))
        msg = self._latest
        self._last_step = msg.step
        self.poses = np.array([msg.x, msg.y, msg.theta])

    def _spin_until(self, predicate, timeout):
        deadline = time.monotonic() + timeout
        while not predicate():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            self._executor.spin_once(timeout_sec=min(remaining, 0.1))
        return True

    def _call(self, client, request, timeout=30.0):
        if not client.wait_for_service(timeout_sec=timeout):
            raise RuntimeError("The testbed's %s service is gone." % client.srv_name)
        future = client.call_async(request)
        if not self._spin_until(future.done, timeout):
            raise RuntimeError("The testbed's %s service did not answer within %.0f s." % (client.srv_name, timeout))
        return future.result()

    def _write_run_info(self, response):
        path = os.environ.get("ROBOTARIUM_RUN_INFO")
        if not path:
            return
        with open(path, "w") as f:
            json.dump({"run_id": response.run_id, "recording": response.recording, "report": response.report,
                       "steps": response.steps, "collisions": response.collisions,
                       "boundary_violations": response.boundary_violations,
                       "actuator_limit_iterations": response.actuator_limit_iterations,
                       "real_time": self.sim_in_real_time, "number_of_robots": self.number_of_robots}, f, indent=2)

    def _end_quietly(self):
        """At exit without call_at_scripts_end (or on an error): free the testbed for the next run."""
        if not self._ended and getattr(self, "_node", None) is not None:
            self._ended = True
            try:
                from robotarium_msgs.srv import EndExperiment
                self._call(self._end_client, EndExperiment.Request(), timeout=5.0)
            except Exception:
                pass
        self._shutdown()

    def _shutdown(self):
        import rclpy
        if getattr(self, "_node", None) is not None:
            self._executor.shutdown()
            self._node.destroy_node()
            self._node = None
            rclpy.try_shutdown(context=self._context)
        if self._embedded is not None:
            self._embedded.stop()
            self._embedded = None
