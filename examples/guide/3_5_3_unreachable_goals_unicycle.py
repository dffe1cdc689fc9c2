# Robotarium Python Guide section 3.5.3 "Robots Moving Towards Unreachable Goals with Unicycle Model" (Listing 11: uni_barriers_with_boundary.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; "\#" -> "#" on line 8; stripped LaTeX residue (\verb|...|, \textit{...}) from the r.set_velocities line (32); goal_points row 2 printed as "5 5 5 5" (4 entries, np.mat raises ValueError "Rows not the same size") -> "5 5 5 5 5" as in upstream uni_barriers_with_boundary.py.
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np

N = 5 # Number of Robots

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, sim_in_real_time=True) # Instantiate Robotarium object

iterations = 3000 # Run the simulation/experiment for 3000 steps

goal_points = np.array(np.mat('5 5 5 5 5; 5 5 5 5 5; 0 0 0 0 0')) # Goal points

unicycle_position_controller = create_clf_unicycle_position_controller() # Create unicycle position controller

uni_barrier_cert = create_unicycle_barrier_certificate_with_boundary() # Create barrier certificates to avoid collision

x = r.get_poses() # Get the poses of robots

r.step() # Iterate the simulation

for i in range(iterations):

    x = r.get_poses() # Get the poses of robots

    dxu = unicycle_position_controller(x, goal_points[:2][:]) # Create unicycle control inputs

    dxu_safe = uni_barrier_cert(dxu, x) # Create safe control inputs (i.e., no collisions)

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of agents 1,...,N to dxu_safe

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
