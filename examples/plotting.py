"""Plotting: draw on the arena while five robots drive to the corners of a pentagon (guide section 3.8).

Everything drawn on r.axes is in arena metres, and on the real Robotarium it is projected onto
the arena floor. This script draws
  * the goals: a scatter of squares, one colour per robot, with text labels G0...G4;
  * a circle around each robot and its name, both moved every iteration (set_offsets,
    set_position);
  * each robot's path so far: a line plot, extended every iteration (set_data).
Sizes are given in metres and converted with determine_marker_size (marker area in points^2)
and determine_font_size (font height in points), so they fit the arena at any window size.
The robots drive with a single-integrator controller and the barrier certificate with the
arena boundary.

Success: every robot ends within 0.05 m of its goal, with no collisions, no boundary violations
and no actuator-limit warnings in the debug report. The script stops as soon as all robots are
there (about 350 iterations; 1000 at most) and prints a final line such as
"goal reached: all 5 robots within 0.05 m".

Run:  ./robotarium run examples/plotting.py
"""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import *
from rps.utilities.controllers import *
from rps.utilities.misc import *
from rps.utilities.transformations import *

N = 5
GOAL_TOLERANCE = 0.05     # m
MAX_ITERATIONS = 1000     # 0.033 s each: about 33 s at most

# Start: a row along the bottom, facing up. Goals: the corners of a pentagon (radius 0.6 m).
initial_conditions = np.array([[-1.2, -0.6, 0.0, 0.6, 1.2],
                               [-0.75, -0.75, -0.75, -0.75, -0.75],
                               [np.pi / 2] * 5])
corner_angles = np.pi / 2 + 2 * np.pi * np.array([1, 2, 0, 4, 3]) / 5   # left to right
goal_points = np.array([0.6 * np.cos(corner_angles), 0.1 + 0.6 * np.sin(corner_angles)])


def within_wheel_limits(dxu, wheel_radius=0.016, base_length=0.105, max_wheel_speed=12.5):
    """Scale each robot's (v, w) down, keeping its turning radius, so neither wheel of the
    GTernal turns faster than max_wheel_speed rad/s (with a 5% margin)."""
    rim_speed = np.abs(dxu[0, :]) + base_length / 2 * np.abs(dxu[1, :])  # fastest wheel, m/s
    limit = 0.95 * max_wheel_speed * wheel_radius
    return dxu * np.minimum(1.0, limit / np.maximum(rim_speed, 1e-9))


r = robotarium.Robotarium(number_of_robots=N, show_figure=True,
                          initial_conditions=initial_conditions, sim_in_real_time=True)

si_position_controller = create_si_position_controller()
si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary()
si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion()

# Sizes in metres, converted to matplotlib's units for this figure.
goal_marker_size = determine_marker_size(r, 0.2)     # a 0.2 m square
robot_marker_size = determine_marker_size(r, 0.15)   # a 0.15 m circle
font_size = determine_font_size(r, 0.08)             # 0.08 m tall letters
colors = ['tab:red', 'tab:blue', 'tab:green', 'tab:purple', 'tab:orange']

# Goals: squares and labels (drawn once; zorder=-2 puts them under the robots).
r.axes.scatter(goal_points[0, :], goal_points[1, :], s=goal_marker_size, marker='s',
               facecolors='none', edgecolors=colors, linewidth=3, zorder=-2)
for i in range(N):
    r.axes.text(goal_points[0, i], goal_points[1, i], 'G%d' % i, fontsize=font_size,
                color='k', fontweight='bold', horizontalalignment='center',
                verticalalignment='center', zorder=-2)

# Robots: circles, names and paths (moved every iteration).
x = r.get_poses()
robot_markers = r.axes.scatter(x[0, :], x[1, :], s=robot_marker_size, marker='o',
                               facecolors='none', edgecolors=colors, linewidth=3)
robot_labels = [r.axes.text(x[0, i], x[1, i] + 0.2, 'R%d' % i, fontsize=font_size,
                            color=colors[i], horizontalalignment='center',
                            verticalalignment='center') for i in range(N)]
path_x, path_y = [[x[0, i]] for i in range(N)], [[x[1, i]] for i in range(N)]
paths = [r.axes.plot(path_x[i], path_y[i], color=colors[i], linewidth=2, zorder=-1)[0]
         for i in range(N)]
r.step()

for iteration in range(MAX_ITERATIONS):
    x = r.get_poses()

    # Update the drawing.
    robot_markers.set_offsets(x[:2, :].T)
    for i in range(N):
        robot_labels[i].set_position((x[0, i], x[1, i] + 0.2))
        path_x[i].append(x[0, i])
        path_y[i].append(x[1, i])
        paths[i].set_data(path_x[i], path_y[i])

    distances = np.linalg.norm(x[:2, :] - goal_points, axis=0)
    if np.all(distances < GOAL_TOLERANCE):
        # A caption in the middle of the arena, shown with one last step.
        r.axes.text(0, 0.1, 'Done!', fontsize=2 * font_size, color='k', fontweight='bold',
                    horizontalalignment='center', verticalalignment='center', zorder=20)
        r.set_velocities(np.arange(N), np.zeros((2, N)))
        r.step()
        break

    dxi = si_position_controller(x[:2, :], goal_points)
    dxi = si_barrier_cert(dxi, x[:2, :])
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
