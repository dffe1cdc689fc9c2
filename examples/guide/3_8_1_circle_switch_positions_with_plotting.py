# Robotarium Python Guide section 3.8.1 "Robots Form a Circle and Switch Positions with Plotting" (Listing 14: barrier_certificates_with_plotting.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; joined wrapped lines/comments (11, 21, 23, 27, 29, 39, 57, 89); line 27 scatter call de-garbled (LaTeX \label residue and a duplicated "s=...,marker=..." fragment removed); line 29 (a commented-out alternative) de-garbled the same way; "x_si_x_goal" -> "x_si, x_goal" (line 77, lost comma); stripped LaTeX residue (\mathtt, {\tt ...}, \verb|...|, \textit, "\_", "\#", repeated comment garbage) from lines 77, 79, 83, 87, 93.
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np
import time

N = 10 # Number of robots

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, sim_in_real_time=True) # Instantiate the Robotarium object with these parameters

num_cycles=2 # How many times should the robots form the circle?

count = -1 # How many times have they formed the circle? (starts at -1 since initial formation will increment the count)

safety_radius = 0.17 # Default Barrier Parameters

# Plotting Parameters
CM = np.random.rand(N,3) # Random Colors array for plotting
safety_radius_marker_size = determine_marker_size(r,safety_radius) # Will scale the plotted markers to be the diameter of provided argument (in meters)
font_height_meters = 0.1
font_height_points = determine_font_size(r,font_height_meters) # Will scale the plotted font height to that of the provided argument (in meters)

x=r.get_poses() # Get the poses of robots

g = r.axes.scatter(x[0,:], x[1,:], s=np.pi/4*safety_radius_marker_size, marker='o', facecolors='none', edgecolors=CM, linewidth=7) # Initial plots

#g = r.axes.plot(x[0,:], x[1,:], markersize=safety_radius_marker_size, linestyle='none', marker='o', markerfacecolor='none', markeredgecolor=color[CM], linewidth=7)

r.step() # Iterate the Simulation

si_barrier_cert = create_single_integrator_barrier_certificate() # Single-integrator barrier certificates

si_position_controller = create_si_position_controller() # Create single integrator position controller

si_to_uni_dyn, uni_to_si_states = create_si_to_uni_mapping() # Create SI to UNI dynamics tranformation

# This portion of the code generates points on a circle enscribed in a 6x6 square that's centered on the origin. The robots switch positions on the circle.
xybound = np.array([-1.2, 1.2, -1, 1])
p_theta = 2*np.pi*(np.arange(0, 2*N, 2)/(2*N))
p_circ = np.vstack([
            np.hstack([xybound[1]*np.cos(p_theta), xybound[1]*np.cos(p_theta+np.pi)]),
            np.hstack([xybound[3]*np.sin(p_theta), xybound[3]*np.sin(p_theta+np.pi)])
            ])

# These variables are so we can tell when the robots should switch positions on the circle.
flag = 0
x_goal = p_circ[:, :N]

while(1): # While True

    x = r.get_poses() # Get the poses of the robots

    # Update Plotted Visualization
    g.set_offsets(x[:2,:].T)
    # This updates the marker sizes if the figure window size is changed. This should be removed when submitting to the Robotarium.
    g.set_sizes([determine_marker_size(r,safety_radius)])

    x_si = uni_to_si_states(x) # Single-integrator to unciycle mapping

    si_velocities = np.zeros((2, N)) # Initialize a velocities variable

    if(np.linalg.norm(x_goal - x_si) < 0.05): # Check if all the agents are close enough to the goals
        flag = 1-flag
        count += 1

    if count == num_cycles: # If True, end simulation
        break

    # Switch goals depending on the state of flag (goals switch to opposite sides of the circle)
    if(flag == 0):
        x_goal = p_circ[:, :N]
    else:
        x_goal = p_circ[:, N:]

    dxi = si_position_controller(x_si, x_goal) # Use a position controller to drive to the goal position

    dxi_safe = si_barrier_cert(dxi, x_si) # Use the barrier certificates to make sure that the agents don't collide

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Single-integrator-to-unicycle mapping

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of agents 1,...,N to dxu_safe

    r.step() # Iterate the simulation

# Caption before finishing the simulation
finished_caption = "All robots safely reached \n their destination"
finished_label = r.axes.text(0,0,finished_caption,fontsize=font_height_points, color='k',fontweight='bold',horizontalalignment='center',verticalalignment='center',zorder=20)
r.step()
time.sleep(5)
r.call_at_scripts_end() # Call at end of script to print debug information
