# Robotarium Python Guide section 3.1.2 "Robots go to a point Unicycle" (Listing 4: uni_go_to_point.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; stripped LaTeX residue (\leftrightarrow, \verb|...|, \textit{...}, \texttt{N}) from the Robotarium(...), goal_points and r.set_velocities lines and restored the ")" the residue swallowed; joined the wrapped Robotarium(...) line.
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np
import time

N = 5 # Number of Robots

initial_conditions = np.array(np.mat('1 0.5 -0.5 0 0.28; 0.8 -0.3 -0.75 0.1 0.34; 0 0 0 0 0')) # Initial Poses

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, initial_conditions=initial_conditions,sim_in_real_time=True) # Instantiate Robotarium object

goal_points = generate_initial_conditions(N) # Goal Points

unicycle_position_controller = create_clf_unicycle_position_controller() # Create unicycle position controller

uni_barrier_cert = create_unicycle_barrier_certificate() # Create barrier certificates to avoid collision

x = r.get_poses() # Get the poses of the Robots

r.step() # Iterate the simulation

# While all Robots are not in the goal points...
while (np.size(at_pose(x, goal_points, rotation_error=100)) != N):

    x = r.get_poses() # Get the poses of Robots

    dxu = unicycle_position_controller(x, goal_points[:2][:]) # Create single-integrator control inputs

    dxu_safe = uni_barrier_cert(dxu, x) # Create safe control inputs (i.e., no collisions)

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of agents 1,...,N to dxu_safe

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
