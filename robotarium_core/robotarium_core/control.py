"""Feedback laws the rps controllers share: plain numpy, no ROS, no argument checks.

The guide's API (robotarium_client/rps/utilities/controllers.py) and 2.x's
(rps/_v2/utilities/controllers.py) wrap these in their own create_* functions, with their own
names, defaults and checks. Where the two APIs compute the same law with a different rounding or
edge case, it is a keyword argument here, named for what it changes.
"""
import numpy as np

from robotarium_core.model import wrap_angle


def limit_speeds(dxi, limit, norms, *, divide_last=False):
    """Scale the columns of dxi (2xN, in place; also returned) longer than `limit` down to that length,
    keeping their directions. norms: the columns' lengths.

    divide_last: (limit * dxi) / norm, as rps 0.0.0's hybrid controller rounds it, rather than
    dxi * (limit / norm); the two differ in the last bit only.
    """
    over = norms > limit
    if divide_last:
        dxi[:, over] = limit * dxi[:, over] / norms[over]
    else:
        dxi[:, over] *= limit / norms[over]
    return dxi


def si_position_law(xi, goals, gains, limit):
    """Proportional single-integrator control: dxi = gains * (goals - xi) (gains: 2x1, per axis), each
    column no longer than `limit` (limit_speeds)."""
    dxi = gains * (goals - xi)
    return limit_speeds(dxi, limit, np.linalg.norm(dxi, axis=0))


def clf_pose_law(states, goals, approach_angle_gain, desired_angle_gain, rotation_error_gain, *, exact_sinc=True,
                 no_spin_at_goal=True):
    """The control-Lyapunov pose law of Aicardi, Casalino, Bicchi and Balestrino (1995): 2xN [v; omega]
    driving unicycles at states (3xN) to goals (3xN [x; y; theta]).

    In the goal's frame, e is the distance from robot to goal, theta the direction of the
    robot-to-goal vector and alpha = theta - (robot heading - goal heading), wrapped; then
        v = gamma e cos(alpha),  omega = k alpha + gamma cos(alpha) (sin(alpha) / alpha) (alpha + h theta)
    with gamma, k, h the approach angle, desired angle and rotation error gains.
    exact_sinc: sin(a)/a as np.sinc (exactly 1 at a = 0; the guide's API), else as 2.1.0 computes it
    (1 where |a| < 1e-6, sin(a)/a elsewhere).
    no_spin_at_goal: at the goal's position the rotated vector can hold a -0.0, and arctan2 then gives
    theta = +-pi (or -0.0); adding +0.0 makes it (+0, +0), theta = 0 (the guide's API; 2.x does not).
    """
    dx, dy = goals[:2] - states[:2]
    c, s = np.cos(goals[2]), np.sin(goals[2])
    along = c * dx + s * dy
    across = -s * dx + c * dy
    if no_spin_at_goal:
        along, across = along + 0.0, across + 0.0
    e = np.hypot(along, across)
    theta = np.arctan2(across, along)
    alpha = wrap_angle(theta - (states[2] - goals[2]))
    ca = np.cos(alpha)
    if exact_sinc:
        sinc = np.sinc(alpha / np.pi)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            sinc = np.where(np.abs(alpha) < 1e-6, 1.0, np.sin(alpha) / alpha)
    omega = desired_angle_gain * alpha + approach_angle_gain * ca * sinc * (alpha + rotation_error_gain * theta)
    return np.vstack((approach_angle_gain * e * ca, omega))


def hybrid_pose_step(states, goals, approaching, si_to_uni, *, speed_limit, turn_gain, position_error,
                     position_epsilon, rotation_error, divide_last=False):
    """One call of the two-mode (drive, then turn) pose controller for unicycles at states (3xN)
    going to goals (3xN). approaching: N booleans, each robot's mode.

    A robot approaching and farther than position_error - position_epsilon from its goal position
    drives straight at it: the single-integrator velocity goal - position, no longer than
    speed_limit (limit_speeds, with divide_last), mapped by si_to_uni(dxi, states). Otherwise one
    whose heading is more than rotation_error off turns on the spot, omega = turn_gain * heading
    error, and approaches again if it is farther than position_error. Otherwise it stands still.

    Returns (dxu 2xN, approaching after the call, the mask of robots that turned).
    """
    heading_error = wrap_angle(goals[2] - states[2])
    dxi = goals[:2] - states[:2]
    distance = np.linalg.norm(dxi, axis=0)
    dxu = np.zeros((2, states.shape[1]))
    drive = approaching & (distance > position_error - position_epsilon)
    if np.any(drive):
        step = limit_speeds(dxi[:, drive], speed_limit, distance[drive], divide_last=divide_last)
        dxu[:, drive] = si_to_uni(step, states[:, drive])
    turn = ~drive & (np.abs(heading_error) > rotation_error)
    approaching = np.where(turn, distance > position_error, approaching)
    dxu[1, turn] = turn_gain * heading_error[turn]
    return dxu, approaching, turn
