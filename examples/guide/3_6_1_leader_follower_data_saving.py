# Robotarium Python Guide section 3.6.1 "Leader-Follower Formation with Data Saving" (Listing 12: leader_follower_data_saving.py), copied as printed; writes goal_distance_data.npy/.txt and inter_robot_distance_data.npy/.txt to the current directory.
# Extraction repairs: removed interleaved line numbers; restored indentation (lines 73-74 belong to the if); stripped LaTeX/HTML residue ({\tt ...}, "\_", "\ ", "</pre>", "\%" -> "%", repeated comment garbage) from lines 45, 53, 72, 73; "savina" -> "saving" (line 18); Robotarium(...) line 45-46: dropped the stray ")" after "initial_conditions," and "sim in real time" -> "sim_in_real_time", "Robotariu" -> "Robotarium"; line 66 "for i in neighbors:" -> "for j in neighbors:" (i/j misread: the body uses j, which is otherwise undefined -> NameError); added the ")" lost at the end of wrapped line 74-75; restored line 86 "r.set_velocities(np.arange(N), dxu_safe)" that the extraction dropped (pseudo code step 34 "Set the velocities of the robots [86]"; comment taken from the same line in 3.3.1); joined wrapped lines 67 and 74-75.
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.graph import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np
import time

iterations = 5000 # Run the simulation/experiment for 5000 steps

N = 4 # Number of robots

waypoints = np.array([[-1, -1, 1, 1],[0.8, -0.8, -0.8, 0.8]]) # Waypoints the leader moves to.

close_enough = 0.03; # How close the leader must get to the waypoint to move to the next one.

# Preallocate data saving
robot_distance = np.zeros((5,iterations)) # Saving 4 inter-robot distances and time
goal_distance = np.empty((0,2))
start_time = time.time()

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

desired_distance = 0.3 # Desired distance between the Robots

initial_conditions = np.array([[0, 0.5, 0.3, -0.1],[0.5, 0.5, 0.2, 0],[0, 0, 0, 0]]) # Initial Positions

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, initial_conditions=initial_conditions, sim_in_real_time=True) # Instantiate the Robotarium

_, uni_to_si_states = create_si_to_uni_mapping() # Unicycle to Single Integrator States Mapping

si_to_uni_dyn = create_si_to_uni_dynamics() # Single Integrator to Unicycle Velocity Commands

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary() # Single-integrator barrier certificates

leader_controller = create_si_position_controller(velocity_magnitude_limit=0.1) # Single-integrator position controller

for t in range(iterations):

    x = r.get_poses() # Get the pose of robots

    xi = uni_to_si_states(x) # Transform poses to Single Integrator

    # Followers
    for i in range(1, N):
        dxi[:, [i]] = np.zeros((2, 1)) # Zero velocities
        neighbors = topological_neighbors(L, i) # Get the topological neighbors of agent i

        for j in neighbors:
            dxi[:, [i]] += formation_control_gain * (np.power(np.linalg.norm(x[:2, [j]] - x[:2, [i]]), 2) - np.power(desired_distance, 2)) * (x[:2, [j]] - x[:2, [i]])

    # Leader
    waypoint = waypoints[:, state].reshape((2, 1))

    dxi[:, [0]] = leader_controller(x[:2, [0]], waypoint)
    if np.linalg.norm(x[:2, [0]] - waypoint) < close_enough: # Leader moves to the waypoint and updates to the next one if
        state = (state + 1) % 4
        goal_distance = np.append(goal_distance, np.array([[np.linalg.norm(xi[:, [0]] - waypoint)], [time.time() - start_time]]))

    # Keep single integrator control vectors under specified magnitude
    norms = np.linalg.norm(dxi, 2, 0) # Threshold control inputs
    idxs_to_normalize = (norms > magnitude_limit) # Threshold control inputs
    dxi[:, idxs_to_normalize] *= magnitude_limit / norms[idxs_to_normalize] # Threshold control inputs

    dxi_safe = si_barrier_cert(dxi, x[:2, :]) # Use Barrier to avoid collision

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Convert single-integrator to unicycle commands

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities using unicycle commands

    # Compute data to be saved and stored in matrix (Distance between connected robots)
    robot_distance[0, t] = np.linalg.norm(xi[:, [0]] - xi[:, [1]])
    robot_distance[4, t] = time.time() - start_time
    for j in range(1, int(len(rows) / 2) + 1):
        robot_distance[j, t] = np.linalg.norm(xi[:, [rows[j]]] - xi[:, [cols[j]]])

    r.step() # Iterate the simulation

# Save Data Locally as Numpy
np.save('goal_distance_data', goal_distance)
np.save('inter_robot_distance_data', robot_distance)

# Save Data Locally as CSV Text File
np.savetxt('goal_distance_data.txt', goal_distance, delimiter=',')
np.savetxt('inter_robot_distance_data.txt', robot_distance.T, delimiter=',')

# Call at end of script to print debug information
r.call_at_scripts_end()
