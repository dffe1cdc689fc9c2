"""The Robotarium API's contract, apart from any backend (as rps's robotarium_abc.py is).

`RobotariumABC` holds what every Robotarium must do the same way: the constructor's argument
checks and defaults, the constants scripts read (`r.time_step`, `r.boundaries`, ...), the initial
conditions, the figure, and the call-order rules of get_poses() / set_velocities() / step(). A
backend subclass supplies the testbed: `_start`, `_advance` and `_end` (robotarium.Robotarium
talks to the ROS 2 testbed over DDS).
"""
from __future__ import annotations

import abc
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from robotarium_client.drawing import DrawingWatcher
from robotarium_client.figure import live_figure
from robotarium_core import model, outcomes
from robotarium_core.config import DEFAULT
from robotarium_core.model import RobotariumError

if TYPE_CHECKING:
    from robotarium_core.config import TestbedConfig
    from robotarium_recording.arena_figure import ArenaFigure


class RobotariumABC(abc.ABC):
    """Same constructor, defaults, attributes and call-order rules as rps.robotarium.Robotarium."""

    _extra_velocity_rows_ignored = True   # rps 0.0.0 drives a (3, N) velocity array by its first two rows

    def __init__(self, number_of_robots: int = -1, show_figure: bool = True, sim_in_real_time: bool = True,
                 initial_conditions: np.ndarray = np.array([]), config: TestbedConfig = DEFAULT) -> None:
        # Argument checks of rps (RobotariumABC), with messages that say what to do.
        model.validate_number_of_robots(number_of_robots, config.max_robots)
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
        if initial_conditions.size > 0 and initial_conditions.shape != (3, number_of_robots):
            raise RobotariumError(
                "Initial conditions provided when creating the Robotarium object must of size 3xN, where N is the "
                "number of robots used. Expected a 3 x %d array but received a %s array."
                % (number_of_robots, " x ".join(map(str, initial_conditions.shape))))

        self.number_of_robots = int(number_of_robots)
        self.show_figure = show_figure
        self.sim_in_real_time = sim_in_real_time

        self._use_config(config)
        self.file_path = None
        self.current_file_size = 0

        if initial_conditions.size == 0:
            initial_conditions = self._default_initial_conditions()
        self.initial_conditions = model.validate_initial_conditions(
            initial_conditions, self.number_of_robots, config.robot_diameter, config.arena)
        self.velocities = np.zeros((2, self.number_of_robots))
        self.poses = self.initial_conditions.copy()

        self._called_step_already = True
        self._checked_poses_already = False
        self._iterations = 0
        self._ended = False
        self._warned_extra_rows = False
        self._report = None   # the debug report, once the testbed ended the experiment
        self._errors = {}   # as rps: {"boundary": n, "collision": n, "actuator": n}, filled at the end
        self.figure, self.axes = [], []
        self._arena_figure = self._drawing = None

    def _use_config(self, config: TestbedConfig) -> None:
        """The constants of rps, from the testbed configuration (a backend passes the testbed's own)."""
        self.config = config
        self.boundaries = list(config.boundaries)
        self.time_step = config.time_step
        self.robot_diameter = config.robot_diameter
        self.robot_radius = config.robot_radius
        self.wheel_radius = config.wheel_radius
        self.base_length = config.base_length
        self.max_linear_velocity = config.max_linear_velocity
        self.max_angular_velocity = config.max_angular_velocity
        self.max_wheel_velocity = config.max_wheel_velocity

    def _default_initial_conditions(self) -> np.ndarray:
        """Random initial conditions when the script gives none. rps draws these in the script's
        process from numpy's global generator, so a script that seeds numpy gets the same start as
        on the Robotarium simulator."""
        # rps, not at import: the script's first import of rps sets it up for one API (api_level)
        from rps.utilities.misc import generate_initial_conditions
        return generate_initial_conditions(self.number_of_robots, spacing=0.2, width=2.5, height=1.5)

    def _make_figure(self) -> None:
        """The arena figure (r.figure, r.axes) when show_figure is True; call once the poses are known.
        What the script then draws on r.axes is watched, so that the video of the run shows it."""
        self._arena_figure = self._drawing = None
        if self.show_figure:
            self._arena_figure = self._new_arena_figure()
            self.figure, self.axes = self._arena_figure.figure, self._arena_figure.axes
            self._drawing = DrawingWatcher(self.axes, self._arena_figure.own_artists)

    def _new_arena_figure(self) -> ArenaFigure:
        """The live figure in rps's layout (a 2.x Robotarium lays it out as 2.x does)."""
        return live_figure(self.config.arena, self.robot_radius, self.poses)

    def _record_drawing(self, step: int) -> None:
        """Hand what the script changed on r.axes since the last call to the backend, as drawn for
        the poses of `step`. Never lets a drawing problem stop the experiment."""
        if self._drawing is None:
            return
        try:
            message = self._drawing.changes(step)
        except Exception as error:   # noqa: BLE001 - the experiment matters more than its picture
            print("[robotarium] the video will not show the script's drawing (%s: %s)"
                  % (type(error).__name__, error), file=sys.stderr)
            self._drawing = None
            return
        if message is not None:
            self._publish_drawing(message)

    # -- the rps API ---------------------------------------------------------------------------

    def get_poses(self) -> np.ndarray:
        """Returns the states of the agents: a 3xN numpy array (x, y, theta of each robot).

        As in rps 0.0.0 it is the Robotarium's own array, which every step() updates in place: a
        script that tests `x` after step() sees the new poses (the guide's 3.1.2 loop ends on them).
        Writing into it moves no robot."""
        if self._checked_poses_already:
            raise RobotariumError("Can only call get_poses() once per call of step().")
        self._called_step_already = False
        self._checked_poses_already = True
        return self.poses

    def set_velocities(self, ids: np.ndarray | Sequence[int] | int, velocities: np.ndarray) -> None:
        """Set unicycle commands: velocities is 2 x len(ids) (v in m/s, omega in rad/s).

        The testbed thresholds them to the wheel limits keeping the commanded arc, and the
        safety node filters them through the barrier certificate before they reach the robots.
        """
        ids = np.asarray(ids).reshape(-1)
        if not isinstance(velocities, np.ndarray):
            raise RobotariumError("set_velocities: velocities must be a 2 x N numpy array; received %s."
                                  % type(velocities).__name__)
        velocities = np.asarray(velocities, dtype=float)
        if (self._extra_velocity_rows_ignored and velocities.ndim == 2 and velocities.shape[0] > 2
                and velocities.shape[1] == ids.size):
            # rps 0.0.0 reads only the first two rows (v, omega): such a script runs there, so it runs here.
            if not self._warned_extra_rows:
                self._warned_extra_rows = True
                print("[robotarium] set_velocities: velocities has %d rows; the Robotarium uses the first two "
                      "(v, omega) and ignores the rest" % velocities.shape[0], file=sys.stderr)
            velocities = velocities[:2]
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

    def step(self) -> None:
        """Send the commands and advance one step (0.033 s) of the testbed."""
        if self._called_step_already:
            raise RobotariumError("Make sure to call get_poses before calling step() again.")
        if self._ended:
            raise RobotariumError("The experiment has ended (call_at_scripts_end was called); start a new "
                                  "Robotarium to run another.")
        self._called_step_already = True
        self._checked_poses_already = False
        self._record_drawing(self._iterations)   # drawn by the script for the poses it last got
        self._iterations += 1
        self.poses[...] = self._advance(self.velocities)   # in place: see get_poses
        if self._arena_figure is not None:
            self._arena_figure.update(self.poses)
            if self._arena_figure.interactive:
                self._arena_figure.show()

    def call_at_scripts_end(self) -> None:
        """End the experiment and print the debug report, as rps does (again if called again)."""
        if self._ended:
            print(self._report, end="")
            return
        self._ended = True
        self._record_drawing(self._iterations)
        self._report = self._end()
        print(self._report, end="")
        self._after_report()

    def _finish(self, outcome: int, detail: str = "") -> str | None:
        """End an experiment that did not reach call_at_scripts_end (the script raised, was
        interrupted or simply ended), saying how (robotarium_core.outcomes); prints nothing.
        Returns the debug report, or None if the experiment had ended already."""
        if self._report is not None:
            return None
        self._ended = True
        self._record_drawing(self._iterations)
        self._report = self._end(outcome, detail)
        return self._report

    # -- what a backend supplies ---------------------------------------------------------------------

    @abc.abstractmethod
    def _advance(self, velocities: np.ndarray) -> np.ndarray:
        """Apply `velocities` (2 x N) for one step and return the poses (3 x N) that follow."""

    @abc.abstractmethod
    def _end(self, outcome: int = outcomes.COMPLETED, detail: str = "") -> str:
        """End the experiment saying how it ended (robotarium_core.outcomes); return the debug report text."""

    def _publish_drawing(self, message: dict[str, object]) -> None:   # noqa: B027 (optional hook: a no-op by default)
        """Keep a DrawingWatcher message (what the script drew) with the run; a backend without a
        recording may ignore it."""

    def _after_report(self) -> None:   # noqa: B027 (optional hook: a no-op by default)
        """What a backend prints after the debug report (e.g. where the run was recorded)."""
