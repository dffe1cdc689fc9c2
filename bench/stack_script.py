"""The N = 20 experiment both sides of bench_stack.py run: the guide's single-integrator
go-to-point loop with a barrier certificate (guide §3.5.1), timed from inside the script.

It runs unchanged on the Robotarium simulator and through this stack; it prints one line,
`STEPS_PER_SECOND <value>`, measured over the control loop only (not start-up).
"""
import sys
import time

import numpy as np

import rps.robotarium as robotarium
from rps.utilities.barrier_certificates import create_single_integrator_barrier_certificate_with_boundary
from rps.utilities.controllers import create_si_position_controller
from rps.utilities.misc import generate_initial_conditions
from rps.utilities.transformations import create_si_to_uni_dynamics_with_backwards_motion

N = 20
ITERATIONS = int(sys.argv[1]) if len(sys.argv) > 1 else 300

np.random.seed(3)
initial_conditions = generate_initial_conditions(N, spacing=0.3, width=2.7, height=1.5)
goals = generate_initial_conditions(N, spacing=0.3, width=2.7, height=1.5)[:2]
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=False)
si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary()
si_position_controller = create_si_position_controller()
si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion()

start = time.perf_counter()
for _ in range(ITERATIONS):
    x = r.get_poses()
    dxi = si_position_controller(x[:2, :], goals)
    dxi = si_barrier_cert(dxi, x[:2, :])
    r.set_velocities(np.arange(N), si_to_uni_dyn(dxi, x))
    r.step()
elapsed = time.perf_counter() - start
print("STEPS_PER_SECOND %.1f" % (ITERATIONS / elapsed))
r.call_at_scripts_end()
