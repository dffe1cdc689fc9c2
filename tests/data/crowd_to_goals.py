"""50 robots drive to goals packed 0.2 m apart with the guide's single-integrator barrier
certificate with boundary in the script: the scene of issue 16, where the testbed's safety node
alone must keep robots from colliding: the script's own certificate keeps the points 5 cm ahead
of the robots 0.17 m apart, which lets two robots backing towards each other touch.

Start poses: the Robotarium's own draw (generate_initial_conditions(N, spacing=0.2, width=2.5,
height=1.5) from numpy's global generator); goals: a second draw of the same kind. The loop is
the guide's §3.5.1 (single integrator at the point ahead, create_si_to_uni_mapping). Seed numpy
from outside for a reproducible run:

    ./robotarium run --lockstep devtools/run_seeded.py SEED tests/data/crowd_to_goals.py [ITERATIONS]

Stops when every robot is within GOAL_TOLERANCE of its goal, or after ITERATIONS (default 300, as in the issue),
and prints one line: `crowd: N robots, I iterations, finished|not finished, goal error max E m, mean M m
(at the start: ...)`. It seldom finishes: robots deadlock in the packed crowd under the script's
certificate (on the Robotarium's simulator too).
"""
import sys

import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import create_single_integrator_barrier_certificate_with_boundary
from rps.utilities.controllers import create_si_position_controller
from rps.utilities.misc import generate_initial_conditions
from rps.utilities.transformations import create_si_to_uni_mapping

N = 50
GOAL_TOLERANCE = 0.05     # m
ITERATIONS = int(sys.argv[1]) if len(sys.argv) > 1 else 300    # 0.033 s each

r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=False)
goals = generate_initial_conditions(N, spacing=0.2, width=2.5, height=1.5)[:2]
si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary()
si_position_controller = create_si_position_controller()
si_to_uni_dyn, uni_to_si_states = create_si_to_uni_mapping()

finished = False
for iteration in range(ITERATIONS + 1):
    x = r.get_poses()
    x_si = uni_to_si_states(x)
    errors = np.linalg.norm(x_si - goals, axis=0)
    if iteration == 0:
        start_errors = errors
    if np.all(errors < GOAL_TOLERANCE):
        finished = True
        break
    if iteration == ITERATIONS:
        break
    dxi = si_position_controller(x_si, goals)
    dxi = si_barrier_cert(dxi, x_si)
    r.set_velocities(np.arange(N), si_to_uni_dyn(dxi, x))
    r.step()

r.call_at_scripts_end()
print("crowd: %d robots, %d iterations, %s, goal error max %.3f m, mean %.3f m (at the start: max %.3f m, mean %.3f m)"
      % (N, iteration, "finished" if finished else "not finished", errors.max(), errors.mean(), start_errors.max(),
         start_errors.mean()))
