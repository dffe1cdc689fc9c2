# Robotarium Python Guide section 3.8.3 "Robots go to a point using Single Integrator and Unicycle Dynamics with background" (Listing 16: si_go_to_point_gt.py), copied as printed; reads GTLogo.png from the current directory (a stand-in GTLogo.png is kept next to this file: run from examples/guide/).
# Extraction repairs: removed interleaved line numbers; restored indentation; joined the wrapped Robotarium(...) line and "sim in real time" -> "sim_in_real_time" (line 13); stripped LaTeX residue ({\tt ...}, "\_", "\ ", \textit) from line 19.
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np
import time

N = 4 # Number of Robots

initial_conditions = np.array(np.mat('1 0.5 -0.5 0; 0.8 -0.3 -0.75 0.1; 0 0 0 0'))

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, initial_conditions=initial_conditions, sim_in_real_time=False) # Instantiate Robotarium

goal_points = 0.9*np.array([[-1, 1, -1, 1],[-1, -1, 1, 1],[0,0,0,0]]) # Goal Points

single_integrator_position_controller = create_si_position_controller() # Single integrator position controller

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary() # Barrier certificates to avoid collision

_, uni_to_si_states = create_si_to_uni_mapping() # Unicycle to Single Integrator States Mapping

si_to_uni_dyn = create_si_to_uni_dynamics_with_backwards_motion() # Single Integrator to Unicycle Velocity Commands

# Read in and scale image
gt_img = plt.imread('GTLogo.png')
x_img = np.linspace(-1.0, 1.0, gt_img.shape[1])
y_img = np.linspace(-1.0, 1.0, gt_img.shape[0])

gt_img_handle = r.axes.imshow(gt_img, extent=(-1, 1, -1, 1))

x = r.get_poses() # Get poses of the Robots

x_si = uni_to_si_states(x) # Transform poses to Single Integrator

r.step() # Iterate the simulation

# While all Robots are not in the goal points.
while (np.size(at_pose(np.vstack((x_si,x[2,:])), goal_points, rotation_error=100)) != N):

    x = r.get_poses() # Get the poses of robots

    x_si = uni_to_si_states(x) # Transform poses to Single Integrator

    dxi = single_integrator_position_controller(x_si, goal_points[:2][:]) # Create single-integrator control inputs

    dxi_safe = si_barrier_cert(dxi, x_si) # Create safe control inputs (i.e., no collisions)

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Transform single integrator velocity commands to unicycle

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities using the Unicycle Commands

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
