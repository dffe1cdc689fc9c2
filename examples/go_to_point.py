"""Go to point: six robots drive to six goal points without colliding (guide section 3.1).

Two ways to drive a differential-drive robot to a point:

* single integrator (the default): plan a velocity for each robot as if it could move in any
  direction (create_si_position_controller), make it safe with a single-integrator barrier
  certificate that also keeps robots inside the arena, then turn it into a forward speed and a
  turning rate (create_si_to_uni_dynamics_with_backwards_motion);
* unicycle (run with the argument `unicycle`): a unicycle position controller gives the forward
  speed and turning rate directly, and a unicycle barrier certificate makes them safe.

The robots start on a hexagon and each drives to the spot two places around it, so their paths
cross and the barrier certificate has to make them give way to each other.

Success: every robot ends within 0.05 m of its goal, with no collisions, no boundary violations
and no actuator-limit warnings in the debug report. The script stops as soon as all robots are
there (about 400 iterations; 1000 at most) and prints a final line such as
"goal reached: all 6 robots within 0.05 m".

Run:  ./robotarium run examples/go_to_point.py            (single integrator)
      ./robotarium run examples/go_to_point.py unicycle   (unicycle)
"""
import sys

import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import *
from rps.utilities.controllers import *
from rps.utilities.misc import *
from rps.utilities.transformations import *

MODEL = sys.argv[1] if len(sys.argv) > 1 else "single_integrator"
assert MODEL in ("single_integrator", "unicycle"), "usage: go_to_point.py [single_integrator|unicycle]"

N = 6                    # number of robots
SHOW_FIGURE = True       # False: no window (r.axes is then unavailable)
GOAL_TOLERANCE = 0.05    # m: how close counts as "at the goal"
MAX_ITERATIONS = 1000    # 0.033 s each: about 33 s at most

# Six robots start on a hexagon, facing its centre; each drives to the spot two places around
# it (robot 0 goes to robot 2's spot, ...), so the six paths cross each other.
x0 = np.array([0.95, 0.0, -0.95, -0.95,  0.0,  0.95])
y0 = np.array([0.35, 0.7,  0.35, -0.35, -0.7, -0.35])
initial_conditions = np.array([x0, y0, np.arctan2(-y0, -x0)])
goal_points = np.array([np.roll(x0, -2), np.roll(y0, -2)])


def within_wheel_limits(dxu, wheel_radius=0.016, base_length=0.105, max_wheel_speed=12.5):
    """Scale each robot's (v, w) down, keeping its turning radius, so neither wheel of the
    GTernal turns faster than max_wheel_speed rad/s (with a 5% margin)."""
    rim_speed = np.abs(dxu[0, :]) + base_length / 2 * np.abs(dxu[1, :])  # fastest wheel, m/s
    limit = 0.95 * max_wheel_speed * wheel_radius
    return dxu * np.minimum(1.0, limit / np.maximum(rim_speed, 1e-9))


r = robotarium.Robotarium(number_of_robots=N, show_figure=SHOW_FIGURE,
                          initial_conditions=initial_conditions, sim_in_real_time=True)

if MODEL == "single_integrator":
    si_position_controller = create_si_position_controller()
    si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary()
    si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion()
else:
    unicycle_position_controller = create_clf_unicycle_position_controller()
    uni_barrier_cert = create_unicycle_barrier_certificate_with_boundary()

# Mark the goals on the figure.
if SHOW_FIGURE:
    r.axes.scatter(goal_points[0, :], goal_points[1, :], s=determine_marker_size(r, 0.1),
                   marker='x', color='g', zorder=-1)

for iteration in range(MAX_ITERATIONS):
    x = r.get_poses()

    distances = np.linalg.norm(x[:2, :] - goal_points, axis=0)
    if np.all(distances < GOAL_TOLERANCE):
        break

    if MODEL == "single_integrator":
        dxi = si_position_controller(x[:2, :], goal_points)   # desired velocities
        dxi = si_barrier_cert(dxi, x[:2, :])                  # made safe
        dxu = si_to_uni_dyn(dxi, x)                           # as (v, w) for each robot
    else:
        dxu = unicycle_position_controller(x, goal_points)
        dxu = uni_barrier_cert(dxu, x)

    r.set_velocities(np.arange(N), within_wheel_limits(dxu))
    r.step()

r.call_at_scripts_end()

if np.all(distances < GOAL_TOLERANCE):
    print("goal reached: all %d robots within %.2f m (%s model, %d iterations, largest error %.3f m)"
          % (N, GOAL_TOLERANCE, MODEL, iteration, distances.max()))
else:
    print("goal NOT reached: %d of %d robots within %.2f m after %d iterations"
          % (np.sum(distances < GOAL_TOLERANCE), N, GOAL_TOLERANCE, MAX_ITERATIONS))
