# Robotarium Python Guide section 3.8.4 "Robots go to a point using Single Integrator with Plotting" (Listing 17: si_go_to_point_with_plotting.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; joined wrapped lines (13, 15, 32, 33, 41, 43); lost underscores/dots restored ("robot marker size m", "line width", line 63 "robot markers[i] set sizes([determine marker size(r. robot marker size m)])"); "olor=" -> "color=" (line 41); stripped LaTeX residue ({\tt ...}, \label{eq:...}, "\_", "\ ", \textit) from lines 17, 51, 72; restored two dropped lines: line 31 "goal_marker_size_m = 0.2" (used on lines 32 and 66; value as in 3.8.5) and the robot_markers list on line 45 (only its "for ii in ..." tail survived; text as the identical line 43 of 3.8.5).
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np
import time

N = 5 # Number of Robots

initial_conditions = np.array(np.mat('1 0.5 -0.5 0 0.28; 0.8 -0.3 -0.75 0.1 0.34; 0 0 0 0 0')) # Initial Positions

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, initial_conditions=initial_conditions, sim_in_real_time=False) # Instantiate Robotarium

goal_points = generate_initial_conditions(N, width=r.boundaries[2]-2*r.robot_diameter, height = r.boundaries[3]-2*r.robot_diameter, spacing=0.5) # Define goal points by removing orientation from poses

single_integrator_position_controller = create_si_position_controller() # Single integrator position controller

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary() # Barrier certificates to avoid collision

_, uni_to_si_states = create_si_to_uni_mapping() # Unicycle to Single Integrator States Mapping

si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion() # Single Integrator to Unicycle Velocity Commands

x = r.get_poses() # Get poses of the Robots

x_si = uni_to_si_states(x) # Transform poses to Single Integrator

# Plotting Parameters
CM = np.random.rand(N,3) # Random Colors array for plotting
goal_marker_size_m = 0.2
robot_marker_size_m = 0.15
marker_size_goal = determine_marker_size(r,goal_marker_size_m) # Will scale the plotted markers to be the diameter of provided argument (in meters)
marker_size_robot = determine_marker_size(r, robot_marker_size_m) # Will scale the plotted markers to be the diameter of provided argument (in meters)
font_size = determine_font_size(r,0.1) # Will scale the plotted font height to that of the provided argument (in meters)
line_width = 5

# Create Goal Point Markers
# Text with goal identification
goal_caption = ['G{0}'.format(ii) for ii in range(goal_points.shape[1])]
#Plot text for caption
goal_points_text = [r.axes.text(goal_points[0,ii], goal_points[1,ii], goal_caption[ii], fontsize=font_size, color='k',fontweight='bold',horizontalalignment='center',verticalalignment='center',zorder=-2)
for ii in range(goal_points.shape[1])]
goal_markers = [r.axes.scatter(goal_points[0,ii], goal_points[1,ii], s=marker_size_goal, marker='s', facecolors='none',edgecolors=CM[ii,:],linewidth=line_width,zorder=-2)
for ii in range(goal_points.shape[1])]
robot_markers = [r.axes.scatter(x[0,ii], x[1,ii], s=marker_size_robot, marker='o', facecolors='none',edgecolors=CM[ii,:],linewidth=line_width)
for ii in range(goal_points.shape[1])]

r.step() # Iterate the simulation

# While all Robots are not in the goal points..
while (np.size(at_pose(np.vstack((x_si,x[2,:])), goal_points, rotation_error=100)) != N):

    x = r.get_poses() # Get poses of Robots

    x_si = uni_to_si_states(x) # Transform poses to Single Integrator

    # Update Plot
    # Update Robot Marker Plotted Visualization
    for i in range(x.shape[1]):
        robot_markers[i].set_offsets(x[:2,i].T)
        # This updates the marker sizes if the figure window size is changed.
        # This should be removed when submitting to the Robotarium.
        robot_markers[i].set_sizes([determine_marker_size(r, robot_marker_size_m)])

    for j in range(goal_points.shape[1]):
        goal_markers[j].set_sizes([determine_marker_size(r, goal_marker_size_m)])

    dxi = single_integrator_position_controller(x_si, goal_points[:2][:]) # Create single-integrator control inputs

    dxi_safe = si_barrier_cert(dxi, x_si) # Create safe control inputs (i.e., no collisions)

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Transform single integrator velocity commands to unicycle

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities using the Unicycle Commands

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
