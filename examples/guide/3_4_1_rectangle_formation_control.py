# Robotarium Python Guide section 3.4.1 "Rectangle Formation Control" (Listing 8: formation_control.py), copied as printed.
# Extraction repairs: removed interleaved line numbers; restored indentation; added the comma lost after row 3 of L (line 12; without it Python indexes a list with a tuple); "1)" -> "])" closing L (line 16); restored the "])" closing weights (line 30) that was dropped; joined the wrapped comment of line 57.
import rps.robotarium as robotarium
from rps.utilities.transformations import *
from rps.utilities.graph import *
from rps.utilities.barrier_certificates import *
from rps.utilities.misc import *
from rps.utilities.controllers import *

# Array representing the geometric distances betwen the agents. In this case, the agents try to form a Rectangle
L = np.array([
    [3, -1, 0, -1, 0, -1],
    [-1, 3, -1, 0, -1, 0],
    [0, -1, 3, -1, 0, -1],
    [-1, 0, -1, 3, -1, 0],
    [0, -1, 0, -1, 3, -1],
    [-1, 0, -1, 0, -1, 3]
])

d = 0.3 # Desired distance between agent
ddiag = np.sqrt(5)*d
formation_control_gain = 10 # Desired gain

# Weight matrix to control inter-agent distances
weights = np.array([
    [0, d, 0, d, 0, ddiag],
    [d, 0, d, 0, d, 0],
    [0, d, 0, ddiag, 0, d],
    [d, 0, ddiag, 0, d, 0],
    [0, d, 0, d, 0, d],
    [ddiag, 0, d, 0, d, 0]
])

iterations = 2000 # Run the simulation/experiment for 2000 steps

N = 6 # Number of Robots

magnitude_limit = 0.15 # Limit maximum linear speed of any robot

r = robotarium.Robotarium(number_of_robots=N, show_figure=True, sim_in_real_time=True) # Instantiate Robotarium object

si_barrier_cert = create_single_integrator_barrier_certificate_with_boundary() # Barrier certificates to avoid collision

si_to_uni_dyn = create_si_to_uni_dynamics() # Single Integrator to Unicycle Velocity Commands

for k in range(iterations):

    x = r.get_poses() # Get the poses of the robots

    dxi = np.zeros((2, N)) # Initialize a velocity vector

    for i in range(N):

        for j in topological_neighbors(L, i):
            error = x[:2, j] - x[:2, i] # Perform a weighted consensus to make the rectangular shape
            dxi[:, i] += formation_control_gain*(np.power(np.linalg.norm(error), 2)- np.power(weights[i, j], 2)) * error

    norms = np.linalg.norm(dxi, 2, 0)
    idxs_to_normalize = (norms > magnitude_limit) # Threshold control inputs
    dxi[:, idxs_to_normalize] *= magnitude_limit/norms[idxs_to_normalize] # Keep single integrator control vectors under specified magnitude

    dxi_safe = si_barrier_cert(dxi, x[:2, :]) # Make sure that the robots don't collide

    dxu_safe = si_to_uni_dyn(dxi_safe, x) # Transform the single-integrator dynamcis to unicycle dynamics

    r.set_velocities(np.arange(N), dxu_safe) # Set the velocities of the robots

    r.step() # Iterate the simulation

r.call_at_scripts_end() # Call at end of script to print debug information
