"""The Robotarium Python API (rps.robotarium.Robotarium) over ROS 2 topics: the DDS backend.

The contract (argument checks, constants, call order) is robotarium_abc.RobotariumABC; this class
keeps it over a testbed_link.TestbedLink (the node, its topics and services, the presences, the
line): the constructor starts an experiment, each step() sends the requested commands and waits
for the simulator's next poses, and call_at_scripts_end() ends the experiment and prints the
simulator's debug report. How to run (which testbed, a forced mode, progress lines) comes from
robotarium_client.session. docs/architecture.md (The client): the experiment's ownership (token,
poses key, presences), real time and lockstep, why step() hands the freshest poses in real time.
"""
from __future__ import annotations

import atexit
import sys
from typing import NoReturn

import numpy as np

from robotarium_client import api_level, session, testbed_link
from robotarium_client.errors import (  # noqa: F401 - also robotarium_client.robotarium's, as before
    EXIT_TIME_LIMIT,
    EndedByTestbed,
    EndedByUnsentRequest,
    TestbedBusy,
    TestbedIncomplete,
    TestbedLost,
    TimeLimitReached,
)
from robotarium_client.progress import StepProgress
from robotarium_client.robotarium_abc import RobotariumABC
from robotarium_client.testbed_link import TestbedLink, holder_of_this_process  # noqa: F401 - end.py's too
from robotarium_core import model, outcomes, run_record
from robotarium_core.config import DEFAULT, TestbedConfig
from robotarium_msgs.srv import StartExperiment


class Robotarium(RobotariumABC):
    """The Robotarium of the guide, on the ROS 2 testbed."""

    API = api_level.GUIDE   # the API its runs are written against (run_record.Experiment.api)

    def __init__(self, number_of_robots: int = -1, show_figure: bool = True, sim_in_real_time: bool = True,
                 initial_conditions: np.ndarray = np.array([])) -> None:
        options = session.options
        # The testbed's own configuration replaces this once connected; a run's --config file
        # (e.g. more robots than the packaged 50) is what the arguments are checked against first.
        config = TestbedConfig.load(options.config_file) if options.config_file else DEFAULT
        super().__init__(number_of_robots, show_figure, sim_in_real_time, initial_conditions, config)
        if options.real_time is not None:
            self.sim_in_real_time = bool(options.real_time)
        self._options = options
        self._link = None      # testbed_link.TestbedLink, once connected
        self._last_step = 0    # the step of the poses step() last returned
        self.run_info = None   # run_record.Experiment, once the experiment ended: run id, recording, report, counters
        self._progress = StepProgress(options.progress_interval, self.time_step,
                                      "real time" if self.sim_in_real_time else "lockstep")
        self._connect()
        self._adopt_testbed_config()
        limit = options.time_limit if options.time_limit is not None else self.config.time_limit
        self._time_limit = float(limit) if limit and float(limit) > 0 else None
        self._start_experiment()
        session.robotaria.append(self)
        session.remember_uncaught_exceptions()
        atexit.register(self._end_quietly)
        self._make_figure()

    # -- the backend -----------------------------------------------------------------------------

    def _advance(self, velocities: np.ndarray) -> np.ndarray:
        armed = testbed_link.arm_hang_watch()
        try:
            return self._step_on_the_testbed(velocities)
        finally:
            if armed:
                testbed_link.disarm_hang_watch()

    def _step_on_the_testbed(self, velocities: np.ndarray) -> np.ndarray:
        link = self._link
        if self.sim_in_real_time:
            link.take_newest_poses()   # the newest step published before this command
            known = max(self._last_step, link.step)
            link.send(velocities, 0)   # unnumbered: the simulator's 30 Hz timer applies it at its next tick
            target = known + 1
        else:
            link.send(velocities, self._iterations)
            target = self._iterations
        poses = link.wait_for_step(target)
        self._last_step = link.step
        self._progress(self._iterations)
        if self._time_limit is not None and link.latest.sim_time >= self._time_limit - 1e-9:
            self._stop_at_time_limit()
        return poses

    def _stop_at_time_limit(self) -> NoReturn:
        """End the experiment at its time limit as call_at_scripts_end() would, with the reason as
        the report's first line, and stop the script (TimeLimitReached)."""
        step, sim_time = self._link.latest.step, self._link.latest.sim_time
        note = ("Stopped at the time limit: %g s of testbed time (step %d, %.2f s); the rest of the script "
                "did not run." % (self._time_limit, step, sim_time))
        self._ended = True
        self._record_drawing(self._iterations)
        self._report = note + "\n" + self._end(outcomes.TIME_LIMIT, note)
        self.run_info.time_limit = {"limit": self._time_limit, "step": step, "sim_time": sim_time, "note": note}
        print(self._report, end="")
        self._after_report()
        raise TimeLimitReached(note)

    def _end(self, outcome: int = outcomes.COMPLETED, detail: str = "") -> str:
        link = self._link
        response = link.end(outcome, detail)
        dropped = {name: {reason: int(getattr(counts, reason)) for reason in model.DROP_REASONS}
                   for name, counts in (("cmd_requested", response.dropped_cmd_requested),
                                        ("cmd_safe", response.dropped_cmd_safe))}
        report = response.report
        if link.recorder_lost_at is not None:   # no verdict on a run whose recording is incomplete
            report = report.replace(model.ACCEPTANCE_LIKELY, model.RECORDING_INCOMPLETE)
        self.run_info = run_record.Experiment(
            run_id=response.run_id, report=report, outcome=outcomes.NAMES[outcome], detail=detail, ended=True,
            recording=response.recording or link.announced_recording() or link.stopped_recording,
            steps=response.steps, collisions=response.collisions, boundary_violations=response.boundary_violations,
            actuator_limit_iterations=response.actuator_limit_iterations, command_timeouts=response.command_timeouts,
            real_time=self.sim_in_real_time, number_of_robots=self.number_of_robots, end_reason=response.end_reason,
            dropped=dropped, recording_stopped_at_step=link.recorder_lost_at,
            recording_stopped_because=link.recording_stopped_because, stale_pose_stops=response.stale_pose_stops,
            hardware=response.hardware, hardware_seed=response.hardware_seed, audit=response.audit,
            first_collision_step=response.first_collision_step or None,
            first_boundary_step=response.first_boundary_step or None,
            safety_interventions=response.safety_interventions, ideal_interventions=response.ideal_interventions,
            safety_restarts=link.safety_restarts_said(), api=self.API)
        self._errors = {k: v for k, v in (("boundary", response.boundary_violations), ("collision", response.collisions),
                                          ("actuator", response.actuator_limit_iterations)) if v}
        return report

    def _finish(self, outcome: int, detail: str = "") -> str | None:
        """As RobotariumABC._finish; but an experiment that the testbed ended itself (an operator, a
        stopped testbed) or whose simulator or safety node is gone has nothing left to end here: the
        script was stopped with that cause, which was printed, and a second line ("could not end the
        experiment") would only repeat it as if something else had failed. ./robotarium run makes the
        results from the recording."""
        if self._link.failure is not None:
            self._ended = True
            return None
        return super()._finish(outcome, detail)

    def partial_run_info(self) -> run_record.Experiment:
        """What is known of a run whose end the testbed never confirmed (a lost testbed)."""
        link = self._link
        info = run_record.Experiment(run_id=link.run_id or "", recording=link.announced_recording(), steps=link.step,
                                     real_time=self.sim_in_real_time, number_of_robots=self.number_of_robots,
                                     safety_restarts=link.safety_restarts_said(), api=self.API)
        if link.unsent_end_at is not None:
            info.ended, info.ended_by_unsent_request_at_step = True, link.unsent_end_at
        return info

    def _after_report(self) -> None:
        info, link = self.run_info, self._link
        for name, counts in info.dropped.items():
            if any(counts.values()):
                print("[robotarium] the testbed dropped command arrays on %s: %s" % (name, model.describe_drops(counts)),
                      file=sys.stderr)
        if info.stale_pose_stops:
            print("The safety node stopped the robots %d time(s) because the testbed's newest poses were older than "
                  "its pose_timeout (an overloaded testbed machine?)." % info.stale_pose_stops)
        if link.recorder_lost_at is not None:
            print("Run %s: recording stopped at step %d (%s)%s" % (
                info.run_id, link.recorder_lost_at, link.recording_stopped_because,
                "; what it recorded until then is in %s" % info.recording if info.recording else ""))
        elif info.recording:
            print("Run %s recorded in %s" % (info.run_id, info.recording))
        else:
            print("Run %s ended (no recorder was running, so it was not recorded)." % info.run_id)
        link.shutdown()

    # -- the experiment on the testbed -----------------------------------------------------------

    def _connect(self) -> None:
        """The link to the testbed in the session's namespace (one started here where none answers and
        the session allows it)."""
        self._link = TestbedLink(self._options.namespace, self.config)
        self._link.connect(self._options.connect_wait, self._options.local_testbed)
        self._link.on_recording_announced = self._on_recording_announced

    def _on_recording_announced(self) -> None:
        if not self._ended:
            session.note_started(self.partial_run_info())

    def _adopt_testbed_config(self) -> None:
        """Take the testbed's configuration (its latched `config` topic) for the constants and the
        checks of the initial conditions: a testbed run with another arena or time step is
        described by its own numbers. A testbed that publishes none uses the packaged default."""
        text = self._link.testbed_configuration()
        if text is None:
            return
        config = TestbedConfig.from_yaml(text)
        if config != self.config:
            self._use_config(config)
            self._link.config = config   # its node_lease judges lost nodes
            model.validate_number_of_robots(self.number_of_robots, config.max_robots)
            model.validate_initial_conditions(self.initial_conditions, self.number_of_robots,
                                              config.robot_diameter, config.arena)

    def _start_experiment(self) -> None:
        request = StartExperiment.Request(name=self._options.experiment_name, number_of_robots=self.number_of_robots,
                                          real_time=self.sim_in_real_time, hardware=bool(self._options.hardware),
                                          seed=int(self._options.seed), audit=bool(self._options.audit))
        request.x, request.y, request.theta = (row.tolist() for row in self.initial_conditions)
        self._complete_start_request(request)
        request.wait, request.holder = bool(self._options.wait), holder_of_this_process()
        response = self._link.start(request)
        if response.real_time and not self.sim_in_real_time:
            # An arena of real robots (robotarium_hardware) runs every experiment in real time, as the
            # Robotarium does: sim_in_real_time=False is the simulator's speed-up only.
            print("[robotarium] the testbed moves real robots: the experiment runs in real time (30 Hz), not in "
                  "lockstep", file=sys.stderr)
            self.sim_in_real_time = True
            self._progress = StepProgress(self._options.progress_interval, self.time_step, "real time")
        session.note_started(self.partial_run_info())
        self._last_step = 0
        self.poses = np.array([response.x, response.y, response.theta])
        try:
            self._link.get_ready()
        except TestbedIncomplete:
            self._end_quietly()
            raise

    def _complete_start_request(self, request: StartExperiment.Request) -> None:
        """What a subclass adds to the StartExperiment request (robotarium2: the 2.x API's fields)."""

    def _publish_drawing(self, message: dict[str, object]) -> None:
        if self._link is not None and self._link.node is not None:
            self._link.publish_drawing(message)

    def _end_quietly(self) -> None:
        """At exit without call_at_scripts_end (a script run with plain python that raised or just
        ended; ./robotarium run ends it before, saying how): free the testbed for the next run,
        saying how the run ended."""
        if self._link is None:
            return
        if not self._ended and self._link.node is not None:
            self._ended = True
            self._link.end_quietly(*session.outcome_of_uncaught(self._iterations))
        self._link.shutdown()
