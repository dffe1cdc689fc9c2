"""Leader-follower: one robot leads a lap of four waypoints, three followers keep formation (guide 3.3).

Robot 0 is the leader: a single-integrator position controller drives it from waypoint to
waypoint around a 1.2 m x 0.8 m rectangle. Robots 1-3 are followers: they see each other
(a triangle) and robot 1 also sees the leader. Each follower runs the formation-control law
of the guide, which pulls a pair of neighbours together when they are farther apart than
0.3 m and pushes them apart when closer. A single-integrator barrier certificate with the arena
boundary keeps everyone apart and inside the arena.

Success: the leader gets within 0.05 m of all four waypoints in turn (one lap) and, parked at the
last one, the formation settles with every linked pair of robots within 0.05 m of the 0.3 m
formation distance, with no collisions, no boundary violations and no actuator-limit warnings in
the debug report. The script stops then (about 900 iterations; 1500 at most) and prints a final line
such as "goal reached: leader visited all 4 waypoints, formation distances within 0.05 m of 0.30 m".

Run:  ./robotarium run examples/leader_follower.py
"""
import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import *
from rps.utilities.controllers import *
from rps.utilities.graph import *
from rps.utilities.misc import *
from rps.utilities.transformations import *

N = 4                          # robot 0 leads, robots 1-3 follow
SHOW_FIGURE = True             # False: no window (r.axes is then unavailable)
MAX_ITERATIONS = 1500          # 0.033 s each: about 50 s at most
CLOSE_ENOUGH = 0.05            # m: the leader has reached a waypoint
DESIRED_DISTANCE = 0.3         # m: between linked robots
FORMATION_TOLERANCE = 0.05     # m
FORMATION_GAIN = 10
FOLLOWER_SPEED_LIMIT = 0.2     # m/s: followers must be faster than the leader to keep up
LEADER_SPEED_LIMIT = 0.15      # m/s

# The lap: the corners of a rectangle, counter-clockwise from the bottom right.
waypoints = np.array([[0.6, 0.6, -0.6, -0.6],
                      [-0.4, 0.4, 0.4, -0.4]])

# Graph Laplacian: followers 1-3 form a triangle, follower 1 also sees the leader.
L = np.zeros((N, N))
L[1:N, 1:N] = -completeGL(N - 1)
L[1, 1] += 1
L[1, 0] = -1
links = [(0, 1), (1, 2), (1, 3), (2, 3)]      # the pairs that keep DESIRED_DISTANCE

# Start near the first corner in roughly the right shape, all facing right.
initial_conditions = np.array([[-0.6, -0.9, -1.1, -1.2],
                               [-0.4, -0.4, -0.2, -0.6],
                               [0.0, 0.0, 0.0, 0.0]])


def within_wheel_limits(dxu, wheel_radius=0.016, base_length=0.105, max_wheel_speed=12.5):
    """Scale each robot's (v, w) down, keeping its turning radius, so neither wheel of the
    GTernal turns faster than max_wheel_speed rad/s (with a 5% margin)."""
    rim_speed = np.abs(dxu[0, :]) + base_length / 2 * np.abs(dxu[1, :])  # fastest wheel, m/s
    limit = 0.95 * max_wheel_speed * wheel_radius
    return dxu * np.minimum(1.0, limit / np.maximum(rim_speed, 1e-9))


def link_errors(x):
    """|distance - DESIRED_DISTANCE| for every linked pair, in m."""
    return np.array([abs(np.linalg.norm(x[:2, i] - x[:2, j]) - DESIRED_DISTANCE) for i, j in links])


r = robotarium.Robotarium(number_of_robots=N, show_figure=SHOW_FIGURE,
                          initial_conditions=initial_conditions, sim_in_real_time=True)

si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion()
si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary()
leader_controller = create_si_position_controller(velocity_magnitude_limit=LEADER_SPEED_LIMIT)

if SHOW_FIGURE:
    font_size = determine_font_size(r, 0.08)
    for k in range(waypoints.shape[1]):
        r.axes.text(waypoints[0, k], waypoints[1, k], 'W%d' % k, fontsize=font_size, color='g',
                    horizontalalignment='center', verticalalignment='center', zorder=-1)

waypoint = 0          # the waypoint the leader is heading for
lap_done = False
for iteration in range(MAX_ITERATIONS):
    x = r.get_poses()

    # Leader: on to the next waypoint once close enough to this one. After the lap (four
    # waypoints) it parks at the last one and we stop as soon as the formation has settled.
    if not lap_done and np.linalg.norm(x[:2, 0] - waypoints[:, waypoint]) < CLOSE_ENOUGH:
        if waypoint == waypoints.shape[1] - 1:
            lap_done = True
        else:
            waypoint += 1
    if lap_done and np.all(link_errors(x) < FORMATION_TOLERANCE):
        break

    dxi = np.zeros((2, N))
    dxi[:, [0]] = leader_controller(x[:2, [0]], waypoints[:, [waypoint]])

    # Followers: formation control with each neighbour in the graph.
    for i in range(1, N):
        for j in topological_neighbors(L, i):
            error = x[:2, j] - x[:2, i]
            dxi[:, i] += FORMATION_GAIN * (np.linalg.norm(error)**2 - DESIRED_DISTANCE**2) * error

    # Keep the followers' speed under the limit.
    norms = np.linalg.norm(dxi[:, 1:], axis=0)
    too_fast = norms > FOLLOWER_SPEED_LIMIT
    dxi[:, 1:][:, too_fast] *= FOLLOWER_SPEED_LIMIT / norms[too_fast]

    dxi = si_barrier_cert(dxi, x[:2, :])
    dxu = si_to_uni_dyn(dxi, x)
    r.set_velocities(np.arange(N), within_wheel_limits(dxu))
    r.step()

r.call_at_scripts_end()

errors = link_errors(x)
if lap_done and np.all(errors < FORMATION_TOLERANCE):
    print("goal reached: leader visited all %d waypoints, formation distances within %.2f m of %.2f m "
          "(%d iterations, largest error %.3f m)"
          % (waypoints.shape[1], FORMATION_TOLERANCE, DESIRED_DISTANCE, iteration, errors.max()))
else:
    print("goal NOT reached: leader visited %d of %d waypoints, largest formation error %.3f m after %d iterations"
          % (waypoint + lap_done, waypoints.shape[1], errors.max(), iteration + 1))
