"""The maths kernel both rps APIs map and control with (robotarium_core.kinematics, .control, and
model's at-goal checks)."""
import numpy as np

from robotarium_core import control, kinematics, model

PI = np.pi
_rng = np.random.default_rng(11)
POSES = np.vstack([_rng.uniform(-1, 1, (2, 25)), _rng.uniform(-PI, PI, 25)])
DXI = _rng.normal(scale=0.2, size=(2, 25))


def test_body_frame_and_heading_tracking_by_hand():
    theta = np.array([0.0, PI / 2, PI / 2, 0.0])
    dxi = np.array([[0.1, 0.0, -0.1, -0.1], [0.0, 0.1, 0.0, 0.0]])
    along, left = kinematics.body_frame(dxi, theta)
    np.testing.assert_allclose(along, [0.1, 0.1, 0.0, -0.1], atol=1e-15)
    np.testing.assert_allclose(left, [0.0, 0.0, 0.1, 0.0], atol=1e-15)
    dxu = kinematics.si_to_uni_heading(dxi, theta, 2, 1.5)
    # ahead: drive, no turn; to the left: the limit; behind: twice the limit
    np.testing.assert_allclose(dxu, [[0.2, 0.2, 0.0, -0.2], [0.0, 0.0, 1.5, 3.0]], atol=1e-15)
    back = kinematics.si_to_uni_heading_reversible(dxi, theta, 2, 1.5)
    np.testing.assert_allclose(back[:, 3], [-0.2, 0.0], atol=1e-15)   # behind: reverse, no turn


def test_a_zero_command_turns_only_without_the_fix():
    theta = np.array([-2.0, -3.0, -1.7])       # cos, sin < 0: dxi along the heading is -0.0 + -0.0
    zero = np.zeros((2, 3))
    assert np.all(kinematics.si_to_uni_heading(zero, theta, 1, PI) == 0)
    assert np.all(np.abs(kinematics.si_to_uni_heading(zero, theta, 1, PI, no_spin_at_rest=False)[1]) == 2 * PI)


def test_si_uni_si_round_trip_at_the_projection_point():
    for distance in (0.03, 0.05, 0.2):
        dxu = kinematics.si_to_uni_projected(DXI, POSES[2], distance)
        np.testing.assert_allclose(kinematics.uni_to_si_projected(dxu, POSES[2], distance), DXI, atol=1e-14)
        ahead = kinematics.points_ahead(POSES, distance)
        np.testing.assert_allclose(np.hypot(*(ahead - POSES[:2])), distance)
        np.testing.assert_allclose(kinematics.axles_behind(ahead, POSES[2], distance), POSES[:2], atol=1e-15)
    # clipped omega
    clipped = kinematics.si_to_uni_projected(DXI, POSES[2], 0.01, 1.0)
    assert np.max(np.abs(clipped[1])) == 1.0


def test_uni_to_si_is_the_velocity_of_the_point_ahead():
    dxu = np.vstack([_rng.uniform(-0.2, 0.2, 25), _rng.uniform(-2, 2, 25)])
    dt, distance = 1e-6, 0.05
    moved = model.unicycle_step(POSES, dxu, dt)
    velocity = (kinematics.points_ahead(moved, distance) - kinematics.points_ahead(POSES, distance)) / dt
    np.testing.assert_allclose(velocity, kinematics.uni_to_si_projected(dxu, POSES[2], distance), atol=1e-6)


def test_speed_limit_and_position_law():
    dxi = DXI * 3
    norms = np.linalg.norm(dxi, axis=0)
    limited = control.limit_speeds(dxi.copy(), 0.2, norms)
    assert np.all(np.linalg.norm(limited, axis=0) <= 0.2 + 1e-15)
    slow = norms <= 0.2
    np.testing.assert_array_equal(limited[:, slow], dxi[:, slow])
    np.testing.assert_allclose(limited[:, ~slow] / np.linalg.norm(limited[:, ~slow], axis=0),
                               dxi[:, ~slow] / norms[~slow])
    np.testing.assert_allclose(control.limit_speeds(dxi.copy(), 0.2, norms, divide_last=True), limited, rtol=1e-15)
    law = control.si_position_law(np.zeros((2, 2)), np.array([[0.1, 1.0], [0.0, 0.0]]), np.array([[1.0], [1.0]]), 0.15)
    np.testing.assert_allclose(law, [[0.1, 0.15], [0.0, 0.0]])


def test_clf_pose_law_stops_at_the_goal_and_agrees_on_sinc():
    at_goal = control.clf_pose_law(POSES, POSES, 1, 2.7, 1)
    np.testing.assert_array_equal(at_goal, np.zeros((2, 25)))
    goals = POSES + np.vstack([_rng.uniform(-0.5, 0.5, (2, 25)), _rng.uniform(-1, 1, 25)])
    exact = control.clf_pose_law(POSES, goals, 1, 2.7, 1)
    np.testing.assert_allclose(control.clf_pose_law(POSES, goals, 1, 2.7, 1, exact_sinc=False), exact, atol=1e-12)
    # v drives towards the goal: positive when it lies ahead
    ahead = kinematics.points_ahead(POSES, 0.3)
    assert np.all(control.clf_pose_law(POSES, np.vstack([ahead, POSES[2]]), 1, 2.7, 1)[0] > 0)


def test_hybrid_step_modes():
    states = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    goals = np.array([[1.0, 0.005, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.01]])
    dxu, approaching, turned = control.hybrid_pose_step(
        states, goals, np.ones(3, dtype=bool), lambda dxi, x: dxi, speed_limit=0.15, turn_gain=2,
        position_error=0.03, position_epsilon=0.01, rotation_error=0.05)
    np.testing.assert_allclose(dxu, [[0.15, 0.0, 0.0], [0.0, 2.0, 0.0]])   # drive (capped), turn, stand still
    assert approaching.tolist() == [True, False, True] and turned.tolist() == [False, True, False]


def test_at_pose_masks():
    states = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0], [0.0, 3.0, 0.0, 1.0]])
    goals = np.array([[0.05, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0], [0.0, 3.0 - 2 * PI + 0.1, 0.3, 1.0]])
    # exactly at the position error; 0.1 rad off once wrapped; 0.3 rad off; there
    assert model.at_pose_mask(states, goals, 0.05, 0.2).tolist() == [True, True, False, True]
    assert model.at_pose_mask(states, goals, 0.05, 0.2, strict=True).tolist() == [False, True, False, True]
    assert model.at_position_mask(states, goals[:2], 0.05).all()
    assert model.at_position_mask(states, goals[:2], 0.049).tolist() == [False, True, True, True]
