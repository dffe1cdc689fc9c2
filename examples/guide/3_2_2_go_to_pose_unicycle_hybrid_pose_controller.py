# Robotarium Python Guide section 3.2.2 "Robots go to a point using Unicycle Hybrid Pose Controller" (Listing 6: uni_go_to_pose_hybrid.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; joined the wrapped Robotarium(...) line (dropped the "->" continuation marker).
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np
import time

N = 5 # Number of Robots

initial_conditions = np.array(np.mat('1 0.5 -0.5 0 0.28; 0.8 -0.3 -0.75 0.1 0.34; 0 0 0 0 0')) #Goal Points

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, initial_conditions=initial_conditions, sim_in_real_time=True) # Instantiate Robotarium object

goal_points = generate_initial_conditions(N) # Goal Points

unicycle_pose_controller = create_hybrid_unicycle_pose_controller() # Create unicycle hybrid pose controller

uni_barrier_cert = create_unicycle_barrier_certificate() # Create barrier certificates to avoid collision

x = r.get_poses() # Get the poses of Robots

r.step() # Iterate the simulation

# While the robots are not in the goal points
while (np.size(at_pose(x, goal_points)) != N):

    x = r.get_poses() # Get poses of Robots

    dxu = unicycle_pose_controller(x, goal_points) # Create unicycle control inputs

    dxu_safe = uni_barrier_cert(dxu, x) # Create safe control inputs (i.e., no collisions)

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of agents 1,...,N to dxu_safe

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
