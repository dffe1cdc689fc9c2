"""Position and pose controllers with 2.x's names and defaults (2.1.0 rps/utilities/controllers.py)."""
import numpy as np

from rps.utilities.transformations import *  # noqa: F401,F403 (2.x's module brings them too)
from rps.utilities.transformations import create_si_to_uni_dynamics, create_si_to_uni_mapping

__all__ = ["np", "create_si_position_controller", "create_uni_position_controller", "create_pose_controller_clf",
           "create_pose_controller_hybrid", "create_pose_parking_controller_clf",
           "create_pose_parking_controller_hybrid", "create_si_to_uni_dynamics", "create_si_to_uni_mapping"]


def _wrap(angle):
    return np.arctan2(np.sin(angle), np.cos(angle))


def create_si_position_controller(x_velocity_gain=0.8, y_velocity_gain=0.8, velocity_magnitude_limit=0.15):
    """f(states 2xN, goals 2xN) -> dxi: proportional, each column's norm clamped to the limit."""
    for name, value in (("x_velocity_gain", x_velocity_gain), ("y_velocity_gain", y_velocity_gain)):
        assert isinstance(value, (int, float)) and value > 0, "%s must be a positive number." % name
    assert isinstance(velocity_magnitude_limit, (int, float)) and velocity_magnitude_limit >= 0, \
        "velocity_magnitude_limit must be non-negative."
    gains = np.array([[x_velocity_gain], [y_velocity_gain]])

    def position_controller_si(states, poses):
        assert states.shape[0] == 2 and poses.shape[0] == 2, "states and poses must be 2xN."
        assert poses.shape[1] == states.shape[1], "states and poses must have the same number of columns."
        dx = gains * (poses - states)
        norms = np.linalg.norm(dx, axis=0)
        over = norms > velocity_magnitude_limit
        dx[:, over] *= velocity_magnitude_limit / norms[over]
        return dx
    return position_controller_si


def create_uni_position_controller(x_velocity_gain=0.8, y_velocity_gain=0.8, velocity_magnitude_limit=0.15,
                                   projection_distance=0.03):
    """f(states 3xN, goals 2xN) -> dxu: the single-integrator controller on the point ahead."""
    si = create_si_position_controller(x_velocity_gain, y_velocity_gain, velocity_magnitude_limit)
    si_to_uni, uni_to_si_states = create_si_to_uni_mapping(projection_distance=projection_distance)

    def position_controller_uni(states, poses):
        assert states.shape[0] == 3 and poses.shape[0] == 2, "states must be 3xN and poses 2xN."
        return si_to_uni(si(uni_to_si_states(states), poses), states)
    return position_controller_uni


def create_pose_controller_clf(approach_angle_gain=1, desired_angle_gain=2.7, rotation_error_gain=1,
                               wheel_velocity_limit=10.0, wheel_radius=0.016, base_length=0.105):
    """f(states 3xN, poses 3xN) -> dxu: the control-Lyapunov pose controller, each command scaled
    down until both wheels are within wheel_velocity_limit."""
    def controller_clf(states, poses):
        assert states.shape[0] == 3 and poses.shape[0] == 3, "states and poses must be 3xN."
        assert poses.shape[1] == states.shape[1], "states and poses must have the same number of columns."
        goal = poses[2]
        dx, dy = poses[0] - states[0], poses[1] - states[1]
        c, s = np.cos(-goal), np.sin(-goal)
        ex, ey = c * dx - s * dy, s * dx + c * dy
        e = np.hypot(ex, ey)
        theta = np.arctan2(ey, ex)
        alpha = _wrap(theta - (states[2] - goal))
        with np.errstate(divide="ignore", invalid="ignore"):
            sinc = np.where(np.abs(alpha) < 1e-6, 1.0, np.sin(alpha) / alpha)
        v = approach_angle_gain * e * np.cos(alpha)
        w = desired_angle_gain * alpha + approach_angle_gain * np.cos(alpha) * sinc * (alpha + rotation_error_gain * theta)
        left = (v - base_length / 2 * w) / wheel_radius
        right = (v + base_length / 2 * w) / wheel_radius
        fastest = np.maximum(np.abs(left), np.abs(right))
        scale = np.where(fastest > wheel_velocity_limit, wheel_velocity_limit / np.maximum(fastest, 1e-300), 1.0)
        return np.vstack([v * scale, w * scale])
    return controller_clf


def create_pose_controller_hybrid(linear_velocity_gain=0.8, angular_velocity_limit=np.pi, velocity_magnitude_limit=0.15,
                                  position_error=0.03, position_epsilon=0.01, rotation_error=0.05):
    """f(states, poses[, in_approach_state]) -> dxu (and the approach state when one is passed):
    drive to the position (single integrator, clamped), then turn to the heading (gain 2); a robot
    that drifts away from its position while turning approaches again."""
    si_to_uni = create_si_to_uni_dynamics(linear_velocity_gain=linear_velocity_gain,
                                          angular_velocity_limit=angular_velocity_limit)
    internal = {"approach_state": np.array([])}

    def controller_hybrid(states, poses, in_approach_state=None):
        n = states.shape[1]
        if in_approach_state is not None:
            approach = in_approach_state
        else:
            if internal["approach_state"].shape[0] != n:
                internal["approach_state"] = np.ones(n)
            approach = internal["approach_state"]
        vec = poses[:2] - states[:2]
        dist = np.linalg.norm(vec, axis=0)
        heading_error = _wrap(poses[2] - states[2])
        dxu = np.zeros((2, n))
        moving = (approach != 0) & (dist > position_error - position_epsilon)
        if np.any(moving):
            step = vec[:, moving].copy()
            long = dist[moving] > velocity_magnitude_limit
            step[:, long] *= velocity_magnitude_limit / dist[moving][long]
            dxu[:, moving] = si_to_uni(step, states[:, moving])
        turning = ~moving & (np.abs(heading_error) > rotation_error)
        approach[turning] = (dist[turning] > position_error).astype(approach.dtype)
        dxu[1, turning] = 2 * heading_error[turning]
        if in_approach_state is not None:
            return dxu, approach
        return dxu
    return controller_hybrid


def create_pose_parking_controller_clf(approach_angle_gain=1, desired_angle_gain=2.7, rotation_error_gain=1,
                                       wheel_velocity_limit=10.0, wheel_radius=0.016, base_length=0.105,
                                       position_error=0.05, rotation_error=0.2):
    """create_pose_controller_clf, with robots already at their pose stopped."""
    clf = create_pose_controller_clf(approach_angle_gain, desired_angle_gain, rotation_error_gain,
                                     wheel_velocity_limit, wheel_radius, base_length)

    def controller_clf_parking(states, poses):
        dxu = clf(states, poses)
        there = (np.linalg.norm(states[:2] - poses[:2], axis=0) < position_error) & (
            np.abs(_wrap(states[2] - poses[2])) < rotation_error)
        dxu[:, there] = 0
        return dxu
    return controller_clf_parking


def create_pose_parking_controller_hybrid(linear_velocity_gain=0.8, angular_velocity_limit=np.pi,
                                          velocity_magnitude_limit=0.15, position_error=0.05,
                                          position_epsilon=0.01, rotation_error=0.2):
    """create_pose_controller_hybrid, with robots already at their pose stopped."""
    hybrid = create_pose_controller_hybrid(linear_velocity_gain, angular_velocity_limit, velocity_magnitude_limit,
                                           position_error, position_epsilon, rotation_error)

    def controller_hybrid_parking(states, poses):
        dxu = hybrid(states, poses)
        there = (np.linalg.norm(states[:2] - poses[:2], axis=0) < position_error) & (
            np.abs(_wrap(states[2] - poses[2])) < rotation_error)
        dxu[:, there] = 0
        return dxu
    return controller_hybrid_parking
