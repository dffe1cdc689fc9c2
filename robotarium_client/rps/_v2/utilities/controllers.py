"""Position and pose controllers with 2.x's names and defaults (2.1.0 rps/utilities/controllers.py).

The laws themselves are robotarium_core.control's, which the guide's module shares; this module
keeps 2.x's names, defaults, asserts and messages and passes 2.x's choices where the two APIs differ."""
import numpy as np

from robotarium_core import control
from robotarium_core.model import at_pose_mask
from rps.utilities.transformations import *  # noqa: F401,F403 (2.x's module brings them too)
from rps.utilities.transformations import create_si_to_uni_dynamics, create_si_to_uni_mapping

__all__ = ["np", "create_si_position_controller", "create_uni_position_controller", "create_pose_controller_clf",
           "create_pose_controller_hybrid", "create_pose_parking_controller_clf",
           "create_pose_parking_controller_hybrid", "create_si_to_uni_dynamics", "create_si_to_uni_mapping"]


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
        return control.si_position_law(states, poses, gains, velocity_magnitude_limit)
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
        # 2.1.0's sin(a)/a (1 below |a| = 1e-6) and no +0.0 at the goal (the guide's API: exact sinc, +0.0)
        v, w = control.clf_pose_law(states, poses, approach_angle_gain, desired_angle_gain, rotation_error_gain,
                                    exact_sinc=False, no_spin_at_goal=False)
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
        # 2.x turns with a fixed gain of 2 (the guide's API: angular_velocity_gain) and writes only the
        # turning robots' flags back, in the array's own dtype.
        dxu, approaching, turning = control.hybrid_pose_step(
            states, poses, approach != 0, si_to_uni, speed_limit=velocity_magnitude_limit, turn_gain=2,
            position_error=position_error, position_epsilon=position_epsilon, rotation_error=rotation_error)
        approach[turning] = approaching[turning].astype(approach.dtype)
        if in_approach_state is not None:
            return dxu, approach
        return dxu
    return controller_hybrid


def _parking(controller, position_error, rotation_error):
    """`controller` with the robots already at their pose (2.x: strictly within both errors) stopped."""
    def parking(states, poses):
        dxu = controller(states, poses)
        dxu[:, at_pose_mask(states, poses, position_error, rotation_error, strict=True)] = 0
        return dxu
    return parking


def create_pose_parking_controller_clf(approach_angle_gain=1, desired_angle_gain=2.7, rotation_error_gain=1,
                                       wheel_velocity_limit=10.0, wheel_radius=0.016, base_length=0.105,
                                       position_error=0.05, rotation_error=0.2):
    """create_pose_controller_clf, with robots already at their pose stopped."""
    return _parking(create_pose_controller_clf(approach_angle_gain, desired_angle_gain, rotation_error_gain,
                                               wheel_velocity_limit, wheel_radius, base_length),
                    position_error, rotation_error)


def create_pose_parking_controller_hybrid(linear_velocity_gain=0.8, angular_velocity_limit=np.pi,
                                          velocity_magnitude_limit=0.15, position_error=0.05,
                                          position_epsilon=0.01, rotation_error=0.2):
    """create_pose_controller_hybrid, with robots already at their pose stopped."""
    return _parking(create_pose_controller_hybrid(linear_velocity_gain, angular_velocity_limit, velocity_magnitude_limit,
                                                  position_error, position_epsilon, rotation_error),
                    position_error, rotation_error)
