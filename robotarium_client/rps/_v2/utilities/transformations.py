"""Single-integrator <-> unicycle mappings with 2.x's names and defaults (2.1.0
rps/utilities/transformations.py), vectorised."""
import numpy as np

__all__ = ["np", "create_si_to_uni_dynamics", "create_si_to_uni_dynamics_with_backwards_motion",
           "create_si_to_uni_mapping", "create_uni_to_si_mapping"]


def _frames(theta):
    return np.cos(theta), np.sin(theta)


def create_si_to_uni_dynamics(linear_velocity_gain=1, angular_velocity_limit=np.pi):
    """f(dxi 2xN, states 3xN) -> dxu: v = gain * (heading . dxi), w = limit * atan2(left . dxi,
    heading . dxi) / (pi / 2)."""
    def si_to_uni(dxi, states):
        c, s = _frames(states[2])
        along = c * dxi[0] + s * dxi[1]
        across = -s * dxi[0] + c * dxi[1]
        return np.vstack([linear_velocity_gain * along,
                          angular_velocity_limit * np.arctan2(across, along) / (np.pi / 2)])
    return si_to_uni


def create_si_to_uni_dynamics_with_backwards_motion(linear_velocity_gain=1, angular_velocity_limit=np.pi):
    """As create_si_to_uni_dynamics, driving backwards where that needs less turning."""
    def si_to_uni(dxi, states):
        relative = np.arctan2(dxi[1], dxi[0]) - states[2]
        relative = np.arctan2(np.sin(relative), np.cos(relative))
        forward = (relative > -np.pi / 2) & (relative < np.pi / 2)
        heading = np.where(forward, states[2], np.arctan2(np.sin(states[2] + np.pi), np.cos(states[2] + np.pi)))
        c, s = _frames(heading)
        v = linear_velocity_gain * (c * dxi[0] + s * dxi[1])
        w = angular_velocity_limit * np.arctan2(-s * dxi[0] + c * dxi[1], v) / (np.pi / 2)
        return np.vstack([np.where(forward, v, -v), w])
    return si_to_uni


def create_si_to_uni_mapping(projection_distance=0.05):
    """(si_to_uni_dyn(dxi, states) -> dxu, uni_to_si_states(states) -> points projection_distance ahead)."""
    d = projection_distance

    def si_to_uni(dxi, states):
        c, s = _frames(states[2])
        return np.vstack([c * dxi[0] + s * dxi[1], (-s * dxi[0] + c * dxi[1]) / d])

    def uni_to_si(states):
        return states[:2, :] + d * np.array([np.cos(states[2, :]), np.sin(states[2, :])])
    return si_to_uni, uni_to_si


def create_uni_to_si_mapping(projection_distance=0.05):
    """(uni_to_si_dyn(dxu, states) -> dxi, si_to_uni_states(uni_states, si_states) -> axle positions)."""
    d = projection_distance

    def uni_to_si(dxu, states):
        c, s = _frames(states[2])
        return np.vstack([c * dxu[0] - d * s * dxu[1], s * dxu[0] + d * c * dxu[1]])

    def si_to_uni(uni_states, si_states):
        return si_states[:2, :] - d * np.array([np.cos(uni_states[2, :]), np.sin(uni_states[2, :])])
    return uni_to_si, si_to_uni
