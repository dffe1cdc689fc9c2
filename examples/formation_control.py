"""Formation control: six robots scattered over the arena form a 2 x 3 rectangle (guide section 3.4).

Nobody is told where to go. Each robot only looks at its three neighbours in a graph (the
graph of the guide's example) and runs the guide's distance-based formation law: it moves
towards a neighbour that is farther than the desired distance and away from one that is
closer. The desired distances are those of a 2 x 3 grid with 0.3 m spacing, so the robots end
up in that rectangle, wherever and however it happens to be placed and turned. A single-
integrator barrier certificate with the arena boundary keeps them apart and inside the arena.

Success: all nine graph edges within 0.03 m of their desired length, with no collisions, no
boundary violations and no actuator-limit warnings in the debug report. The script stops as soon
as the rectangle is formed (about 250 iterations; 1000 at most) and prints a final line such as
"goal reached: rectangle formed, all 9 distances within 0.03 m".

Run:  ./robotarium run examples/formation_control.py
"""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import *
from rps.utilities.controllers import *
from rps.utilities.graph import *
from rps.utilities.misc import *
from rps.utilities.transformations import *

N = 6
SHOW_FIGURE = True        # False: no window (r.axes is then unavailable)
MAX_ITERATIONS = 1000     # 0.033 s each: about 33 s at most
TOLERANCE = 0.03          # m
FORMATION_GAIN = 10
SPEED_LIMIT = 0.15        # m/s

# The target shape: a 2 x 3 grid, 0.3 m apart (robot i's spot in column i % 3, row i // 3).
shape = np.array([[0.0, 0.3, 0.6, 0.0, 0.3, 0.6],
                  [0.0, 0.0, 0.0, 0.3, 0.3, 0.3]])

# Who sees whom: every robot has three neighbours (the graph Laplacian of the guide's example).
L = np.array([[ 3, -1,  0, -1,  0, -1],
              [-1,  3, -1,  0, -1,  0],
              [ 0, -1,  3, -1,  0, -1],
              [-1,  0, -1,  3, -1,  0],
              [ 0, -1,  0, -1,  3, -1],
              [-1,  0, -1,  0, -1,  3]])
edges = [(i, j) for i in range(N) for j in topological_neighbors(L, i) if i < j]

# Desired distance between neighbours: their distance in the target shape.
desired = np.zeros((N, N))
for i, j in edges:
    desired[i, j] = desired[j, i] = np.linalg.norm(shape[:, i] - shape[:, j])

# Scattered start (x; y; heading).
initial_conditions = np.array([[-1.2, -0.3, 0.9, -0.8, 0.4, 1.3],
                               [0.6, 0.7, 0.5, -0.6, -0.5, -0.7],
                               [0.0, -1.5, 3.0, 1.0, 2.0, -2.5]])


def within_wheel_limits(dxu, wheel_radius=0.016, base_length=0.105, max_wheel_speed=12.5):
    """Scale each robot's (v, w) down, keeping its turning radius, so neither wheel of the
    GTernal turns faster than max_wheel_speed rad/s (with a 5% margin)."""
    rim_speed = np.abs(dxu[0, :]) + base_length / 2 * np.abs(dxu[1, :])  # fastest wheel, m/s
    limit = 0.95 * max_wheel_speed * wheel_radius
    return dxu * np.minimum(1.0, limit / np.maximum(rim_speed, 1e-9))


def edge_errors(x):
    """|distance - desired distance| for every edge of the graph, in m."""
    return np.array([abs(np.linalg.norm(x[:2, i] - x[:2, j]) - desired[i, j]) for i, j in edges])


r = robotarium.Robotarium(number_of_robots=N, show_figure=SHOW_FIGURE,
                          initial_conditions=initial_conditions, sim_in_real_time=True)

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary()
si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion()

# Draw the graph's edges; they follow the robots.
if SHOW_FIGURE:
    x0 = initial_conditions
    edge_lines = [r.axes.plot(x0[0, [i, j]], x0[1, [i, j]], color='b', linewidth=2, zorder=-1)[0]
                  for i, j in edges]

for iteration in range(MAX_ITERATIONS):
    x = r.get_poses()

    errors = edge_errors(x)
    if np.all(errors < TOLERANCE):
        break

    if SHOW_FIGURE:
        for line, (i, j) in zip(edge_lines, edges):
            line.set_data(x[0, [i, j]], x[1, [i, j]])

    dxi = np.zeros((2, N))
    for i in range(N):
        for j in topological_neighbors(L, i):
            error = x[:2, j] - x[:2, i]
            dxi[:, i] += FORMATION_GAIN * (np.linalg.norm(error)**2 - desired[i, j]**2) * error

    norms = np.linalg.norm(dxi, axis=0)
    too_fast = norms > SPEED_LIMIT
    dxi[:, too_fast] *= SPEED_LIMIT / norms[too_fast]

    dxi = si_barrier_cert(dxi, x[:2, :])
    dxu = si_to_uni_dyn(dxi, x)
    r.set_velocities(np.arange(N), within_wheel_limits(dxu))
    r.step()

r.call_at_scripts_end()

if np.all(errors < TOLERANCE):
    print("goal reached: rectangle formed, all %d distances within %.2f m (%d iterations, largest error %.3f m)"
          % (len(edges), TOLERANCE, iteration, errors.max()))
else:
    print("goal NOT reached: largest distance error %.3f m after %d iterations" % (errors.max(), MAX_ITERATIONS))
