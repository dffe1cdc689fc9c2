"""The Robotarium arena and the GTernal robot model: plain numpy, no ROS.

Every number comes from the user's guide (cited as "guide §x") or from the Robotarium Python
simulator it documents (robotarium-python-simulator 0.0.0, cited as "rps"). One step of the
testbed, as in rps.Robotarium.step(): count the debug report's errors on the poses *before* the
move and the commands as set; threshold the commands to the wheel limits, keeping the commanded
arc (guide §2.5); integrate the unicycle with one forward-Euler step of TIME_STEP and wrap the
heading. Where rps 0.0.0 differs from the guide (it clips v and omega separately) we follow the
guide; commands within the limits move the robots bit for bit as rps does
(docs/user-guide.md#behaviour-worth-knowing).
"""
import functools
from collections.abc import Mapping, Sequence

import numpy as np

from robotarium_core.config import DEFAULT, TestbedConfig

# The Robotarium's numbers, as module constants for the rps API and the defaults of the functions
# below. They are written once, in the testbed configuration (robotarium_core/testbed.yaml).
ARENA_X_MIN, ARENA_X_MAX, ARENA_Y_MIN, ARENA_Y_MAX = DEFAULT.arena   # 3.2 m x 2 m (guide §2.7.2)
ARENA = DEFAULT.arena
BOUNDARIES = DEFAULT.boundaries            # rps: [x_min, y_min, width, height]
TIME_STEP = DEFAULT.time_step              # 0.033 s (guide §2.7.6, §4.2.4; rps time_step)
ROBOT_DIAMETER = DEFAULT.robot_diameter    # GTernal (rps robotarium_abc.py; guide §2.7.1, §2.7.4)
ROBOT_RADIUS = DEFAULT.robot_radius
WHEEL_RADIUS = DEFAULT.wheel_radius
BASE_LENGTH = DEFAULT.base_length
MAX_LINEAR_VELOCITY = DEFAULT.max_linear_velocity     # |v| <= 0.2 m/s (guide §2.7.1)
MAX_WHEEL_VELOCITY = DEFAULT.max_wheel_velocity       # 12.5 rad/s (guide §2.7.1)
MAX_ANGULAR_VELOCITY = DEFAULT.max_angular_velocity   # about 3.64 rad/s (guide §2.7.1 "about 3.6")
MIN_ROBOTS, MAX_ROBOTS = 1, DEFAULT.max_robots        # 1 to 50 in simulation (guide §2.7.3)
COMMAND_TIMEOUT = DEFAULT.command_timeout             # 0.5 s (guide §2.7.6)


class RobotariumError(ValueError, AssertionError):
    """A bad argument or input, with a message that says what is wrong and what would be right.

    It is a ValueError, and also an AssertionError because rps signals the same mistakes with
    failed asserts: scripts written against rps that catch AssertionError keep working.
    """


def wrap_angle(theta: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to [-pi, pi] the way rps does (arctan2 of sine and cosine)."""
    return np.arctan2(np.sin(theta), np.cos(theta))


def at_pose_mask(poses: np.ndarray, goals: np.ndarray, position_error: float, rotation_error: float,
                 strict: bool = False) -> np.ndarray:
    """Per robot (N booleans): within position_error (m) of its goal position and rotation_error (rad,
    the heading error wrapped) of its goal heading. poses, goals: 3xN. strict: < instead of <= (2.x's
    parking controllers)."""
    distance = np.linalg.norm(poses[:2] - goals[:2], axis=0)
    heading = np.abs(wrap_angle(poses[2] - goals[2]))
    if strict:
        return (distance < position_error) & (heading < rotation_error)
    return (distance <= position_error) & (heading <= rotation_error)


def at_position_mask(points: np.ndarray, goals: np.ndarray, position_error: float) -> np.ndarray:
    """Per robot (N booleans): within position_error (m) of its goal. points: 2xN or more rows (x, y
    first); goals: 2xN."""
    return np.linalg.norm(points[:2] - goals[:2], axis=0) <= position_error


def unicycle_to_wheels(dxu: np.ndarray, wheel_radius: float = WHEEL_RADIUS, base_length: float = BASE_LENGTH) -> np.ndarray:
    """2xN (v, omega) -> 2xN (left, right) wheel speeds in rad/s (rps _uni_to_diff, guide §2.5.1)."""
    v, w = dxu[0], dxu[1]
    return np.vstack(((2 * v - base_length * w) / (2 * wheel_radius),
                      (2 * v + base_length * w) / (2 * wheel_radius)))


def fastest_wheel(v: np.ndarray, w: np.ndarray, wheel_radius: float = WHEEL_RADIUS,
                  base_length: float = BASE_LENGTH) -> np.ndarray:
    """Speed of the faster wheel of each robot: max(|2v - Lw|, |2v + Lw|) / 2r = (2|v| + L|w|) / 2r."""
    return (2 * np.abs(v) + base_length * np.abs(w)) / (2 * wheel_radius)


def exceeds_actuator_limits(dxu: np.ndarray, max_linear: float = MAX_LINEAR_VELOCITY,
                            max_angular: float = MAX_ANGULAR_VELOCITY, max_wheel: float = MAX_WHEEL_VELOCITY,
                            wheel_radius: float = WHEEL_RADIUS, base_length: float = BASE_LENGTH) -> bool:
    """True when some robot's command is over the wheel-speed limit, judged as rps judges it.

    rps first clips v to +-0.2 m/s and omega to +-3.64 rad/s separately (set_velocities) and then
    counts the iteration when a wheel of the clipped command turns faster than 12.5 rad/s
    (_validate). Doing the same keeps our debug report equal to the reference's.
    """
    v = np.minimum(np.abs(dxu[0]), max_linear)   # |clip(v)|: fastest_wheel needs magnitudes only
    w = np.minimum(np.abs(dxu[1]), max_angular)
    return bool(np.any(fastest_wheel(v, w, wheel_radius, base_length) > max_wheel))


def is_actuator_limit_iteration(dxu: np.ndarray, requested_exceeds_limits: bool = False, **limits: float) -> bool:
    """Whether a step with the commands dxu in force counts in the debug report: they exceed the
    limits (exceeds_actuator_limits), or the safety node says the script's own commands behind
    them did (rps judges what the script set, before any filtering)."""
    return bool(requested_exceeds_limits) or exceeds_actuator_limits(dxu, **limits)


def threshold_keeping_arc(dxu: np.ndarray, max_linear: float = MAX_LINEAR_VELOCITY,
                          max_angular: float = MAX_ANGULAR_VELOCITY, max_wheel: float = MAX_WHEEL_VELOCITY,
                          wheel_radius: float = WHEEL_RADIUS, base_length: float = BASE_LENGTH) -> np.ndarray:
    """Scale each robot's (v, omega) by one factor alpha <= 1 so that both wheels stay within
    max_wheel, |v| <= max_linear and |omega| <= max_angular (guide §2.5: v_scaled = alpha v,
    w_scaled = alpha w keeps the arc radius v/omega). Commands already within limits are
    returned unchanged, bit for bit."""
    v, w = np.abs(dxu[0]), np.abs(dxu[1])
    # Most commands are within the limits (every step of a lockstep run passes here up to three
    # times): that is alpha >= 1 for every robot below, checked without its divisions and errstate
    # (for positive a and b, a / b < 1 exactly when b > a; NaN fails the check and goes the long way).
    if (v.max(initial=0.0) <= max_linear and w.max(initial=0.0) <= max_angular
            and fastest_wheel(v, w, wheel_radius, base_length).max(initial=0.0) <= max_wheel):
        return dxu.copy()
    with np.errstate(divide="ignore", over="ignore"):
        wheel = fastest_wheel(v, w, wheel_radius, base_length)
        alpha = np.minimum(np.minimum(max_wheel / wheel, 1.0), np.minimum(max_linear / v, max_angular / w))
    over = alpha < 1
    if not np.any(over):
        return dxu.copy()
    scaled = dxu.copy()
    scaled[:, over] *= alpha[over]
    huge = ~np.isfinite(wheel)
    if np.any(huge):
        # |v| or |omega| near the largest float (1e308): the wheel speed overflowed and alpha came
        # out 0, a stop. Take the direction (v, omega) / max(|v|, |omega|) instead and go as far
        # along it as the limits allow: full speed on the commanded arc, as for any other value.
        unit = dxu[:, huge] / np.maximum(v[huge], w[huge])
        u_v, u_w = np.abs(unit[0]), np.abs(unit[1])
        with np.errstate(divide="ignore", over="ignore"):
            reach = np.minimum(max_wheel / fastest_wheel(u_v, u_w, wheel_radius, base_length),
                               np.minimum(max_linear / u_v, max_angular / u_w))
        scaled[:, huge] = unit * reach
    return scaled


def unicycle_step(poses: np.ndarray, dxu: np.ndarray, time_step: float = TIME_STEP) -> np.ndarray:
    """The poses after one forward-Euler step of the unicycle with commands dxu (2 x N, applied as
    they are), heading wrapped: rps.Robotarium.step()'s integration, in its expression order."""
    v, w = dxu[0], dxu[1]
    moved = np.empty_like(poses)
    moved[0] = poses[0] + time_step * np.cos(poses[2]) * v
    moved[1] = poses[1] + time_step * np.sin(poses[2]) * v
    moved[2] = wrap_angle(poses[2] + time_step * w)
    return moved


def lookahead_poses(poses: np.ndarray, commands: np.ndarray, time_step: float = TIME_STEP, **limits: float) -> np.ndarray:
    """Where the robots would be one step on if `commands` (2 x N, the script's own) were applied:
    thresholded to the actuator limits along their arc, as the simulator would, then integrated."""
    return unicycle_step(poses, threshold_keeping_arc(commands, **limits), time_step)


def violations(poses: np.ndarray, robot_diameter: float = ROBOT_DIAMETER,
               arena: Sequence[float] = ARENA) -> tuple[int, int]:
    """(collisions, boundary violations) the debug report counts on these poses: robot pairs within
    a robot diameter, robots outside the arena."""
    return count_collisions(poses, robot_diameter), int(np.count_nonzero(outside_arena(poses, arena)))


@functools.lru_cache(maxsize=64)
def robot_pairs(number_of_robots: int) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays (i, j) of every pair i < j, cached per N (the step's hot path uses them)."""
    return np.triu_indices(number_of_robots, k=1)


# Above this many robots, count_collisions looks only at pairs from a sweep along x (candidate_pairs)
# instead of all N(N-1)/2: at 400 robots 80k pairs a step, in the simulator and the safety node.
SWEEP_MIN_ROBOTS = 100


def candidate_pairs(x: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays (i, j) of every pair whose x coordinates differ by at most `radius` (padded by
    a relative 1e-9 so rounding never leaves a pair out), from one sort: a superset of the pairs
    within `radius` in the plane, about N * (pairs per strip) of them rather than N^2 / 2."""
    n = len(x)
    order = np.argsort(x, kind="stable")
    xs = x[order]
    reach = radius * (1 + 1e-9) + 1e-12
    counts = np.searchsorted(xs, xs + reach, side="right") - np.arange(1, n + 1)
    np.maximum(counts, 0, out=counts)
    first = np.repeat(np.arange(n), counts)
    offset = np.arange(len(first)) - np.repeat(np.cumsum(counts) - counts, counts)
    return order[first], order[first + 1 + offset]


def count_collisions(poses: np.ndarray, robot_diameter: float = ROBOT_DIAMETER) -> int:
    """Robot pairs whose centres are within one robot diameter (rps _validate counts each pair).
    Beyond SWEEP_MIN_ROBOTS the same test runs on candidate_pairs only: a pair within the diameter
    has |dx| = sqrt(dx^2) <= sqrt(dx^2 + dy^2) <= diameter (IEEE rounding is monotone), so it is
    a candidate, and the count is the same number, bit for bit the same test."""
    x, y = poses[0], poses[1]
    if poses.shape[1] > SWEEP_MIN_ROBOTS:
        i, j = candidate_pairs(x, robot_diameter)
    else:
        i, j = robot_pairs(poses.shape[1])
    dx, dy = x[i] - x[j], y[i] - y[j]
    return int(np.count_nonzero(np.sqrt(dx * dx + dy * dy) <= robot_diameter))  # as np.linalg.norm in rps


def outside_arena(poses: np.ndarray, arena: Sequence[float] = ARENA) -> np.ndarray:
    """Boolean mask of robots whose centre is outside the arena (rps _validate)."""
    x, y = poses[0], poses[1]
    return (x < arena[0]) | (x > arena[1]) | (y < arena[2]) | (y > arena[3])


def validate_number_of_robots(number_of_robots: object, max_robots: int = MAX_ROBOTS) -> None:
    """The one check of a robot count (client, simulator, utilities), with rps's wording."""
    if isinstance(number_of_robots, bool) or not isinstance(number_of_robots, (int, np.integer)):
        raise RobotariumError(
            "The number of robots (number_of_robots) must be an integer between %d and %d; received %r of "
            "type %s." % (MIN_ROBOTS, max_robots, number_of_robots, type(number_of_robots).__name__))
    if not MIN_ROBOTS <= number_of_robots <= max_robots:
        raise RobotariumError(
            "Requested %d robots: number_of_robots must be between %d and %d (the simulator's range; the real "
            "Robotarium deploys up to %d): pass number_of_robots=N." % (
                number_of_robots, MIN_ROBOTS, max_robots, DEFAULT.real_testbed_max_robots))


def validate_initial_conditions(poses: np.ndarray, number_of_robots: int, robot_diameter: float = ROBOT_DIAMETER,
                                arena: Sequence[float] = ARENA) -> np.ndarray:
    """Raise RobotariumError unless `poses` is a finite 3xN array of robots inside the arena, no
    two of them closer than a robot diameter (they would start in collision)."""
    poses = np.asarray(poses, dtype=float)
    if poses.shape != (3, number_of_robots):
        raise RobotariumError(
            "initial_conditions must be a 3 x %d array (x, y, theta of each robot); received shape %s."
            % (number_of_robots, poses.shape))
    if not np.all(np.isfinite(poses)):
        raise RobotariumError("initial_conditions must be finite; received NaN or inf at robots %s."
                              % np.flatnonzero(~np.all(np.isfinite(poses), axis=0)).tolist())
    outside = np.flatnonzero(outside_arena(poses, arena))
    if outside.size:
        raise RobotariumError(
            "initial_conditions put robots %s outside the arena [%g, %g] x [%g, %g]; move them inside."
            % (outside.tolist(), *arena))
    if number_of_robots > 1:
        i, j = robot_pairs(number_of_robots)
        distances = np.hypot(poses[0, i] - poses[0, j], poses[1, i] - poses[1, j])
        close = distances <= robot_diameter
        if np.any(close):
            k = int(np.argmax(close))
            raise RobotariumError(
                "initial_conditions place robots %d and %d %.3f m apart, in collision; keep centres more "
                "than %.2f m apart (0.15 m or more is recommended)." % (i[k], j[k], distances[k], robot_diameter))
    return poses


def random_initial_conditions(number_of_robots: int, rng: np.random.Generator | np.random.RandomState,
                              spacing: float = 0.2, width: float = 2.5, height: float = 1.5) -> np.ndarray:
    """Random poses on a grid of `spacing` in a width x height box centred in the arena.

    The same algorithm and defaults as rps (misc.generate_initial_conditions called by
    RobotariumABC with spacing=0.2, width=2.5, height=1.5), drawn from `rng` (a
    numpy.random.Generator or RandomState, or np.random itself: the global stream, which the
    guide's generate_initial_conditions draws from) so that a seed reproduces them.
    """
    x_range, y_range = int(np.floor(width / spacing)), int(np.floor(height / spacing))
    choices = rng.choice(x_range * y_range, number_of_robots, replace=False) + 1
    x_cell, y_cell = np.divmod(choices, y_range)
    return np.vstack((x_cell * spacing - width / 2, y_cell * spacing - height / 2,
                      rng.random(number_of_robots) * 2 * np.pi - np.pi))


# Why a node drops an incoming command array: the fields of robotarium_msgs/DropCounts, counted
# per input (cmd_requested at the safety node, cmd_safe at the simulator). The first three are
# decided from the serialized bytes (robotarium_core.cdr), the next three by check_commands.
DROP_REASONS = {
    "foreign": "it does not carry the running experiment's token (or key), or no experiment is running",
    "oversized": "more ids or twists than the experiment has robots",
    "malformed": "its bytes are not a TwistArray",
    "nonfinite": "NaN or inf in a velocity",
    "length_mismatch": "ids and twists of different lengths, or an id given twice",
    "unknown_id": "an id that is not a robot of this experiment",
    "stale": "not for the step the testbed is at: a lockstep step already taken or not the next one, a second "
             "array for one step, or (real time) filtered at poses the testbed has left",
}


def describe_drops(counts: dict) -> str:
    """{reason: count} of dropped arrays in words, each reason with what it means ("1 stale (not for the step
    ...)"): a late array of the script's own is not a foreign one."""
    return "; ".join("%d %s (%s)" % (n, reason, DROP_REASONS[reason]) for reason, n in counts.items() if n)


def check_commands(ids: np.ndarray, v: np.ndarray, w: np.ndarray, number_of_robots: int) -> str | None:
    """Why an incoming command array must be dropped, or None if it is fine.

    Returns one of "length_mismatch" (ids, v and omega of different lengths, or an id twice),
    "unknown_id" (an id outside 0..N-1) or "nonfinite" (NaN or inf in v or omega).
    """
    if not (len(ids) == len(v) == len(w)):
        return "length_mismatch"
    # The usual array, every robot in order, has neither a duplicate nor an unknown id: checked
    # without np.unique's sort (both the safety node and the simulator check every lockstep step).
    if not (len(ids) == number_of_robots and np.array_equal(ids, np.arange(number_of_robots))):
        if len(np.unique(ids)) != len(ids):
            return "length_mismatch"
        if len(ids) and (np.min(ids) < 0 or np.max(ids) >= number_of_robots):
            return "unknown_id"
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(w))):
        return "nonfinite"
    return None


class StepGate:
    """The simulator's rule for the safe arrays it applies (issue 22): each cmd_safe array carries
    in its `step` the step it produces, that is the pose step it was filtered at plus one (the
    safety node's robotarium_safety.guard.Guard marks it so), and the barrier certificate's guarantee
    is about one step from exactly those poses. So:
      lockstep:  an array is applied only when it produces the next step (step == steps + 1), and
                 the one applied steps the testbed: at most one array per step, each filtered at
                 the poses it moves from. A re-send, a burst of arrays filtered at one pose, a
                 step ahead or behind, adds no step and no motion.
      real time: an array replaces the commands in force; it is taken only when filtered at the
                 poses of the current tick (step == steps + 1) or of the one before (step ==
                 steps: it crossed a tick on its way), and never one filtered at older poses
                 than the array in force (a reordering). Arrays never add up: whatever comes
                 within a tick, one set of commands is in force during each step. An array of
                 stops is taken whatever its step: it cannot move a robot.
    Why one tick late is covered: the array was filtered at the poses p_{k-1} and then moves the
    robots from p_k, which its own step k-1 -> k (filtered at p_{k-2} or later, the same rule) put
    at most T v_max = 6.6 mm from p_{k-1}; the boundary rows keep each centre boundary_margin
    (55 mm) inside the arena and their bound falls as gap^3, so a second step at the allowed speed
    stays inside; for pairs, a certificate used for two steps closes at most 2 collision_barrier_rate
    (0.4) of the squared gap, and the change of heading in one step (omega_max T = 0.12 rad) adds
    at most 2 v_max T sin(0.12) = 1.6 mm for the pair, inside collision_margin (5 mm). A command
    held over several ticks (a script slower than the tick) is outside the certificate's guarantee,
    as the real robots' firmware holds it too (barrier_certificates, assumption 1); command_timeout
    ends it.

    Pure: the simulator node calls `admit` for every valid array before applying it, and the
    property test (robotarium_safety/test/test_safety_guarantee.py) runs the same object on adversarial streams."""

    def __init__(self, real_time: bool) -> None:
        self.real_time = real_time
        self.in_force = 0   # real time: the step of the array in force (0: none yet)

    def admit(self, step: int, steps: int, stop: bool = False) -> str | None:
        """None when the array marked `step` may be applied now that the testbed has taken
        `steps` steps (then, in lockstep, the caller steps the testbed); else why not, in words
        (its drop reason is "stale")."""
        if not self.real_time:
            if step == steps + 1:
                return None
            return "step %d is not the next one (the testbed is at step %d)" % (step, steps)
        if stop:
            return None
        if step not in (steps, steps + 1):
            return "filtered at the poses of step %d; the testbed is at step %d" % (step - 1, steps)
        if step < self.in_force:
            return "filtered at older poses (step %d) than the commands in force (step %d)" % (step - 1, self.in_force - 1)
        self.in_force = step
        return None


NOT_COMPLETED = "The run did not complete, so there is no acceptance estimate.\n"
ACCEPTANCE_LIKELY = "No errors in your simulation! Acceptance of your experiment is likely!\n"
# ... in its place when the run's recording stopped early (the recorder gone, a full disk)
RECORDING_INCOMPLETE = "No errors in your simulation, but its recording is incomplete, so there is no acceptance estimate.\n"


CHANGED_BY_SAFETY = ("The safety layer changed {0} of {1} command arrays of this run (largest change {2:.3g}, mean {3:.3g} "
                     "m/s or rad/s): the robots did not drive your script's own commands, so this run gives no counts of "
                     "the Robotarium's.\n")


def safety_lines(interventions: int = 0, arrays: int = 0, largest_change: float = 0.0,
                 mean_change: float = 0.0) -> list[str]:
    """What the always-on safety layer did, when it changed the script's commands: how often and how
    much. Empty when it never stepped in."""
    if not interventions:
        return []
    return [CHANGED_BY_SAFETY.format(interventions, max(arrays, interventions), largest_change, mean_change)]


def debug_report(iterations: int, boundary_violations: int, collisions: int, actuator_limit_iterations: int,
                 time_step: float = TIME_STEP, completed: bool = True, number_of_robots: int | None = None,
                 real_testbed_max_robots: int = DEFAULT.real_testbed_max_robots, hardware_seed: int | None = None,
                 safety: Mapping[str, float] | None = None) -> str:
    """The text rps.Robotarium.call_at_scripts_end() prints, character for character, for a completed
    ideal run of at most real_testbed_max_robots robots. A run that did not complete (an error, an
    interruption, no call_at_scripts_end) gets the same counts but never the acceptance estimate:
    NOT_COMPLETED takes its place. Beside the estimated duration it also says when the run used more
    robots than the real Robotarium deploys, and that it ran hardware-like (hardware_seed: the seed
    of robotarium_sim.hardware's model; None for the ideal testbed).

    safety: safety_lines' keyword arguments (what the safety layer did). Where it changed the
    script's commands, the robots drove something else than the Robotarium would have: the report
    then says so instead of giving the duration, the counts and the acceptance estimate, which would
    be this run's, not the script's (./robotarium run adds the Robotarium's verdict, judged on the
    script's own commands)."""
    lines = ["##### DEBUG OUTPUT #####\n"]
    changed = safety_lines(**(safety or {}))
    if not changed:
        lines.append("Your simulation will take approximately {0} real seconds when deployed on the Robotarium. \n\n"
                     .format(int(np.ceil(iterations * time_step))))
    if number_of_robots is not None and number_of_robots > real_testbed_max_robots:
        lines.append("Your simulation uses {0} robots, but the real Robotarium deploys at most {1}: use {1} or fewer "
                     "to run it there. \n\n".format(number_of_robots, real_testbed_max_robots))
    if hardware_seed is not None:
        lines.append("This run simulated the real testbed's hardware (tracking and command latency, pose noise, "
                     "wheel dynamics; seed {0}). \n\n".format(hardware_seed))
    if changed:
        lines += changed
    elif boundary_violations or collisions or actuator_limit_iterations:
        if boundary_violations:
            lines.append("\t Simulation had {0} iteration(s) robots were outside the boundaries.\n\n"
                         .format(boundary_violations))
        if collisions:
            lines.append("\t Simulation had {0} iteration(s) where robots collided.\n\n".format(collisions))
        if actuator_limit_iterations:
            lines.append("\t Simulation had {0} iteration(s) where the actuator limits were exceeded.\n"
                         .format(actuator_limit_iterations))
    elif completed:
        lines.append(ACCEPTANCE_LIKELY)
    if not completed:
        lines.append(("\n" if lines[-1].endswith(".\n") and not lines[-1].endswith("\n\n") else "") + NOT_COMPLETED)
    return "".join(lines)


class Testbed:
    """The arena with N GTernals: poses, current commands, and the debug report's counters.

    Time is not kept here: the simulator node decides when to step (30 Hz timer or lockstep)
    and passes wall-clock times for the command timeout.
    """

    def __init__(self, initial_poses: np.ndarray, config: TestbedConfig = DEFAULT) -> None:
        self.poses = np.array(initial_poses, dtype=float)
        self.number_of_robots = self.poses.shape[1]
        validate_number_of_robots(self.number_of_robots, config.max_robots)
        validate_initial_conditions(self.poses, self.number_of_robots, config.robot_diameter, config.arena)
        self.config = config
        self.time_step = config.time_step
        self.robot_diameter = config.robot_diameter
        self.arena = config.arena
        self.limits = config.limits
        self.velocities = np.zeros((2, self.number_of_robots))   # commands as set, before thresholding
        self.command_times = np.full(self.number_of_robots, -np.inf)
        # The safety node's word that the script's own commands behind these exceed the limits.
        self.requested_exceeds_limits = False
        self.steps = 0
        self.collisions = 0
        self.boundary_violations = 0
        self.actuator_limit_iterations = 0
        self.command_timeouts = 0

    def set_commands(self, ids: np.ndarray | Sequence[int], v: np.ndarray | Sequence[float] | float,
                     w: np.ndarray | Sequence[float] | float, now: float = 0.0, requested_exceeds_limits: bool = False,
                     offset: float = 0.0, refreshed: bool = False) -> None:
        """Set (v, omega) for the robots `ids` (already checked with check_commands).

        requested_exceeds_limits: these commands were filtered from ones that exceed the actuator
        limits (the safety node says so); the iterations they are in force count as rps counts.
        offset: seconds into the current step when they arrived; the ideal testbed applies every
        command from the start of its next step (the hardware-like one sends it at that moment).
        refreshed: the commands in force filtered again (TwistArray.refreshed): their command
        timeout runs on from when the commands they came from arrived.
        """
        ids = np.asarray(ids, dtype=int)
        self.requested_exceeds_limits = bool(requested_exceeds_limits)
        self.velocities[0, ids] = v
        self.velocities[1, ids] = w
        if not refreshed:
            self.command_times[ids] = now

    def expire_commands(self, now: float, timeout: float = COMMAND_TIMEOUT) -> np.ndarray:
        """Stop robots whose command is older than `timeout` (guide §2.7.6); count each expiry once."""
        stale = (now - self.command_times > timeout) & np.any(self.velocities != 0, axis=0)
        if np.any(stale):
            self.velocities[:, stale] = 0.0
            self.requested_exceeds_limits = False  # what is in force is no longer what was asked
            self.command_timeouts += int(np.count_nonzero(stale))
        return stale

    def step(self) -> None:
        """Advance one time step, as rps.Robotarium.step(): count, threshold, integrate."""
        self._count()
        self._move()
        self.steps += 1

    def _count(self) -> None:
        """The debug report's errors, on the poses before the move and the commands in force."""
        self.boundary_violations += int(np.count_nonzero(outside_arena(self.poses, self.arena)))
        self.collisions += count_collisions(self.poses, self.robot_diameter)
        if is_actuator_limit_iteration(self.velocities, self.requested_exceeds_limits, **self.limits):
            self.actuator_limit_iterations += 1

    def _move(self) -> None:
        """Threshold the commands in force and integrate the unicycle over one time step."""
        self.poses[:] = unicycle_step(self.poses, threshold_keeping_arc(self.velocities, **self.limits),
                                      self.time_step)

    @property
    def sim_time(self) -> float:
        return self.steps * self.time_step

    # The seed of the hardware-like model; None: the ideal testbed (the report names the mode).
    seed = None
    # s between the poses a command is filtered at and the robots obeying it, beyond the one step the
    # safety node's certificate covers (ArmSafety.latency): none for the ideal testbed.
    latency = 0.0

    def report(self, completed: bool = True, safety: Mapping[str, float] | None = None) -> str:
        return debug_report(self.steps, self.boundary_violations, self.collisions, self.actuator_limit_iterations,
                            self.time_step, completed, self.number_of_robots, self.config.real_testbed_max_robots,
                            self.seed, safety)


def is_intervention(filtered: bool, max_change: float, tolerance: float) -> bool:
    """Whether the safety layer intervened in one command array: it solved the barrier QP or sent a
    stop (`filtered`), and that changed a command by more than `tolerance` (max_change: the largest
    change; for a stop, the largest finite requested speed). A stop of a request that was at rest
    changed nothing: counting it made reports say "658 interventions, largest change 0" (issue 22),
    so the count and its largest change always agree."""
    return bool(filtered) and float(max_change) > tolerance


class RunTally:
    """What a run's report needs beside the testbed's counters: the step at which each error
    counter first became non-zero (a verification's verdict names it), and what the safety layer
    did: its interventions (how often, how much)."""

    def __init__(self) -> None:
        self.first_collision_step = 0    # the step (1: the first step() call) whose count made collisions > 0
        self.first_boundary_step = 0
        self.interventions = 0
        self.largest_change = 0.0
        self.change_sum = 0.0

    def after_step(self, testbed: Testbed) -> None:
        """Call after every testbed.step()."""
        if testbed.collisions and not self.first_collision_step:
            self.first_collision_step = testbed.steps
        if testbed.boundary_violations and not self.first_boundary_step:
            self.first_boundary_step = testbed.steps

    def add_safety_report(self, intervention: bool, max_change: float) -> None:
        if intervention:
            self.interventions += 1
            self.largest_change = max(self.largest_change, float(max_change))
            self.change_sum += float(max_change)

    def safety(self, arrays: int) -> dict[str, float]:
        """safety_lines' keyword arguments, `arrays` command arrays in all."""
        return dict(interventions=self.interventions, arrays=arrays, largest_change=self.largest_change,
                    mean_change=self.change_sum / self.interventions if self.interventions else 0.0)
