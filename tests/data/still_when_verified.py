"""A script that behaves differently when it is verified: in lockstep (how ./robotarium verify and
the portal's verification run it) its two robots stand still; in real time (the run) they drive
head-on at full speed. Verified, nothing is changed; in the run the safety layer holds them apart,
and the portal flags the experiment with both figures (issue 36)."""
import numpy as np

import rps.robotarium as robotarium

N = 2
initial_conditions = np.array([[-0.5, 0.5], [0.0, 0.0], [0.0, np.pi]])
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, initial_conditions=initial_conditions,
                          sim_in_real_time=True)
speed = 0.2 if r.sim_in_real_time else 0.0
for _ in range(120):
    r.get_poses()
    r.set_velocities(np.arange(N), np.array([[speed, speed], [0.0, 0.0]]))
    r.step()
r.call_at_scripts_end()
