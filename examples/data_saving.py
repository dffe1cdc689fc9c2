"""Data saving: record every pose and every command of a go-to-point run to a file (guide section 3.6).

Five robots start at random spots (numpy's random generator is seeded, so every run is the same)
and drive to five random goals with a single-integrator controller and the barrier certificate
with the arena boundary. Each iteration the script appends the robots' poses and the (v, w)
commands it sent to two lists; at the end it saves them, with the goals and the time step, to
data_saving.npz in the current directory. On the Robotarium, files your script writes come back
with the experiment's results. Read them back with

    data = np.load('data_saving.npz')
    data['poses'].shape    # (iterations, 3, N): x, y, heading of every robot at every iteration
    data['inputs'].shape   # (iterations, 2, N): v (m/s) and w (rad/s) sent at every iteration

Success: every robot ends within 0.05 m of its goal, with no collisions, no boundary violations
and no actuator-limit warnings in the debug report, and the file holds one pose and one command
per iteration. The script stops as soon as all robots are there (about 350 iterations; 1000 at
most) and prints a final line such as "goal reached: all 5 robots within 0.05 m".

Run:  ./robotarium run examples/data_saving.py
"""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import *
from rps.utilities.controllers import *
from rps.utilities.misc import *
from rps.utilities.transformations import *

N = 5
SHOW_FIGURE = True        # False: no window (r.axes is then unavailable)
GOAL_TOLERANCE = 0.05     # m
MAX_ITERATIONS = 1000     # 0.033 s each: about 33 s at most
TIME_STEP = 0.033         # s: one Robotarium iteration
DATA_FILE = 'data_saving.npz'

# Random but reproducible: the same seed gives the same starts and goals every run.
np.random.seed(3)
initial_conditions = generate_initial_conditions(N, spacing=0.5, width=2.6, height=1.5)
goal_points = generate_initial_conditions(N, spacing=0.5, width=2.6, height=1.5)[:2, :]


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

pose_log = []      # one 3 x N array per iteration
input_log = []     # one 2 x N array per iteration

for iteration in range(MAX_ITERATIONS):
    x = r.get_poses()

    distances = np.linalg.norm(x[:2, :] - goal_points, axis=0)
    if np.all(distances < GOAL_TOLERANCE):
        break

    dxi = si_position_controller(x[:2, :], goal_points)
    dxi = si_barrier_cert(dxi, x[:2, :])
    dxu = within_wheel_limits(si_to_uni_dyn(dxi, x))
    r.set_velocities(np.arange(N), dxu)

    pose_log.append(x.copy())      # copy: get_poses may hand back the same array every time
    input_log.append(dxu.copy())

    r.step()

np.savez(DATA_FILE, poses=np.array(pose_log), inputs=np.array(input_log),
         goals=goal_points, time_step=TIME_STEP)
print("saved %d iterations of poses and inputs to %s" % (len(pose_log), DATA_FILE))

r.call_at_scripts_end()

if np.all(distances < GOAL_TOLERANCE):
    print("goal reached: all %d robots within %.2f m (%d iterations, largest error %.3f m)"
          % (N, GOAL_TOLERANCE, iteration, distances.max()))
else:
    print("goal NOT reached: %d of %d robots within %.2f m after %d iterations"
          % (np.sum(distances < GOAL_TOLERANCE), N, GOAL_TOLERANCE, MAX_ITERATIONS))
