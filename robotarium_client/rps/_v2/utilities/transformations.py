"""Single-integrator <-> unicycle mappings with 2.x's names and defaults (2.1.0
rps/utilities/transformations.py), vectorised.

The maps themselves are robotarium_core.kinematics', which the guide's module shares; this module
keeps 2.x's names and defaults and passes 2.x's choices where the two APIs differ."""
import numpy as np

from robotarium_core import kinematics

__all__ = ["np", "create_si_to_uni_dynamics", "create_si_to_uni_dynamics_with_backwards_motion",
           "create_si_to_uni_mapping", "create_uni_to_si_mapping"]


def create_si_to_uni_dynamics(linear_velocity_gain=1, angular_velocity_limit=np.pi):
    """f(dxi 2xN, states 3xN) -> dxu: v = gain * (heading . dxi), w = limit * atan2(left . dxi,
    heading . dxi) / (pi / 2)."""
    def si_to_uni(dxi, states):
        # 2.x: the angle of dxi itself (the guide's: of (v, left)), and a zero command may turn, as in 2.1.0.
        return kinematics.si_to_uni_heading(dxi, states[2], linear_velocity_gain, angular_velocity_limit,
                                            gain_in_angle=False, no_spin_at_rest=False)
    return si_to_uni


def create_si_to_uni_dynamics_with_backwards_motion(linear_velocity_gain=1, angular_velocity_limit=np.pi):
    """As create_si_to_uni_dynamics, driving backwards where that needs less turning."""
    def si_to_uni(dxi, states):
        # 2.x really backs up (the guide's API keeps rps 0.0.0's forward mapping under this name).
        return kinematics.si_to_uni_heading_reversible(dxi, states[2], linear_velocity_gain, angular_velocity_limit)
    return si_to_uni


def create_si_to_uni_mapping(projection_distance=0.05):
    """(si_to_uni_dyn(dxi, states) -> dxu, uni_to_si_states(states) -> points projection_distance ahead)."""
    d = projection_distance

    def si_to_uni(dxi, states):
        return kinematics.si_to_uni_projected(dxi, states[2], d)   # 2.x does not clip omega (the guide's API does)

    def uni_to_si(states):
        return kinematics.points_ahead(states, d)
    return si_to_uni, uni_to_si


def create_uni_to_si_mapping(projection_distance=0.05):
    """(uni_to_si_dyn(dxu, states) -> dxi, si_to_uni_states(uni_states, si_states) -> axle positions)."""
    d = projection_distance

    def uni_to_si(dxu, states):
        return kinematics.uni_to_si_projected(dxu, states[2], d)

    def si_to_uni(uni_states, si_states):
        return kinematics.axles_behind(si_states, uni_states[2], d)
    return uni_to_si, si_to_uni
