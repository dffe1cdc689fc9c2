"""A lockstep scenario run twice: through the whole stack (client, safety node, simulator over
DDS) and in this process through the same pure code (the controller, the safety node's
`filter_commands` with its certificate, the model), so that a change to the stack's plumbing
(executors, message handling, transport) can prove it moved no robot by a single bit:
tests/test_client.py compares the two.

The scenario makes every part work: six robots in two columns swap sides, so they meet in the
middle and the safety node's barrier certificate changes their commands; the guide's unicycle
position controller asks for more than the wheels can do at first (actuator-limit iterations).

Why not a stored file of poses: the poses are bit-for-bit repeatable on one machine, not across
processors. numpy picks its kernels by the CPU's instruction sets, a last-bit difference at step 1
grows through 300 steps of feedback to 0.17 m (measured 2026-11-26: a reference recorded on
2026-11-23 on another processor differed from step 1 on, by 4e-16 m there). Computed in the same
process on the same machine, both sides use the same kernels.
"""
import numpy as np

STEPS = 300
START = np.array([[-0.5, -0.5, -0.5, 0.5, 0.5, 0.5],
                  [-0.3, 0.0, 0.3, -0.3, 0.0, 0.3],
                  [0.0, 0.1, -0.1, np.pi, np.pi - 0.1, np.pi + 0.1]])
GOALS = START[:2] * np.array([[-1.0], [1.0]])


def run(robotarium):
    """Run the scenario on `robotarium` (a fresh lockstep Robotarium of 6 robots at START);
    returns the poses of every step, shape (STEPS + 1, 3, 6), and the debug report."""
    import contextlib
    import io

    from rps.utilities.controllers import create_clf_unicycle_position_controller
    controller = create_clf_unicycle_position_controller()
    poses = []
    for _ in range(STEPS):
        x = robotarium.get_poses()
        poses.append(x.copy())   # rps hands out its own array, which step() updates in place
        robotarium.set_velocities(np.arange(6), controller(x, GOALS))
        robotarium.step()
    poses.append(robotarium.get_poses())
    with contextlib.redirect_stdout(io.StringIO()) as out:
        robotarium.call_at_scripts_end()
    report = out.getvalue().split("Run ")[0]   # without where it was recorded
    return np.array(poses), report


def in_process(config):
    """The same scenario without ROS: what the safety node's filter and the simulator's model
    make of the controller's commands, step by step. Returns the poses of every step and the
    debug report (the safety layer steers: it says how much, and gives no count of the Robotarium's)."""
    from robotarium_core import model
    from robotarium_safety.guard import filter_commands
    from robotarium_safety.testbed_certificate import TestbedCertificate
    from rps.utilities.controllers import create_clf_unicycle_position_controller
    controller = create_clf_unicycle_position_controller()
    certificate = TestbedCertificate(config)
    testbed = model.Testbed(START.copy(), config)
    tally = model.RunTally()
    poses = []
    for _ in range(STEPS):
        x = testbed.poses.copy()
        poses.append(x)
        filtered = filter_commands(certificate, controller(x, GOALS), x, config)
        change = float(filtered.change.max())
        tally.add_safety_report(model.is_intervention(change > 0, change, config.intervention_tolerance), change)
        testbed.set_commands(np.arange(6), filtered.safe[0], filtered.safe[1],
                             requested_exceeds_limits=filtered.over_limits)
        testbed.step()
    poses.append(testbed.poses.copy())
    report = model.debug_report(testbed.steps, testbed.boundary_violations, testbed.collisions,
                                testbed.actuator_limit_iterations, config.time_step, safety=tally.safety(STEPS))
    return np.array(poses), report
