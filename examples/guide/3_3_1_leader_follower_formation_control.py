# Robotarium Python Guide section 3.3.1 "Leader-Follower Formation Control" (Listing 7: leader_follower.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; stripped LaTeX residue ("\#", "\_", {\tt ...}, \verb|...|, \textit{...}, repeated comment garbage) from lines 11, 45, 47, 58, 77, 79; joined wrapped lines 39 and 61; restored line 59 "for j in neighbors:" that the extraction dropped (the body on line 61 uses j; pseudo code step 21 "for each neighbor j of robot i").
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.graph import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np

iterations = 5000 # Run the simulation/experiment for 5000 steps

N = 4 # Number of robots

waypoints = np.array([[-1, -1, 1, 1],[0.8, -0.8, -0.8, 0.8]]) # Waypoints the leader moves to.

close_enough = 0.03; # How close the leader must get to the waypoint to move to the next one.

# Create the desired Laplacian
followers = -completeGL(N-1)
L = np.zeros((N,N))
L[1:N,1:N] = followers
L[1,1] = L[1,1] + 1
L[1,0] = -1

# Find connections
[rows,cols] = np.where(L==1)

dxi = np.zeros((2,N)) # For computational/memory reasons, initialize the velocity vector

state = 0 # Initialize leader state

magnitude_limit = 0.15 # Limit maximum linear speed of any robot

formation_control_gain = 10 # Gains for the Formation Control

desired_distance = 0.3 # desired distance between the Robots

initial_conditions = np.array([[0, 0.5, 0.3, -0.1],[0.5, 0.5, 0.2, 0],[0, 0, 0, 0]]) # Initial Positions

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, initial_conditions=initial_conditions, sim_in_real_time=True) # Instantiate the Robotarium

_, uni_to_si_states = create_si_to_uni_mapping() # Unicycle to Single Integrator States Mapping

si_to_uni_dyn = create_si_to_uni_dynamics() # Single Integrator to Unicycle Velocity Commands

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary() # Single_integrator barrier certificates

leader_controller = create_si_position_controller(velocity_magnitude_limit=0.1) # Single-integrator position controller

for t in range(iterations):

    x = r.get_poses() # Get the poses of robots

    xi = uni_to_si_states(x) # Transform poses to Single Integrator

    # Followers
    for i in range(1,N):
        dxi[:,[i]] = np.zeros((2,1)) # Zero velocities
        neighbors = topological_neighbors(L,i) # Get the topological neighbors of agent i

        for j in neighbors:
            dxi[:,[i]] += formation_control_gain*(np.power(np.linalg.norm(x[:2,[j]]-x[:2,[i]]), 2)-np.power(desired_distance, 2))*(x[:2,[j]]-x[:2,[i]])

    # Leader
    waypoint = waypoints[:,state].reshape((2,1))

    dxi[:,[0]] = leader_controller(x[:2,[0]], waypoint)
    if np.linalg.norm(x[:2,[0]] - waypoint) < close_enough: # Leader moves to the waypoint and updates to the next one if
        state = (state + 1) % 4

    # Keep single integrator control vectors under specified magnitude
    norms = np.linalg.norm(dxi, 2, 0)  # Threshold control inputs
    idxs_to_normalize = (norms > magnitude_limit)  # Threshold control inputs
    dxi[:, idxs_to_normalize] *= magnitude_limit/norms[idxs_to_normalize]  # Threshold control inputs

    dxi_safe = si_barrier_cert(dxi, x[:2,:]) # Use Barrier to avoid collision

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Convert single-integrator to unicycle commands

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities using unicycle commands

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
