"""The arena and GTernal model against hand-computed cases and against the reference simulator."""
import math

import numpy as np
import pytest

from devtools.reference import reference_available, run_reference
from robotarium_core import model
from robotarium_core.model import RobotariumError


def one_robot(x=0.0, y=0.0, theta=0.0):
    return model.Testbed(np.array([[x], [y], [theta]]))


def test_straight_line():
    tb = one_robot(theta=0.0)
    tb.set_commands([0], [0.1], [0.0])
    for _ in range(30):
        tb.step()
    assert tb.poses[0, 0] == pytest.approx(30 * 0.033 * 0.1, abs=1e-12)
    assert tb.poses[1, 0] == pytest.approx(0.0, abs=1e-12)
    assert tb.poses[2, 0] == 0.0
    assert tb.steps == 30 and tb.sim_time == pytest.approx(0.99)


def test_straight_line_along_heading():
    tb = one_robot(theta=math.pi / 3)
    tb.set_commands([0], [0.2], [0.0])
    tb.step()
    assert tb.poses[:2, 0] == pytest.approx([0.033 * 0.2 * 0.5, 0.033 * 0.2 * math.sqrt(3) / 2], abs=1e-12)


def test_pure_rotation_does_not_translate():
    tb = one_robot(x=0.3, y=-0.2, theta=0.0)
    tb.set_commands([0], [0.0], [1.0])
    for _ in range(10):
        tb.step()
    assert tb.poses[:2, 0] == pytest.approx([0.3, -0.2], abs=1e-15)
    assert tb.poses[2, 0] == pytest.approx(0.33, abs=1e-12)


def test_angle_wraps_to_minus_pi_pi():
    tb = one_robot(theta=3.1)
    tb.set_commands([0], [0.0], [3.0])
    tb.step()  # 3.1 + 0.099 = 3.199 > pi
    assert tb.poses[2, 0] == pytest.approx(3.199 - 2 * math.pi, abs=1e-12)
    assert -math.pi <= tb.poses[2, 0] <= math.pi
    assert model.wrap_angle(np.array([-3.5]))[0] == pytest.approx(-3.5 + 2 * math.pi)


def test_threshold_keeps_commands_within_limits_unchanged():
    dxu = np.array([[0.1, -0.12, 0.0, 0.05], [0.5, -1.0, 3.0, 0.0]])
    assert np.array_equal(model.threshold_keeping_arc(dxu), dxu)


def test_threshold_preserves_arc_and_respects_wheel_limits():
    dxu = np.array([[0.3, 0.2, 0.0, -0.5], [1.0, 2.0, 10.0, 0.4]])
    out = model.threshold_keeping_arc(dxu)
    wheels = model.unicycle_to_wheels(out)
    assert np.all(np.abs(wheels) <= model.MAX_WHEEL_VELOCITY + 1e-9)
    assert np.all(np.abs(out[0]) <= 0.2 + 1e-12) and np.all(np.abs(out[1]) <= model.MAX_ANGULAR_VELOCITY + 1e-12)
    # Same arc: same ratio v/omega, same signs; and one wheel (or a limit) is exactly at its bound.
    moving = dxu[1] != 0
    assert out[0, moving] / out[1, moving] == pytest.approx(dxu[0, moving] / dxu[1, moving])
    assert np.all(np.sign(out) == np.sign(dxu))
    # Hand-computed: v=0.3, w=1 -> wheels (0.6 -+ 0.105)/0.032 = 15.47, 22.03 -> alpha = 12.5/22.03
    alpha = 12.5 / ((0.6 + 0.105) / 0.032)
    assert out[:, 0] == pytest.approx([0.3 * alpha, 1.0 * alpha])
    # Pure rotation at 10 rad/s is held to the rps angular limit of 2*0.2/0.11 rad/s.
    assert out[:, 2] == pytest.approx([0.0, 2 * 0.2 / 0.11])


def test_actuator_limit_counted_like_rps():
    # v = 0.3 alone: rps clips v to 0.2 first, wheels at exactly 12.5 -> not counted.
    assert not model.exceeds_actuator_limits(np.array([[0.3], [0.0]]))
    # v = 0.2 with a little turn: one wheel over 12.5 -> counted.
    assert model.exceeds_actuator_limits(np.array([[0.2], [0.5]]))
    tb = model.Testbed(np.array([[0.0, 0.5], [0.0, 0.0], [0.0, 0.0]]))
    tb.set_commands([0, 1], [0.2, 0.0], [0.5, 0.0])
    tb.step()
    tb.set_commands([0, 1], [0.1, 0.0], [0.0, 0.0])
    tb.step()
    assert tb.actuator_limit_iterations == 1


def test_actuator_count_takes_the_safety_nodes_word_on_the_request():
    # The safety node replaced an over-limit request with a drivable command: rps would have
    # judged the request, so the iteration counts; once the command times out nothing was asked.
    tb = one_robot()
    tb.set_commands([0], [0.1], [0.0], now=10.0, requested_exceeds_limits=True)
    tb.step()
    assert tb.actuator_limit_iterations == 1
    tb.expire_commands(10.6)
    tb.step()
    tb.set_commands([0], [0.1], [0.0], now=11.0)
    tb.step()
    assert tb.actuator_limit_iterations == 1


def test_collision_counting_per_pair_and_step():
    poses = np.array([[0.0, 0.10, 0.20, 1.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    # pairs within 0.11: (0,1) 0.10, (1,2) 0.10; (0,2) is 0.20 apart.
    assert model.count_collisions(poses) == 2
    assert model.count_collisions(np.array([[0.0, 0.11], [0.0, 0.0], [0.0, 0.0]])) == 1  # <= counts, as rps
    assert model.count_collisions(np.array([[0.0, 0.1101], [0.0, 0.0], [0.0, 0.0]])) == 0


def test_large_crowds_count_collisions_as_every_pair_would():
    # Beyond SWEEP_MIN_ROBOTS only pairs from a sweep along x are tested: the count must be the
    # all-pairs count exactly, borderline distances (exactly one diameter, in x and diagonally) included.
    rng = np.random.default_rng(3)
    n = model.SWEEP_MIN_ROBOTS + 50
    for _trial in range(30):
        poses = rng.uniform(-1, 1, (3, n)) * np.array([[3.0], [2.0], [3.0]]) * rng.uniform(0.05, 1.0)
        poses[:, 1] = poses[:, 0] + [0.11, 0.0, 0.0]                          # exactly a diameter apart in x
        poses[:, 3] = poses[:, 2] + [0.11 / np.sqrt(2), 0.11 / np.sqrt(2), 0.0]   # and on a diagonal
        i, j = model.robot_pairs(n)
        dx, dy = poses[0, i] - poses[0, j], poses[1, i] - poses[1, j]
        every_pair = int(np.count_nonzero(np.sqrt(dx * dx + dy * dy) <= 0.11))
        assert model.count_collisions(poses, 0.11) == every_pair
    assert every_pair > 0


def test_boundary_counting_and_collisions_accumulate_per_step():
    tb = model.Testbed(np.array([[1.55, -0.5], [0.0, 0.0], [0.0, 0.0]]))
    tb.set_commands([0], [0.2], [0.0])
    for _ in range(20):  # 0.0066 m per step: crosses x = 1.6 after 8 steps
        tb.step()
    # Counted on the poses before each move: steps 9..20 see robot 0 outside.
    crossing = next(k for k in range(30) if 1.55 + k * 0.0066 > 1.6)
    assert tb.boundary_violations == 20 - crossing
    assert tb.collisions == 0
    assert "robots were outside the boundaries" in tb.report()


def test_command_timeout_stops_and_counts_once():
    tb = one_robot()
    tb.set_commands([0], [0.1], [0.0], now=10.0)
    assert not tb.expire_commands(10.4).any()
    assert tb.expire_commands(10.6).tolist() == [True]
    assert tb.velocities[:, 0].tolist() == [0.0, 0.0]
    assert not tb.expire_commands(20.0).any()
    assert tb.command_timeouts == 1


def test_check_commands_finds_each_problem():
    ok = model.check_commands(np.array([0, 1]), np.array([0.1, 0.0]), np.array([0.0, 0.2]), 2)
    assert ok is None
    assert model.check_commands(np.array([0, 1]), np.array([0.1]), np.array([0.0, 0.2]), 2) == "length_mismatch"
    assert model.check_commands(np.array([0, 0]), np.array([0.1, 0.1]), np.array([0.0, 0.2]), 2) == "length_mismatch"
    assert model.check_commands(np.array([0, 5]), np.array([0.1, 0.1]), np.array([0.0, 0.2]), 2) == "unknown_id"
    assert model.check_commands(np.array([0, 1]), np.array([np.nan, 0.1]), np.array([0.0, 0.2]), 2) == "nonfinite"
    assert model.check_commands(np.array([0, 1]), np.array([0.1, 0.1]), np.array([np.inf, 0.2]), 2) == "nonfinite"


def test_dropped_arrays_are_described_by_what_each_reason_means():
    """A late array of the script's own (stale) is said to be late, not called foreign or invalid."""
    text = model.describe_drops({"foreign": 0, "stale": 1, "nonfinite": 2})
    assert text == "1 stale (%s); 2 nonfinite (%s)" % (model.DROP_REASONS["stale"], model.DROP_REASONS["nonfinite"])
    assert "filtered at poses the testbed has left" in text and "token" not in text
    assert model.describe_drops(dict.fromkeys(model.DROP_REASONS, 0)) == ""


@pytest.mark.parametrize("n", [1, 5, 20, 50])
def test_random_initial_conditions_are_valid_and_seeded(n):
    a = model.random_initial_conditions(n, np.random.default_rng(3))
    b = model.random_initial_conditions(n, np.random.default_rng(3))
    assert np.array_equal(a, b)
    model.validate_initial_conditions(a, n)  # inside the arena and no two in collision
    assert a.shape == (3, n)


@pytest.mark.parametrize("bad, words", [
    (np.array([[0.0, 0.05], [0.0, 0.0], [0.0, 0.0]]), "collision"),
    (np.array([[0.0, 1.7], [0.0, 0.0], [0.0, 0.0]]), "outside the arena"),
    (np.array([[0.0, np.nan], [0.0, 0.0], [0.0, 0.0]]), "finite"),
    (np.zeros((2, 2)), "3 x 2"),
])
def test_invalid_initial_conditions_are_refused(bad, words):
    with pytest.raises(RobotariumError, match=words):
        model.validate_initial_conditions(bad, 2)


@pytest.mark.parametrize("n", [0, 51, -1, 2.0, True])
def test_number_of_robots_range(n):
    with pytest.raises(RobotariumError, match="number_of_robots"):
        model.validate_number_of_robots(n)


def test_report_text_matches_rps_format():
    clean = model.debug_report(450, 0, 0, 0)
    assert clean == ("##### DEBUG OUTPUT #####\n"
                     "Your simulation will take approximately 15 real seconds when deployed on the Robotarium. \n\n"
                     "No errors in your simulation! Acceptance of your experiment is likely!\n")
    assert "\t Simulation had 450 iteration(s) where the actuator limits were exceeded.\n" in model.debug_report(450, 0, 0, 450)


@pytest.mark.skipif(not reference_available(), reason="reference venv missing (./robotarium setup makes it)")
def test_steps_match_reference_bit_for_bit():
    """Within the actuator limits our step is the reference's step, bit for bit, and the
    debug counters (collisions per pair, boundary per robot, actuator per iteration) agree."""
    rng = np.random.default_rng(7)
    n, steps = 8, 150
    initial = model.random_initial_conditions(n, rng)
    # Commands inside the wheel limits, plus some steps over them (the counters must agree there too,
    # though rps then drives a different arc, so poses are compared only while commands are within limits).
    commands = np.stack([np.vstack((rng.uniform(-0.08, 0.08, n), rng.uniform(-1.5, 1.5, n))) for _ in range(steps)])
    code = """
import numpy as np
import rps.robotarium as robotarium
r = robotarium.Robotarium(number_of_robots=n, show_figure=False, initial_conditions=initial.copy(), sim_in_real_time=False)
trace = []
for k in range(steps):
    r.get_poses()
    r.set_velocities(np.arange(n), commands[k].copy())
    r.step()
    trace.append(r.poses.copy())
result["trace"] = np.array(trace)
result["errors"] = {k: v for k, v in r._errors.items() if not k.endswith("_string")}
"""
    ref = run_reference(code, n=n, steps=steps, initial=initial, commands=commands)
    tb = model.Testbed(initial)
    ours = []
    for k in range(steps):
        tb.set_commands(range(n), commands[k][0], commands[k][1])
        tb.step()
        ours.append(tb.poses.copy())
    assert np.array_equal(np.array(ours), ref["trace"])
    assert tb.collisions == ref["errors"].get("collision", 0)
    assert tb.boundary_violations == ref["errors"].get("boundary", 0)
    assert tb.actuator_limit_iterations == ref["errors"].get("actuator", 0)


@pytest.mark.skipif(not reference_available(), reason="reference venv missing (./robotarium setup makes it)")
def test_counters_match_reference_in_a_messy_run():
    """Robots driven into each other, out of the arena and over the wheel limits: the counters
    of the debug report agree with the reference's (poses differ once limits are exceeded)."""
    initial = np.array([[-0.3, 0.3, 1.4, -1.0], [0.0, 0.0, 0.8, -0.5], [0.0, math.pi, 0.5, 0.0]])
    steps = 120
    # A head-on pair, one robot leaving the arena, and one far from all others driving a circle
    # over the wheel limits (rps drives it on another arc, but nowhere near anyone or any wall).
    commands = np.array([[0.15, 0.15, 0.19, 0.2], [0.0, 0.0, 0.1, 0.5]])
    code = """
import numpy as np
import rps.robotarium as robotarium
r = robotarium.Robotarium(number_of_robots=4, show_figure=False, initial_conditions=initial.copy(), sim_in_real_time=False)
for k in range(steps):
    r.get_poses()
    r.set_velocities(np.arange(4), commands.copy())
    r.step()
result["errors"] = {k: v for k, v in r._errors.items() if not k.endswith("_string")}
"""
    ref = run_reference(code, initial=initial, steps=steps, commands=commands)
    tb = model.Testbed(initial)
    for _ in range(steps):
        tb.set_commands(range(4), commands[0], commands[1])
        tb.step()
    assert tb.collisions == ref["errors"]["collision"] > 0
    assert tb.boundary_violations == ref["errors"]["boundary"] > 0
    assert tb.actuator_limit_iterations == ref["errors"]["actuator"] == steps


def test_huge_finite_commands_saturate_on_their_arc_never_a_stop():
    """1e308 once overflowed the wheel speed to inf and scaled the command to 0 (a stop): it must
    be full speed along the commanded arc like any other command beyond the limits."""
    huge = np.array([[1e308, -1e308, 1e308, 0.1, -1e300, 1e308],
                     [0.0, 1e308, -1.0, 1e308, 1e300, 1e308]])
    out = model.threshold_keeping_arc(huge)
    assert np.all(np.isfinite(out))
    assert not model.exceeds_actuator_limits(out * (1 - 1e-12))
    wheels = model.fastest_wheel(out[0], out[1])
    # every robot drives at a limit: the wheel limit, or |v| = 0.2, or |omega| = its limit
    at_limit = (np.isclose(wheels, model.MAX_WHEEL_VELOCITY) | np.isclose(np.abs(out[0]), model.MAX_LINEAR_VELOCITY)
                | np.isclose(np.abs(out[1]), model.MAX_ANGULAR_VELOCITY))
    assert np.all(at_limit), out
    assert np.array_equal(np.sign(out), np.sign(huge))   # same direction
    # the arc v / omega is kept where both are of comparable size
    assert out[0, 1] / out[1, 1] == pytest.approx(-1.0) and out[0, 5] / out[1, 5] == pytest.approx(1.0)
    assert out[0, 0] == model.MAX_LINEAR_VELOCITY and out[1, 0] == 0.0


def test_the_intervention_count_and_its_largest_change_agree():
    """Stops of requests at rest once counted as interventions of change 0: a report said "658
    interventions, largest change 0" (issue 22). Now a count > 0 always comes with a change > tolerance."""
    tolerance, tally = 1e-3, model.RunTally()
    for filtered, change in ((True, 0.0), (True, 0.0), (True, 0.5e-3), (False, 0.3)):   # stops at rest, a tiny
        tally.add_safety_report(model.is_intervention(filtered, change, tolerance), change)   # change, a passthrough
    assert tally.safety(4)["interventions"] == 0 and model.safety_lines(**tally.safety(4)) == []
    tally.add_safety_report(model.is_intervention(True, 0.2, tolerance), 0.2)   # a stop of 0.2 m/s
    summary = tally.safety(5)
    assert summary["interventions"] == 1 and summary["largest_change"] == 0.2
    assert "changed 1 of 5 command arrays of this run (largest change 0.2," in "".join(model.safety_lines(**summary))
