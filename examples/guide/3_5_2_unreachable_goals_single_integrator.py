# Robotarium Python Guide section 3.5.2 "Robots Moving Towards Unreachable Goals with Single-Integrator Model" (Listing 10: si_barriers_with_boundary.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; the wrapped second half of the Robotarium(...) call (line 13) was lost and is restored as "sim_in_real_time=True) # Instantiate Robotarium object" (as upstream si_barriers_with_boundary.py); restored the word "collision" wrapped off the comment of line 22.
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np

N = 5 # Number of Robots

initial_conditions = np.array(np.mat('1 0.5 -0.5 0 0.28; 0.8 -0.3 -0.75 0.1 0.34; 0 0 0 0 0')) # Initial positions

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, initial_conditions=initial_conditions, sim_in_real_time=True) # Instantiate Robotarium object

iterations = 3000 # Run the simulation/experiment for 3000 steps

goal_points = np.array(np.mat('5 -5 5 -5 5; 5 5 -5 -5 5; 0 0 0 0 0')) # Goal points

si_position_controller = create_si_position_controller() # Create single integrator position controller

si_to_uni_dyn, uni_to_si_states = create_si_to_uni_mapping() # Create SI to UNI dynamics transformation

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary() # Create barrier certificates to avoid collision

x = r.get_poses() # Get the poses of robots

r.step() # Iterate the simulation

# While the Robots are not in the goal points
for i in range(iterations):

    x = r.get_poses() # Get the poses of robots

    xi = uni_to_si_states(x) # Transform unicycle states to single integrator

    dxi = si_position_controller(xi, goal_points[:2, :]) # Create single-integrator control inputs

    dxi_safe = si_barrier_cert(dxi, xi) # Create safe control inputs (i.e., no collisions)

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Map the single integrator back to unicycle dynamics

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of agents 1,...,N to dxu_safe

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
