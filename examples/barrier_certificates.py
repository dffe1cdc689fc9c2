"""Barrier certificates: eight robots cross an ellipse at once, all paths meeting in the middle (guide 3.5).

The robots start evenly spaced on an ellipse that nearly fills the arena and each drives
straight at the spot three places further round, so all eight paths cross near the middle at
the same time. Left alone they would crash;
the single-integrator barrier certificate with the arena boundary
(create_single_integrator_barrier_certificate_with_boundary) changes each commanded velocity
as little as it can so that no two robots come closer than 0.17 m (centre to centre) and no
robot drives out of the arena. The robots swerve around each other and still get there.

Success: every robot ends within 0.05 m of its goal, with no collisions, no boundary
violations and no actuator-limit warnings in the debug report. The script stops as soon as all
robots are there (about 500 iterations; 1500 at most) and prints a final line such as
"goal reached: all 8 robots within 0.05 m".

Run:  ./robotarium run examples/barrier_certificates.py
See barrier_certificates_no_boundary.py for the certificate without the arena boundary.
"""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import *
from rps.utilities.controllers import *
from rps.utilities.misc import *
from rps.utilities.transformations import *

N = 8
SHOW_FIGURE = True        # False: no window (r.axes is then unavailable)
GOAL_TOLERANCE = 0.05     # m
MAX_ITERATIONS = 1500     # 0.033 s each: about 50 s at most

# Evenly spaced on an ellipse (semi-axes 1.3 m and 0.8 m), facing the centre. Goal: the spot
# three places further round (robot 0 goes to robot 3's spot, ...).
angles = 2 * np.pi * np.arange(N) / N + np.pi / N
x0, y0 = 1.3 * np.cos(angles), 0.8 * np.sin(angles)
initial_conditions = np.array([x0, y0, np.arctan2(-y0, -x0)])
goal_points = np.array([np.roll(x0, -3), np.roll(y0, -3)])


def within_wheel_limits(dxu, wheel_radius=0.016, base_length=0.105, max_wheel_speed=12.5):
    """Scale each robot's (v, w) down, keeping its turning radius, so neither wheel of the
    GTernal turns faster than max_wheel_speed rad/s (with a 5% margin)."""
    rim_speed = np.abs(dxu[0, :]) + base_length / 2 * np.abs(dxu[1, :])  # fastest wheel, m/s
    limit = 0.95 * max_wheel_speed * wheel_radius
    return dxu * np.minimum(1.0, limit / np.maximum(rim_speed, 1e-9))


r = robotarium.Robotarium(number_of_robots=N, show_figure=SHOW_FIGURE,
                          initial_conditions=initial_conditions, sim_in_real_time=True)

si_position_controller = create_si_position_controller()
si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary()
si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion()

if SHOW_FIGURE:
    r.axes.scatter(goal_points[0, :], goal_points[1, :], s=determine_marker_size(r, 0.1),
                   marker='x', color='g', zorder=-1)

for iteration in range(MAX_ITERATIONS):
    x = r.get_poses()

    distances = np.linalg.norm(x[:2, :] - goal_points, axis=0)
    if np.all(distances < GOAL_TOLERANCE):
        break

    dxi = si_position_controller(x[:2, :], goal_points)   # straight at the goal
    dxi = si_barrier_cert(dxi, x[:2, :])                  # ... unless that is unsafe
    dxu = si_to_uni_dyn(dxi, x)
    r.set_velocities(np.arange(N), within_wheel_limits(dxu))
    r.step()

r.call_at_scripts_end()

if np.all(distances < GOAL_TOLERANCE):
    print("goal reached: all %d robots within %.2f m (%d iterations, largest error %.3f m)"
          % (N, GOAL_TOLERANCE, iteration, distances.max()))
else:
    print("goal NOT reached: %d of %d robots within %.2f m after %d iterations"
          % (np.sum(distances < GOAL_TOLERANCE), N, GOAL_TOLERANCE, MAX_ITERATIONS))
