"""Mappings between single-integrator and unicycle models (guide section 4.3).

A unicycle at pose (x, y, theta) takes commands (v, omega). Two ways to drive it with a
single-integrator velocity dxi: heading tracking (create_si_to_uni_dynamics,
..._with_backwards_motion: v along the heading, omega turns it towards dxi), or a point
`projection_distance` ahead of the axle, which moves exactly like a single integrator
(create_si_to_uni_mapping, create_uni_to_si_dynamics; guide 4.3.3-4.3.4).

The maps themselves are robotarium_core.kinematics', shared with 2.x's module; this one keeps the
guide's names, defaults, argument checks and messages. Its fixes to rps 0.0.0 are marked "Fix:"
in the code and listed in docs/user-guide.md#the-toolboxs-fixes-to-rps-000.
"""
import numpy as np

from robotarium_core import kinematics
from rps.utilities import _check_array, _check_number

__all__ = [
    "np",
    "create_si_to_uni_dynamics",
    "create_si_to_uni_dynamics_with_backwards_motion",
    "create_si_to_uni_mapping",
    "create_uni_to_si_dynamics",
]


def _inputs(dxi, poses, where):
    dxi = _check_array(dxi, "dxi", where, 2, what="of single-integrator velocities [x_dot; y_dot]")
    poses = _check_array(poses, "poses", where, 3, dxi.shape[1], "of unicycle poses [x; y; theta], one column per column of dxi")
    return dxi, poses


def create_si_to_uni_dynamics(linear_velocity_gain=1, angular_velocity_limit=np.pi):
    """Return si_to_uni_dyn(dxi, poses) -> 2xN unicycle commands [v; omega] (guide 4.3.1).

    v = linear_velocity_gain * (dxi . heading)
    omega = angular_velocity_limit * phi / (pi/2), phi = arctan2(dxi . left normal, v) in (-pi, pi]
    (for a gain of 1, phi is the angle from the heading to dxi)

    As in rps and the MATLAB toolbox, angular_velocity_limit is reached at phi = +-pi/2, so a
    target behind the robot gives up to twice it (the testbed then thresholds to the wheel limits).

    linear_velocity_gain: > 0. angular_velocity_limit: >= 0 (rad/s).
    """
    where = "create_si_to_uni_dynamics"
    gain = _check_number(linear_velocity_gain, "linear_velocity_gain", where, low=0, strict=True)
    limit = _check_number(angular_velocity_limit, "angular_velocity_limit", where, low=0)

    def si_to_uni_dyn(dxi, poses):
        """dxi: 2xN single-integrator velocities; poses: 3xN unicycle poses -> 2xN [v; omega]."""
        dxi, poses = _inputs(dxi, poses, "si_to_uni_dyn (from create_si_to_uni_dynamics)")
        # rps and MATLAB measure the angle of (v, left), so the gain also shapes the turn rate (2.x's
        # forward map does not). Fix: a zero command no longer spins a robot at 2*angular_velocity_limit
        # (no_spin_at_rest: arctan2(+0.0, -0.0) = pi in rps).
        return kinematics.si_to_uni_heading(dxi, poses[2], gain, limit, gain_in_angle=True, no_spin_at_rest=True)

    return si_to_uni_dyn


def create_si_to_uni_dynamics_with_backwards_motion(linear_velocity_gain=1, angular_velocity_limit=np.pi):
    """The same mapping as create_si_to_uni_dynamics, as in rps 0.0.0 (guide 4.3.2).

    rps 0.0.0 ships this as the forward mapping (upstream: "TODO: Backwards motion is the same as
    without backwards motion"), and the guide's scripts are tuned on that: a version that really
    backs up (as guide 4.3.2's text and the MATLAB toolbox describe) made the guide's own
    go-to-point script (§3.1.1) spin about its goals forever, because that script steers the
    projected point with commands computed for the robot's centre. Scripts must behave here as
    they do on the Robotarium simulator, so we keep its behaviour.
    """
    where = "create_si_to_uni_dynamics_with_backwards_motion"
    _check_number(linear_velocity_gain, "linear_velocity_gain", where, low=0, strict=True)
    _check_number(angular_velocity_limit, "angular_velocity_limit", where, low=0)
    forward = create_si_to_uni_dynamics(linear_velocity_gain, angular_velocity_limit)

    def si_to_uni_dyn(dxi, poses):
        """dxi: 2xN single-integrator velocities; poses: 3xN unicycle poses -> 2xN [v; omega]."""
        _inputs(dxi, poses, "si_to_uni_dyn (from create_si_to_uni_dynamics_with_backwards_motion)")
        return forward(dxi, poses)

    return si_to_uni_dyn


def create_si_to_uni_mapping(projection_distance=0.05, angular_velocity_limit=np.pi):
    """Return (si_to_uni_dyn, uni_to_si_states) for a control point projection_distance ahead (guide 4.3.3).

    si_to_uni_dyn(dxi, poses): inverts the projected point's kinematics,
        v = dxi . heading, omega = (dxi . left normal) / projection_distance,
    with omega clipped to +-angular_velocity_limit.
    uni_to_si_states(poses): the 2xN positions of the projected points.

    projection_distance: > 0 (m). angular_velocity_limit: >= 0 (rad/s; +inf for no clip).
    """
    where = "create_si_to_uni_mapping"
    distance = _check_number(projection_distance, "projection_distance", where, low=0, strict=True)
    # Fix: rps checked projection_distance >= 0 here under angular_velocity_limit's message.
    limit = _check_number(angular_velocity_limit, "angular_velocity_limit", where, low=0, allow_inf=True)

    def si_to_uni_dyn(dxi, poses):
        """dxi: 2xN velocities of the projected points; poses: 3xN unicycle poses -> 2xN [v; omega]."""
        dxi, poses = _inputs(dxi, poses, "si_to_uni_dyn (from create_si_to_uni_mapping)")
        return kinematics.si_to_uni_projected(dxi, poses[2], distance, limit)   # clipped, as rps (2.x is not)

    def uni_to_si_states(poses):
        """poses: 3xN unicycle poses -> 2xN positions of the projected control points."""
        poses = _check_array(poses, "poses", "uni_to_si_states (from create_si_to_uni_mapping)", 3,
                             what="of unicycle poses [x; y; theta]")
        return kinematics.points_ahead(poses, distance)

    return si_to_uni_dyn, uni_to_si_states


def create_uni_to_si_dynamics(projection_distance=0.05):
    """Return uni_to_si_dyn(dxu, poses) -> 2xN velocities of points projection_distance ahead (guide 4.3.4).

    [x_dot; y_dot] = [cos theta, -l sin theta; sin theta, l cos theta] [v; omega], l = projection_distance.
    """
    where = "create_uni_to_si_dynamics"
    distance = _check_number(projection_distance, "projection_distance", where, low=0, strict=True)

    def uni_to_si_dyn(dxu, poses):
        """dxu: 2xN unicycle commands [v; omega]; poses: 3xN unicycle poses -> 2xN [x_dot; y_dot]."""
        # Fix: rps's type check named an undefined variable (dxi) and raised NameError instead.
        where_dyn = "uni_to_si_dyn (from create_uni_to_si_dynamics)"
        dxu = _check_array(dxu, "dxu", where_dyn, 2, what="of unicycle commands [v; omega]")
        poses = _check_array(poses, "poses", where_dyn, 3, dxu.shape[1],
                             "of unicycle poses [x; y; theta], one column per column of dxu")
        return kinematics.uni_to_si_projected(dxu, poses[2], distance)

    return uni_to_si_dyn
