"""Go to pose: five robots drive to goal poses, a position AND a heading each (guide section 3.2).

The robots start in a column on the left of the arena, facing right. Their goals form an arc on
the right, every robot facing the centre of the arc like an audience around a stage, so each has
to turn to a different heading once it gets there. A hybrid unicycle
pose controller (create_hybrid_unicycle_pose_controller) first drives each robot to its goal
position and then turns it on the spot to the goal heading; a unicycle barrier certificate with
the arena boundary keeps the robots apart and inside the arena.

Success: every robot ends within 0.05 m and 0.2 rad of its goal pose (at_pose), with no
collisions, no boundary violations and no actuator-limit warnings in the debug report. The
script stops as soon as all robots are there (about 550 iterations; 1000 at most) and prints
a final line such as "goal reached: all 5 robots within 0.05 m and 0.2 rad of their goal poses".

Run:  ./robotarium run examples/go_to_pose.py
"""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import *
from rps.utilities.controllers import *
from rps.utilities.misc import *
from rps.utilities.transformations import *

N = 5                    # number of robots
SHOW_FIGURE = True       # False: no window (r.axes is then unavailable)
POSITION_ERROR = 0.05    # m
ROTATION_ERROR = 0.2     # rad
MAX_ITERATIONS = 1000    # 0.033 s each: about 33 s at most

# Start: a column on the left, everyone facing right (x; y; heading).
initial_conditions = np.array([[-1.2, -1.2, -1.2, -1.2, -1.2],
                               [-0.6, -0.3,  0.0,  0.3,  0.6],
                               [ 0.0,  0.0,  0.0,  0.0,  0.0]])

# Goals: an arc of radius 0.8 around the point (0.3, 0), 0.5 m apart, each robot facing that
# point. Robot 0 (bottom of the column) goes to the bottom of the arc, robot 4 to the top.
centre = np.array([0.3, 0.0])
angles = np.radians([-75, -37.5, 0, 37.5, 75])
goal_poses = np.array([centre[0] + 0.8 * np.cos(angles),
                       centre[1] + 0.8 * np.sin(angles),
                       angles + np.pi])
goal_poses[2, :] = np.arctan2(np.sin(goal_poses[2, :]), np.cos(goal_poses[2, :]))  # to (-pi, pi]


def within_wheel_limits(dxu, wheel_radius=0.016, base_length=0.105, max_wheel_speed=12.5):
    """Scale each robot's (v, w) down, keeping its turning radius, so neither wheel of the
    GTernal turns faster than max_wheel_speed rad/s (with a 5% margin)."""
    rim_speed = np.abs(dxu[0, :]) + base_length / 2 * np.abs(dxu[1, :])  # fastest wheel, m/s
    limit = 0.95 * max_wheel_speed * wheel_radius
    return dxu * np.minimum(1.0, limit / np.maximum(rim_speed, 1e-9))


r = robotarium.Robotarium(number_of_robots=N, show_figure=SHOW_FIGURE,
                          initial_conditions=initial_conditions, sim_in_real_time=True)

unicycle_pose_controller = create_hybrid_unicycle_pose_controller()
uni_barrier_cert = create_unicycle_barrier_certificate_with_boundary()

# Draw each goal pose as an arrow.
if SHOW_FIGURE:
    for i in range(N):
        r.axes.arrow(goal_poses[0, i], goal_poses[1, i],
                     0.12 * np.cos(goal_poses[2, i]), 0.12 * np.sin(goal_poses[2, i]),
                     width=0.01, length_includes_head=True, color='g', zorder=-1)

for iteration in range(MAX_ITERATIONS):
    x = r.get_poses()

    done = at_pose(x, goal_poses, position_error=POSITION_ERROR, rotation_error=ROTATION_ERROR)
    if np.size(done) == N:
        break

    dxu = unicycle_pose_controller(x, goal_poses)   # drive to the position, then turn
    dxu = uni_barrier_cert(dxu, x)                  # made safe
    r.set_velocities(np.arange(N), within_wheel_limits(dxu))
    r.step()

r.call_at_scripts_end()

if np.size(done) == N:
    print("goal reached: all %d robots within %.2f m and %.1f rad of their goal poses (%d iterations)"
          % (N, POSITION_ERROR, ROTATION_ERROR, iteration))
else:
    print("goal NOT reached: %d of %d robots at their goal poses after %d iterations"
          % (np.size(done), N, MAX_ITERATIONS))
