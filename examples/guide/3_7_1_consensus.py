# Robotarium Python Guide section 3.7.1 "Consensus Algorithm for Multiple Robots" (Listing 13: consensus.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; stripped LaTeX escapes ("\_" -> "_", "\#" -> "#") from line 33.
import rps.robotarium as robotarium
from rps.utilities.graph import *
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np

N = 12 # Number of robots

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, sim_in_real_time=True) # Instantiate Robotarium object

iterations = 1000 # Run the simulation/experiment for 1000 steps

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary() # Single-integrator barrier certificates

si_to_uni_dyn, uni_to_si_states = create_si_to_uni_mapping() # Create SI to UNI dynamics tranformation

L = cycle_GL(N) # Generated a connected graph Laplacian (for a cylce graph).

for k in range(iterations):

    x = r.get_poses() # Get the poses of the robots

    x_si = uni_to_si_states(x) # Convert to single-integrator poses

    si_velocities = np.zeros((2, N)) # Initialize the single-integrator control inputs

    for i in range(N): # For each robot...

        j = topological_neighbors(L, i) # Get the neighbors of robot 'i' (encoded in the graph Laplacian)

        si_velocities[:, i] = np.sum(x_si[:, j] - x_si[:, i, None], 1) # Compute the consensus algorithm

    si_velocities_safe = si_barrier_cert(si_velocities, x_si) # Use the barrier certificate to avoid collisions

    dxu_safe = si_to_uni_dyn(si_velocities_safe, x) # Transform single integrator to unicycle

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of agents 1,...,N to dxu_safe

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
