"""Position and pose controllers (guide section 4.4).

Each create_* function checks its gains once and returns a controller that maps the robots'
current states and goals (one column per robot) to velocity commands for all robots at once.
Like rps, `from rps.utilities.controllers import *` also brings the transformations.

The laws themselves (proportional single-integrator control, the CLF pose law, the hybrid pose
controller's step) are robotarium_core.control's, shared with 2.x's module; this one keeps the
guide's names, defaults, checks and messages. Its fixes to rps 0.0.0 are marked "Fix:" in the code
and listed in docs/user-guide.md#the-toolboxs-fixes-to-rps-000.
"""
import numpy as np

from robotarium_core import control
from rps.utilities import RobotariumError, _check_array, _check_number, _describe
from rps.utilities.transformations import *  # noqa: F401,F403 (rps re-exports them from here)
from rps.utilities.transformations import __all__ as _transformations_all

__all__ = list(_transformations_all) + [
    "create_si_position_controller",
    "create_clf_unicycle_position_controller",
    "create_clf_unicycle_pose_controller",
    "create_hybrid_unicycle_pose_controller",
]


def create_si_position_controller(x_velocity_gain=1, y_velocity_gain=1, velocity_magnitude_limit=0.15):
    """Return si_position_controller(xi, positions) -> 2xN single-integrator velocities (guide 4.4.1).

    Proportional control dxi = diag(x_velocity_gain, y_velocity_gain) (positions - xi), each
    column scaled down to norm velocity_magnitude_limit when longer (keeping its direction).

    x_velocity_gain, y_velocity_gain: > 0. velocity_magnitude_limit: >= 0 (m/s; the platform
    drives at most 0.2 m/s; +inf for no limit).
    """
    where = "create_si_position_controller"
    gains = np.array([[_check_number(x_velocity_gain, "x_velocity_gain", where, low=0, strict=True)],
                      [_check_number(y_velocity_gain, "y_velocity_gain", where, low=0, strict=True)]])
    # Fix: rps's type-check message for this argument named y_velocity_gain.
    limit = _check_number(velocity_magnitude_limit, "velocity_magnitude_limit", where, low=0, allow_inf=True)

    def si_position_controller(xi, positions):
        """xi: 2xN single-integrator states; positions: 2xN goal points -> 2xN velocities."""
        where_ctl = "si_position_controller (from create_si_position_controller)"
        xi = _check_array(xi, "xi", where_ctl, 2, what="of single-integrator states [x; y]")
        positions = _check_array(positions, "positions", where_ctl, 2, xi.shape[1],
                                 "of goal points [x_goal; y_goal], one column per column of xi")
        return control.si_position_law(xi, positions, gains, limit)

    return si_position_controller


def create_clf_unicycle_position_controller(linear_velocity_gain=0.8, angular_velocity_gain=3):
    """Return position_uni_clf_controller(states, positions) -> 2xN [v; omega] (guide 4.4.2/4.4.3).

    With e the distance to the goal and phi the bearing of the goal relative to the heading
    (a control-Lyapunov design, rps controllers.py):
        v = linear_velocity_gain * e * cos(phi),  omega = angular_velocity_gain * e * sin(phi).

    linear_velocity_gain, angular_velocity_gain: >= 0.
    (The guide's headings 4.4.2 and 4.4.3 swap "pose" and "position"; the names here are rps's.)
    """
    where = "create_clf_unicycle_position_controller"
    k_v = _check_number(linear_velocity_gain, "linear_velocity_gain", where, low=0)
    k_w = _check_number(angular_velocity_gain, "angular_velocity_gain", where, low=0)

    def position_uni_clf_controller(states, positions):
        """states: 3xN unicycle states [x; y; theta]; positions: 2xN goals [x; y] -> 2xN [v; omega]."""
        where_ctl = "position_uni_clf_controller (from create_clf_unicycle_position_controller)"
        states = _check_array(states, "states", where_ctl, 3, what="of unicycle states [x; y; theta]")
        positions = _check_array(positions, "positions", where_ctl, 2, states.shape[1],
                                 "of goal positions [x_goal; y_goal], one column per column of states")
        error = positions - states[:2]
        distance = np.linalg.norm(error, axis=0)
        bearing = np.arctan2(error[1], error[0]) - states[2]
        return np.vstack((k_v * distance * np.cos(bearing), k_w * distance * np.sin(bearing)))

    return position_uni_clf_controller


def create_clf_unicycle_pose_controller(approach_angle_gain=1, desired_angle_gain=2.7, rotation_error_gain=1):
    """Return pose_uni_clf_controller(states, poses) -> 2xN [v; omega] (guide 4.4.2/4.4.3).

    The Lyapunov-based steering law of Aicardi, Casalino, Bicchi and Balestrino (1995), as in rps.
    In the goal's frame, let e be the distance from robot to goal, theta the direction of the
    robot-to-goal vector and alpha = theta - (robot heading - goal heading), wrapped. Then
        v = gamma * e * cos(alpha)
        omega = k * alpha + gamma * (cos(alpha) sin(alpha) / alpha) * (alpha + h * theta)
    with gamma = approach_angle_gain, k = desired_angle_gain, h = rotation_error_gain (all >= 0).
    """
    where = "create_clf_unicycle_pose_controller"
    gamma = _check_number(approach_angle_gain, "approach_angle_gain", where, low=0)
    k = _check_number(desired_angle_gain, "desired_angle_gain", where, low=0)
    h = _check_number(rotation_error_gain, "rotation_error_gain", where, low=0)

    def pose_uni_clf_controller(states, poses):
        """states: 3xN unicycle states; poses: 3xN goal poses [x; y; theta] -> 2xN [v; omega]."""
        where_ctl = "pose_uni_clf_controller (from create_clf_unicycle_pose_controller)"
        states = _check_array(states, "states", where_ctl, 3, what="of unicycle states [x; y; theta]")
        poses = _check_array(poses, "poses", where_ctl, 3, states.shape[1],
                             "of goal poses [x_goal; y_goal; theta_goal], one column per column of states")
        # Fix: rps computed cos(a) sin(a) / a, NaN at a = 0; sin(a)/a = sinc(a/pi) -> 1 there (exact_sinc).
        # At the goal, arctan2 must see (+0, +0), not a -0.0 (no_spin_at_goal). 2.x's port does neither.
        # Fix: rps printed gamma, e and cos(alpha) for every robot on every call.
        return control.clf_pose_law(states, poses, gamma, k, h, exact_sinc=True, no_spin_at_goal=True)

    return pose_uni_clf_controller


def create_hybrid_unicycle_pose_controller(linear_velocity_gain=1, angular_velocity_gain=2, velocity_magnitude_limit=0.15,
                                           angular_velocity_limit=np.pi, position_error=0.05, position_epsilon=0.03,
                                           rotation_error=0.05):
    """Return pose_uni_hybrid_controller(states, poses, input_approach_state=np.empty([0, 0])) (guide 4.4.4).

    A two-mode controller per robot: while approaching, drive straight at the goal position
    (single-integrator velocity capped at velocity_magnitude_limit, mapped with
    create_si_to_uni_dynamics(linear_velocity_gain, angular_velocity_limit)) until within
    position_error - position_epsilon; then turn on the spot, omega = angular_velocity_gain *
    heading error, until within rotation_error of the goal heading; then stop. A robot that,
    while turning, is found more than position_error away goes back to approaching.

    input_approach_state: optional, one 0/1 flag per robot (shape (N,) or (1, N); 1 =
    approaching). Without it (the default, an empty array) every robot starts approaching on each
    call, as in rps. With it, the flags are read and updated in place, so passing the same array
    on every call keeps each robot's mode between calls (the hysteresis rps intended).

    Gains and limits: linear_velocity_gain > 0, the others >= 0; position_epsilon is the guide's
    0.03 (rps 0.0.0: 0.02).
    """
    where = "create_hybrid_unicycle_pose_controller"
    _check_number(linear_velocity_gain, "linear_velocity_gain", where, low=0, strict=True)
    k_w = _check_number(angular_velocity_gain, "angular_velocity_gain", where, low=0)
    speed_limit = _check_number(velocity_magnitude_limit, "velocity_magnitude_limit", where, low=0, allow_inf=True)
    _check_number(angular_velocity_limit, "angular_velocity_limit", where, low=0)
    close_enough = _check_number(position_error, "position_error", where, low=0)
    epsilon = _check_number(position_epsilon, "position_epsilon", where, low=0)
    aligned = _check_number(rotation_error, "rotation_error", where, low=0)

    si_to_uni_dyn = create_si_to_uni_dynamics(linear_velocity_gain=linear_velocity_gain,
                                              angular_velocity_limit=angular_velocity_limit)

    def pose_uni_hybrid_controller(states, poses, input_approach_state=np.empty([0, 0])):
        """states: 3xN unicycle states; poses: 3xN goal poses -> 2xN [v; omega]."""
        where_ctl = "pose_uni_hybrid_controller (from create_hybrid_unicycle_pose_controller)"
        states = _check_array(states, "states", where_ctl, 3, what="of unicycle states [x; y; theta]")
        n = states.shape[1]
        poses = _check_array(poses, "poses", where_ctl, 3, n,
                             "of goal poses [x_goal; y_goal; theta_goal], one column per column of states")
        # Fix: rps only defined approach_state when input_approach_state had the wrong size, so
        # passing one raised NameError; here a size-N array is used and updated in place.
        if input_approach_state is None or (isinstance(input_approach_state, np.ndarray)
                                            and input_approach_state.size == 0):
            approaching = np.ones(n, dtype=bool)
            given = None
        else:
            given = input_approach_state
            if not (isinstance(given, np.ndarray) and given.dtype.kind in "biuf"
                    and given.shape in ((n,), (1, n)) and given.flags.writeable):
                raise RobotariumError(
                    "%s: input_approach_state must be an empty array (the default) or a writable numpy "
                    "array of N = %d flags of shape (%d,) or (1, %d); received %s."
                    % (where_ctl, n, n, n, _describe(given)))
            if not np.all(np.isfinite(given)):
                raise RobotariumError("%s: input_approach_state must hold finite 0/1 flags; received NaN or inf."
                                      % where_ctl)
            approaching = given.reshape(-1) != 0

        # Approach in a straight line, then turn on the spot (angular_velocity_gain; 2.x: 2), leaving the
        # approach mode unless the robot has drifted away; else stand still. The speed cap rounds as rps's
        # (divide_last). Fix: rps wrote `approach_state = 1` (the whole array) for `approach_state[i] = 1`.
        dxu, approaching, _ = control.hybrid_pose_step(
            states, poses, approaching, si_to_uni_dyn, speed_limit=speed_limit, turn_gain=k_w,
            position_error=close_enough, position_epsilon=epsilon, rotation_error=aligned, divide_last=True)
        if given is not None:
            given[...] = approaching.reshape(given.shape)
        return dxu

    return pose_uni_hybrid_controller
