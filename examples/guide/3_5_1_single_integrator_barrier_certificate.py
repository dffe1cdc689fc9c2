# Robotarium Python Guide section 3.5.1 "Single Integrator Barrier Certificate" (Listing 9: barrier_certficate.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; restored two dropped lines: line 23 "radius = 1" (radius is used on line 24 but its definition was lost; value from the upstream barrier_certificates.py example) and line 29 "])" closing p_circ; "x_{goal} = p_{circ}" -> "x_goal = p_circ" (line 51, LaTeX subscripts); "If O" -> "If 0" in the comment of line 48.
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *
import numpy as np

N = 10 # Number of Robots

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, sim_in_real_time=True) # Instantiate the Robotarium object

num_cycles = 2 # Number times Robots form circle

count = -1 # Number times they have formed the circle (starts at -1 since initial formation will increment the count)

si_barrier_cert = create_single_integrator_barrier_certificate() # Create barrier certificates to avoid collision

si_position_controller = create_si_position_controller() # Create single integrator position controller

si_to_uni_dyn, uni_to_si_states = create_si_to_uni_mapping() # Create SI to UNI dynamics transformation

# Generates points on a circle inscribed in a 6x6 square centered at the origin. Robots swap positions on the circle.
radius = 1
xybound = radius * np.array([-1, 1, -1, 1])
p_theta = 2 * np.pi * (np.arange(0, 2 * N, 2) / (2 * N))
p_circ = np.vstack([
    np.hstack([xybound[1] * np.cos(p_theta), xybound[1] * np.cos(p_theta + np.pi)]),
    np.hstack([xybound[3] * np.sin(p_theta), xybound[3] * np.sin(p_theta + np.pi)])
])

flag = 0 # These variables are so we can tell when the robots should switch positions on the circle.
x_goal = p_circ[:, :N]

while(1): # While True

    x = r.get_poses() # Get the poses of robots

    x_si = uni_to_si_states(x) # Transform unicycle state to Single Integrator state.

    si_velocities = np.zeros((2, N)) # Initialize a velocities variable

    if(np.linalg.norm(x_goal - x_si) < 0.05): # If all the agent are close enough to the goals
        flag = 1 - flag # Change
        count += 1 # Increase the counter

    if count == num_cycles: # if the robots did the circle twice
        break # End the Experiment

    if(flag == 0): # If 0, we change the goal to the other side of the circle
        x_goal = p_circ[:, :N]
    else:
        x_goal = p_circ[:, N:] # If 1, we change the goal to the other side of the circle

    dxi = si_position_controller(x_si, x_goal) # Use a position controller to drive to the goal position

    dxi_safe = si_barrier_cert(dxi, x_si) # Use the barrier certificates to make sure that the agents don't collide

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Use the second single-integrator-to-unicycle mapping to map to unicycle

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of agents 1,...,N to dxu_safe

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
