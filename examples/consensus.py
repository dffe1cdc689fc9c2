"""Consensus: eight robots spread over the arena gather in one place by talking only to neighbours (guide 3.7).

The robots are linked in a ring (a cycle graph, cycle_GL): robot i sees only robots i-1 and
i+1. Each moves towards the average of its two neighbours (the consensus protocol: the sum of
the differences), and nobody knows where the group as a whole is, yet they all head for the
same spot, close to the average of where they started (marked with a green x). They cannot all
stand on one point: the single-integrator barrier certificate with the arena boundary keeps
them at least 0.17 m apart, so they settle into a tight cluster around it.

Success: all robots within 0.45 m of the group's centroid (they start up to 1.5 m from it),
with no collisions, no boundary violations and no actuator-limit warnings in the debug report.
The script stops as soon as the group has gathered (about 300 iterations; 1000 at most) and
prints a final line such as "goal reached: all 8 robots within 0.45 m of their centroid".

Run:  ./robotarium run examples/consensus.py
"""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import *
from rps.utilities.controllers import *
from rps.utilities.graph import *
from rps.utilities.misc import *
from rps.utilities.transformations import *

N = 8
SHOW_FIGURE = True        # False: no window (r.axes is then unavailable)
GATHERED = 0.45           # m: largest distance from the centroid that counts as gathered
MAX_ITERATIONS = 1000     # 0.033 s each: about 33 s at most

# Spread over the arena (x; y; heading). Ring order: robot i's neighbours are i-1 and i+1.
initial_conditions = np.array([[-1.3, -0.5, 0.4, 1.3, 1.2, 0.3, -0.6, -1.2],
                               [0.7, 0.8, 0.6, 0.7, -0.6, -0.8, -0.6, -0.2],
                               [0.0, 1.0, 2.0, 3.0, -2.0, -1.0, 0.5, 1.5]])

L = cycle_GL(N)   # graph Laplacian of the ring


def within_wheel_limits(dxu, wheel_radius=0.016, base_length=0.105, max_wheel_speed=12.5):
    """Scale each robot's (v, w) down, keeping its turning radius, so neither wheel of the
    GTernal turns faster than max_wheel_speed rad/s (with a 5% margin)."""
    rim_speed = np.abs(dxu[0, :]) + base_length / 2 * np.abs(dxu[1, :])  # fastest wheel, m/s
    limit = 0.95 * max_wheel_speed * wheel_radius
    return dxu * np.minimum(1.0, limit / np.maximum(rim_speed, 1e-9))


r = robotarium.Robotarium(number_of_robots=N, show_figure=SHOW_FIGURE,
                          initial_conditions=initial_conditions, sim_in_real_time=True)

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary()
si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion()

# Mark the average of the starting positions: where consensus should bring the group.
if SHOW_FIGURE:
    start_mean = initial_conditions[:2, :].mean(axis=1)
    r.axes.scatter(start_mean[0], start_mean[1], s=determine_marker_size(r, 0.1),
                   marker='x', color='g', zorder=-1)

for iteration in range(MAX_ITERATIONS):
    x = r.get_poses()

    spread = np.linalg.norm(x[:2, :] - x[:2, :].mean(axis=1, keepdims=True), axis=0)
    if np.all(spread < GATHERED):
        break

    dxi = np.zeros((2, N))
    for i in range(N):
        neighbors = topological_neighbors(L, i)
        dxi[:, i] = np.sum(x[:2, neighbors] - x[:2, [i]], axis=1)   # consensus protocol

    dxi = si_barrier_cert(dxi, x[:2, :])
    dxu = si_to_uni_dyn(dxi, x)
    r.set_velocities(np.arange(N), within_wheel_limits(dxu))
    r.step()

r.call_at_scripts_end()

if np.all(spread < GATHERED):
    print("goal reached: all %d robots within %.2f m of their centroid (%d iterations, farthest %.3f m)"
          % (N, GATHERED, iteration, spread.max()))
else:
    print("goal NOT reached: farthest robot %.3f m from the centroid after %d iterations"
          % (spread.max(), MAX_ITERATIONS))
