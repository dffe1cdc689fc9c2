"""Unicycle kinematics: the single-integrator <-> unicycle maps and the points ahead of the axle.

Plain numpy, no ROS, vectorised over robots (one column per robot), no argument checks: both rps
APIs check arguments their own way, then call in here; the testbed's 2.x colliders and sensor
origins are points ahead too. Two ways to drive a unicycle (v, omega) with a single-integrator
velocity dxi: heading tracking (si_to_uni_heading, si_to_uni_heading_reversible: v along the
heading, omega turns it towards dxi), or a point `distance` l ahead of the axle (points_ahead),
which moves like a single integrator:
      d/dt point = [cos theta, -l sin theta; sin theta, l cos theta] [v; omega]
invertible for l > 0 (si_to_uni_projected inverts it, uni_to_si_projected applies it).
"""
import numpy as np

from robotarium_core.model import wrap_angle


def body_frame(dxi, theta):
    """2xN world-frame vectors dxi seen from robots heading theta: (along the heading, to its left)."""
    c, s = np.cos(theta), np.sin(theta)
    return c * dxi[0] + s * dxi[1], -s * dxi[0] + c * dxi[1]


def si_to_uni_heading(dxi, theta, linear_velocity_gain, angular_velocity_limit, *, gain_in_angle=True,
                      no_spin_at_rest=True):
    """Heading tracking: 2xN [v; omega] for single-integrator velocities dxi (2xN) at headings theta.

    v = linear_velocity_gain * (dxi along the heading);
    omega = angular_velocity_limit * phi / (pi/2), phi = arctan2(dxi to the left, a) in (-pi, pi],
    so the limit is reached at phi = +-pi/2 and a target behind gives up to twice it.
    a is v (gain_in_angle: rps 0.0.0, the MATLAB toolbox, 2.x's backwards mapping) or dxi along the
    heading (2.x's forward mapping); they differ where the gain is not 1.
    no_spin_at_rest: a zero dxi can give a = -0.0 and arctan2(0, -0.0) = pi, a still robot told to
    spin at twice the limit; adding +0.0 to a turns -0.0 into +0.0 and leaves every other number
    alone (the guide's API does; 2.x, as 2.1.0, does not).
    """
    along, left = body_frame(dxi, theta)
    v = linear_velocity_gain * along
    a = v if gain_in_angle else along
    if no_spin_at_rest:
        a = a + 0.0
    return np.vstack((v, angular_velocity_limit * np.arctan2(left, a) / (np.pi / 2)))


def si_to_uni_heading_reversible(dxi, theta, linear_velocity_gain, angular_velocity_limit, *, no_spin_at_rest=False):
    """si_to_uni_heading driving backwards where dxi points more than 90 degrees off the heading:
    the robot then tracks dxi with its back (heading theta + pi) and v changes sign. The angle is
    that of (dxi to the left, v), as 2.1.0's create_si_to_uni_dynamics_with_backwards_motion."""
    relative = wrap_angle(np.arctan2(dxi[1], dxi[0]) - theta)
    forward = (relative > -np.pi / 2) & (relative < np.pi / 2)
    heading = np.where(forward, theta, wrap_angle(theta + np.pi))
    dxu = si_to_uni_heading(dxi, heading, linear_velocity_gain, angular_velocity_limit, gain_in_angle=True,
                            no_spin_at_rest=no_spin_at_rest)
    dxu[0] = np.where(forward, dxu[0], -dxu[0])
    return dxu


def si_to_uni_projected(dxi, theta, distance, angular_velocity_limit=None):
    """2xN [v; omega] that move the points `distance` ahead of the axles with velocities dxi (2xN):
    v = dxi along the heading, omega = (dxi to the left) / distance, clipped to
    +-angular_velocity_limit unless that is None (2.x does not clip)."""
    along, left = body_frame(dxi, theta)
    omega = left / distance
    if angular_velocity_limit is not None:
        omega = np.clip(omega, -angular_velocity_limit, angular_velocity_limit)
    return np.vstack((along, omega))


def uni_to_si_projected(dxu, theta, distance):
    """2xN velocities of the points `distance` ahead of unicycles at headings theta driven by dxu = [v; omega]."""
    c, s = np.cos(theta), np.sin(theta)
    v, omega = dxu[0], dxu[1]
    return np.vstack((c * v - distance * s * omega, s * v + distance * c * omega))


def points_ahead(poses, distance):
    """2xN points `distance` ahead of the axles of unicycles at poses (3xN [x; y; theta])."""
    return poses[:2] + distance * np.vstack((np.cos(poses[2]), np.sin(poses[2])))


def axles_behind(points, theta, distance):
    """2xN axle positions of unicycles at headings theta whose points `distance` ahead are `points`
    (the inverse of points_ahead)."""
    return points[:2] - distance * np.vstack((np.cos(theta), np.sin(theta)))
