"""A lockstep run whose every pose is kept in tests/data/lockstep_reference.npz, so that a change
to the stack's plumbing (executors, message handling, transport) can prove it moved no robot by a
single bit: tests/test_client.py runs the same scenario and compares.

The scenario makes every part work: six robots in two columns swap sides, so they meet in the
middle and the safety node's barrier certificate changes their commands; the guide's unicycle
position controller asks for more than the wheels can do at first (actuator-limit iterations).

Re-make the reference only when the testbed's behaviour is meant to change (the model, the
safety node's certificate), from `./robotarium shell`:
    python -m devtools.lockstep_reference
"""
import os

import numpy as np

from devtools import REPO

REFERENCE = os.path.join(REPO, "tests", "data", "lockstep_reference.npz")
STEPS = 300
START = np.array([[-0.5, -0.5, -0.5, 0.5, 0.5, 0.5],
                  [-0.3, 0.0, 0.3, -0.3, 0.0, 0.3],
                  [0.0, 0.1, -0.1, np.pi, np.pi - 0.1, np.pi + 0.1]])


def run(robotarium):
    """Run the scenario on `robotarium` (a fresh lockstep Robotarium of 6 robots at START);
    returns the poses of every step, shape (STEPS + 1, 3, 6), and the debug report."""
    import contextlib
    import io

    from rps.utilities.controllers import create_clf_unicycle_position_controller
    controller = create_clf_unicycle_position_controller()
    goals = START[:2] * np.array([[-1.0], [1.0]])
    poses = []
    for _ in range(STEPS):
        x = robotarium.get_poses()
        poses.append(x)
        robotarium.set_velocities(np.arange(6), controller(x, goals))
        robotarium.step()
    poses.append(robotarium.get_poses())
    with contextlib.redirect_stdout(io.StringIO()) as out:
        robotarium.call_at_scripts_end()
    report = out.getvalue().split("Run ")[0]   # without where it was recorded
    return np.array(poses), report


def main():
    from devtools.rosutil import unique_domain_id
    os.environ["ROS_DOMAIN_ID"] = str(unique_domain_id())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rps.robotarium
    from robotarium_client import session
    from robotarium_client.testbed import LocalTestbed, testbed_answers
    session.options = session.RunOptions(local_testbed=False)
    with LocalTestbed(record=False):
        if not testbed_answers(timeout=60):
            raise RuntimeError("the local testbed did not come up")
        poses, report = run(rps.robotarium.Robotarium(number_of_robots=6, show_figure=False,
                                                      initial_conditions=START.copy(), sim_in_real_time=False))
    os.makedirs(os.path.dirname(REFERENCE), exist_ok=True)
    np.savez_compressed(REFERENCE, poses=poses, report=report)
    print(report)
    print("wrote %s: %d steps" % (REFERENCE, len(poses) - 1))


if __name__ == "__main__":
    main()
