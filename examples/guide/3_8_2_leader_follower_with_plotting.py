# Robotarium Python Guide section 3.8.2 "Leader-Follower Formation Control with Plotting" (Listing 15: leader_follower_with_plotting.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation (119 belongs to the if); joined wrapped lines (39, 51, 53, 61, 63, 76, 79, 81, 100, 112); stripped LaTeX residue ({\tt ...}, \label/\mbox, \verb, \textit, "\_", "\#", repeated comment garbage) from lines 45, 47, 50, 78, 130; lost underscores in "magnitude limit" (31) and "desired distance" (35); "follower text = np.emptv((3.0))" -> "follower_text = np.empty((3,0))" (line 70); restored line 94 "line_follower[q][0].set_data(...)" that the extraction dropped (text from the upstream leader_follower_with_plotting.py; pseudo code "Update plot handles [91-98]"); line 112 "np.linalg.norm(x[:2, [i]] - x[:2, [i]])" -> "x[:2, [j]] - x[:2, [i]]" (i/j misread as in 3.6.1; 3.3.1 and the rest of line 112 use j).
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

desired_distance = 0.3 # Desired distance between the Robots

initial_conditions = np.array([[0, 0.5, 0.3, -0.1],[0.5, 0.5, 0.2, 0],[0, 0, 0, 0]]) # Initial Positions

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, initial_conditions=initial_conditions, sim_in_real_time=True) # Instantiate the Robotarium

_, uni_to_si_states = create_si_to_uni_mapping() # Unicycle to Single Integrator States Mapping

si_to_uni_dyn = create_si_to_uni_dynamics() # Single Integrator to Unicycle Velocity Commands

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary() # Single-integrator barrier certificates

leader_controller = create_si_position_controller(velocity_magnitude_limit=0.1) # Single-integrator position controller

# Plotting Parameters
CM = np.random.rand(N,3) # Random Colors array for plotting
marker_size_goal = determine_marker_size(r,0.2) # Will scale the plotted markers to be the diameter of provided argument (in meters)
font_size_m = 0.1
font_size = determine_font_size(r,font_size_m) # Will scale the plotted font height to that of the provided argument (in meters)
line_width = 5

# Create goal text and markers
# Text with goal identification
goal_caption = ['G{0}'.format(ii) for ii in range(waypoints.shape[1])]
# Plot text for caption
waypoint_text = [r.axes.text(waypoints[0,ii], waypoints[1,ii], goal_caption[ii], fontsize=font_size, color='k', fontweight='bold', horizontalalignment='center', verticalalignment='center', zorder=-2)
for ii in range(waypoints.shape[1])]
g = [r.axes.scatter(waypoints[0,ii], waypoints[1,ii], s=marker_size_goal, marker='s', facecolors='none',edgecolors=CM[ii,:],linewidth=line_width,zorder=-2)
for ii in range(waypoints.shape[1])]

# Plot Graph Connections
x = r.get_poses() # Get the pose of robots

linked_follower_index = np.empty((2,3))
follower_text = np.empty((3,0))
for jj in range(1,int(len(rows)/2)+1):
        linked_follower_index[:,[jj-1]] = np.array([[rows[jj]],[cols[jj]]])
        follower_text = np.append(follower_text, '{0}'.format(jj))

line_follower = [r.axes.plot([x[0,rows[kk]], x[0,cols[kk]]],[x[1,rows[kk]], x[1,cols[kk]]],linewidth=line_width,color='b',zorder=-1)
 for kk in range(1,N)]
line_leader = r.axes.plot([x[0,0],x[0,1]],[x[1,0],x[1,1]],linewidth=line_width,color='r',zorder = -1)
follower_labels = [r.axes.text(x[0,kk],x[1,kk]+0.15,follower_text[kk-1],fontsize=font_size, color='b',fontweight='bold',horizontalalignment='center',verticalalignment='center',zorder=0)
for kk in range(1,N)]
leader_label = r.axes.text(x[0,0],x[1,0]+0.15,"Leader",fontsize=font_size, color='r',fontweight='bold',horizontalalignment='center',verticalalignment='center',zorder=0)

r.step() # Iterate the simulation

for t in range(iterations):

    x = r.get_poses() # Get the pose of robots

    xi = uni_to_si_states(x) # Transform poses to Single Integrator

    for q in range(N-1):
        follower_labels[q].set_position([xi[0,q+1], xi[1,q+1]+0.15])
        follower_labels[q].set_fontsize(determine_font_size(r, font_size_m))
        line_follower[q][0].set_data([x[0,rows[q+1]], x[0,cols[q+1]]], [x[1,rows[q+1]], x[1,cols[q+1]]])
    leader_label.set_position([xi[0,0], xi[1,0]+0.15])
    leader_label.set_fontsize(determine_font_size(r, font_size_m))
    line_leader[0].set_data([x[0,0], x[0,1]], [x[1,0], x[1,1]])

    # This updates the marker sizes if the figure window size is changed. This should be removed when submitting to the Robotarium.
    for q in range(waypoints.shape[1]):
        waypoint_text[q].set_fontsize(determine_font_size(r, font_size_m))
        g[q].set_sizes([determine_marker_size(r, 0.2)])

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

    # Keep single integrator control vectors under specified magnitude
    norms = np.linalg.norm(dxi, 2, 0) # Threshold control inputs
    idxs_to_normalize = (norms > magnitude_limit) # Threshold control inputs
    dxi[:, idxs_to_normalize] *= magnitude_limit / norms[idxs_to_normalize] # Threshold control inputs

    dxi_safe = si_barrier_cert(dxi, x[:2, :]) # Use Barrier to avoid collision

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Convert single-integrator to unicycle commands

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of agents 1,...,N to dxu_safe

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
