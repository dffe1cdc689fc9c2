"""rps.utilities: known answers, argument errors, star imports, and agreement with the reference.

The reference is the Robotarium's own simulator (PyPI robotarium-python-simulator 0.0.0) in
.venv-reference; tests/reference.py runs code there. Every comparison with it runs in one
subprocess (the `ref` fixture) to keep the file fast. Where we fixed a bug of the reference, the
test checks our answer by hand instead (and, where useful, that the reference differs).
"""
import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from devtools.reference import reference_available, run_reference  # noqa: E402
from robotarium_core.model import RobotariumError  # noqa: E402
from rps.utilities.controllers import (  # noqa: E402
    create_clf_unicycle_pose_controller,
    create_clf_unicycle_position_controller,
    create_hybrid_unicycle_pose_controller,
    create_si_position_controller,
)
from rps.utilities.graph import (  # noqa: E402
    completeGL,
    cycle_GL,
    delta_disk_neighbors,
    lineGL,
    random_connectedGL,
    randomGL,
    topological_neighbors,
)
from rps.utilities.misc import at_pose, at_position, determine_font_size, determine_marker_size, generate_initial_conditions  # noqa: E402
from rps.utilities.transformations import (  # noqa: E402
    create_si_to_uni_dynamics,
    create_si_to_uni_dynamics_with_backwards_motion,
    create_si_to_uni_mapping,
    create_uni_to_si_dynamics,
)

PI = np.pi


def col(*values):
    """A column vector (one robot)."""
    return np.array(values, dtype=float).reshape(-1, 1)


# --------------------------------------------------------------------------------------------
# Transformations: known answers
# --------------------------------------------------------------------------------------------

def test_si_to_uni_dynamics_known_poses():
    f = create_si_to_uni_dynamics()
    poses = np.array([[0, 1, 0, 0], [0, 2, 0, 0], [0, 0, PI / 2, 0]], dtype=float)
    dxi = np.array([[1, 0, 1, -1], [0, 1, 1, 0]], dtype=float)
    dxu = f(dxi, poses)
    # Ahead: straight on. Left: v = 0, omega = limit * (pi/2)/(pi/2). Heading +y, dxi (1,1):
    # along = 1, left = -1, omega = pi * (-pi/4) / (pi/2). Behind: v = -1, omega = pi*pi/(pi/2).
    np.testing.assert_allclose(dxu, [[1, 0, 1, -1], [0, PI, -PI / 2, 2 * PI]], atol=1e-12)
    # The gain scales v and, as in rps/MATLAB, enters the angle: arctan2(left, gain*along).
    g = create_si_to_uni_dynamics(linear_velocity_gain=2, angular_velocity_limit=1)
    np.testing.assert_allclose(g(col(1, 1), col(0, 0, 0)), col(2, np.arctan2(1, 2) / (PI / 2)))


def test_si_to_uni_dynamics_zero_command_does_not_spin():
    # Fix over rps: theta in (-pi, -pi/2) made arctan2(+0, -0) = pi, i.e. omega = 2*limit.
    for make in (create_si_to_uni_dynamics, create_si_to_uni_dynamics_with_backwards_motion):
        dxu = make()(np.zeros((2, 4)), np.array([[0] * 4, [0] * 4, [-2.5, -PI / 2 - 0.1, 1.0, 3.0]]))
        assert np.array_equal(dxu, np.zeros((2, 4)))


def test_si_to_uni_backwards_motion_is_the_forward_mapping_as_in_rps():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(2, 200))
    p = np.vstack((rng.normal(size=(2, 200)), rng.uniform(-PI, PI, 200)))
    np.testing.assert_array_equal(create_si_to_uni_dynamics_with_backwards_motion(0.8, 1.5)(d, p),
                                  create_si_to_uni_dynamics(0.8, 1.5)(d, p))


def test_si_to_uni_mapping_and_projection():
    si_to_uni, uni_to_si_states = create_si_to_uni_mapping(projection_distance=0.05)
    poses = np.array([[0, 0, 1], [0, 0, 2], [0, 0, PI / 2]], dtype=float)
    dxu = si_to_uni(np.array([[0.1, 0, 0.0], [0.02, 1, 0.1]]), poses)
    # omega = left / l: 0.02/0.05 = 0.4; 1/0.05 = 20 is clipped to pi; heading +y: v = 0.1.
    np.testing.assert_allclose(dxu, [[0.1, 0, 0.1], [0.4, PI, 0]], atol=1e-12)
    np.testing.assert_allclose(uni_to_si_states(poses), [[0.05, 0.05, 1], [0, 0, 2.05]], atol=1e-12)
    # Without clipping the two maps are inverse to each other.
    uni_to_si = create_uni_to_si_dynamics(projection_distance=0.05)
    rng = np.random.default_rng(2)
    p = np.vstack((rng.normal(size=(2, 30)), rng.uniform(-PI, PI, 30)))
    d = rng.normal(scale=0.05, size=(2, 30))
    unclipped = create_si_to_uni_mapping(0.05, np.inf)[0]
    np.testing.assert_allclose(uni_to_si(unclipped(d, p), p), d, atol=1e-12)


def test_uni_to_si_dynamics_known_pose():
    f = create_uni_to_si_dynamics(projection_distance=0.05)
    # Heading +y, v = 1, omega = 2: the point moves +y at 1 and -x at l*omega = 0.1.
    np.testing.assert_allclose(f(col(1, 2), col(0, 0, PI / 2)), col(-0.1, 1), atol=1e-12)


# --------------------------------------------------------------------------------------------
# Controllers: known answers
# --------------------------------------------------------------------------------------------

def test_si_position_controller():
    f = create_si_position_controller()
    xi = np.zeros((2, 3))
    goals = np.array([[0.1, 3, 0], [0, 4, 0]], dtype=float)
    # Within the limit: proportional. (3, 4) has norm 5 > 0.15: scaled to 0.15 along it.
    np.testing.assert_allclose(f(xi, goals), [[0.1, 0.09, 0], [0, 0.12, 0]], atol=1e-12)
    g = create_si_position_controller(x_velocity_gain=2, y_velocity_gain=0.5, velocity_magnitude_limit=10)
    np.testing.assert_allclose(g(col(1, 1), col(2, 3)), col(2, 1))


def test_clf_unicycle_position_controller():
    f = create_clf_unicycle_position_controller()
    states = np.zeros((3, 3))
    dxu = f(states, np.array([[1, 0, 0], [0, 1, 0]], dtype=float))
    # Ahead at 1 m: v = 0.8, omega = 0. Left at 1 m: v = 0, omega = 3. At the goal: 0.
    np.testing.assert_allclose(dxu, [[0.8, 0, 0], [0, 3, 0]], atol=1e-12)


def test_clf_unicycle_pose_controller_known_states(capsys):
    f = create_clf_unicycle_pose_controller()
    states = np.array([[0, 0, 0], [0, 0, 0], [0.3, 0, 0.3]], dtype=float)
    poses = np.array([[0, 1, 0], [0, 0, 0], [0, 0, -2.5]], dtype=float)
    dxu = f(states, poses)
    # Robot 0: at the goal position, heading error: e = 0, theta = 0, alpha = -0.3.
    a = -0.3
    np.testing.assert_allclose(dxu[:, 0], [0, 2.7 * a + np.cos(a) * np.sin(a)], atol=1e-12)
    # Robot 1: goal 1 m straight ahead and aligned: alpha = 0. Fix: rps gave NaN here.
    np.testing.assert_allclose(dxu[:, 1], [1, 0], atol=1e-12)
    # Robot 2: at the goal position, goal heading -2.5: theta must be 0 (rps saw pi, from -0.0).
    a = np.arctan2(np.sin(-2.8), np.cos(-2.8))
    np.testing.assert_allclose(dxu[:, 2], [0, 2.7 * a + np.cos(a) * np.sin(a)], atol=1e-12)
    assert capsys.readouterr().out == ""   # Fix: rps printed three lines per robot


def test_hybrid_pose_controller_modes():
    f = create_hybrid_unicycle_pose_controller()
    states = np.zeros((3, 4))
    poses = np.array([[1, 0.03, 0.01, 0.01], [0, 0, 0, 0], [0, 0, 1, 0.01]])
    dxu = f(states, poses)
    # Far: drive at the 0.15 m/s cap. 0.03 m away (> 0.05 - 0.03): still approaching, dxi =
    # (0.03, 0), v = 0.03. 0.01 m away with heading error 1: turn with omega = 2 * 1. Within both
    # tolerances: stop.
    np.testing.assert_allclose(dxu, [[0.15, 0.03, 0, 0], [0, 0, 2, 0]], atol=1e-12)
    # position_epsilon defaults to the guide's 0.03: at 0.025 m the robot approaches (rps 0.0.0,
    # with 0.02, would already turn).
    assert f(col(0, 0, 0), col(0.025, 0, 1))[0, 0] > 0


def test_hybrid_pose_controller_approach_state_in_place():
    f = create_hybrid_unicycle_pose_controller()
    state = np.ones(2)
    # Robot 0 reaches the position and starts turning: its flag drops to 0.
    dxu = f(np.zeros((3, 2)), np.array([[0.01, 1], [0, 0], [1, 0]]), state)
    np.testing.assert_array_equal(state, [0, 1])
    # Next call, robot 0 has drifted 0.03 m (> 0.02, < 0.05): in turning mode it keeps turning
    # (without the state it would drive back), and stays flagged 0.
    dxu = f(np.zeros((3, 2)), np.array([[0.03, 1], [0, 0], [1, 0]]), state)
    np.testing.assert_allclose(dxu[:, 0], [0, 2])
    np.testing.assert_array_equal(state, [0, 1])
    assert f(np.zeros((3, 1)), np.array([[0.03], [0], [1]]))[0, 0] > 0
    # Drifted beyond position_error while turning: approach again (rps overwrote the array here).
    state2 = np.zeros((1, 2))
    f(np.zeros((3, 2)), np.array([[0.06, 0.01], [0, 0], [1, 1]]), state2)
    np.testing.assert_array_equal(state2, [[1, 0]])


# --------------------------------------------------------------------------------------------
# Miscellaneous
# --------------------------------------------------------------------------------------------

def test_at_pose_and_at_position_indices():
    states = np.array([[0, 0.06, 0, 0, 1], [0, 0, 0, 0, 1], [0, 0, 0.3, 2 * PI - 0.1, 0]])
    poses = np.array([[0, 0, 0, 0, 1.04], [0, 0, 0, 0, 1.0], [0, 0, 0, 0, 0.19]])
    # 0: exact. 1: 6 cm off. 2: 0.3 rad off. 3: 2pi - 0.1 wraps to 0.1. 4: 4 cm and 0.19 rad.
    done = at_pose(states, poses)
    assert isinstance(done, tuple) and len(done) == 1
    np.testing.assert_array_equal(done[0], [0, 3, 4])
    assert np.size(at_pose(states, poses, rotation_error=100)) == 4
    # Fix: rps's at_position raised NameError (it referred to an undefined `poses`).
    np.testing.assert_array_equal(at_position(states, poses[:2])[0], [0, 2, 3])
    np.testing.assert_array_equal(at_position(states, poses[:2], position_error=0.1)[0], [0, 1, 2, 3, 4])


@pytest.mark.parametrize("N", [1, 7, 50])
def test_generate_initial_conditions_spacing_and_area(N):
    poses = generate_initial_conditions(N)
    assert poses.shape == (3, N)
    assert np.all(np.abs(poses[0]) <= 1.5 + 1e-9) and np.all(np.abs(poses[1]) <= 0.9 + 1e-9)
    assert np.all((poses[2] >= -PI) & (poses[2] < PI))
    gaps = np.linalg.norm(poses[:2, :, None] - poses[:2, None, :], axis=0) + 10 * np.eye(N)
    assert gaps.min() >= 0.3 - 1e-9
    # The Robotarium's own call (rps: spacing 0.2 in 2.5 x 1.5 m) stays inside the arena.
    p = generate_initial_conditions(N, spacing=0.2, width=2.5, height=1.5)
    assert np.all(np.abs(p[0]) <= 1.25 + 1e-9) and np.all(np.abs(p[1]) <= 0.75 + 1e-9)


def test_generate_initial_conditions_uses_the_global_seed():
    np.random.seed(42)
    a = generate_initial_conditions(10)
    np.random.seed(42)
    b = generate_initial_conditions(10)
    c = generate_initial_conditions(10)
    assert np.array_equal(a, b) and not np.array_equal(b, c)


class _Figure:
    """A stand-in for a Robotarium with show_figure=True: an Agg axes set up as rps does."""

    def __init__(self, figsize, dpi):
        self.boundaries = [-1.6, -1, 3.2, 2]
        self.figure, self.axes = plt.subplots(figsize=figsize, dpi=dpi)
        self.axes.set_xlim(-1.7, 1.7)
        self.axes.set_ylim(-1.1, 1.1)
        self.figure.subplots_adjust(left=-0.03, right=1.03, bottom=-0.03, top=1.03, wspace=0, hspace=0)


FIGURES = [((6.4, 4.8), 100), ((10, 6.25), 80)]
_FIGURE_CODE = """
import matplotlib.pyplot as plt
from rps.utilities.misc import determine_marker_size, determine_font_size
class R: pass
result["sizes"] = []
for figsize, dpi in figures:
    r = R(); r.boundaries = [-1.6, -1, 3.2, 2]
    r.figure, r.axes = plt.subplots(figsize=figsize, dpi=dpi)
    r.axes.set_xlim(-1.7, 1.7); r.axes.set_ylim(-1.1, 1.1)
    r.figure.subplots_adjust(left=-0.03, right=1.03, bottom=-0.03, top=1.03, wspace=0, hspace=0)
    result["sizes"].append([determine_marker_size(r, m) for m in (0.05, 0.2, 0.5)]
                           + [determine_font_size(r, h) for h in (0.05, 0.1)])
"""


def test_marker_and_font_size_scale_with_the_request():
    r = _Figure(*FIGURES[0])
    assert determine_marker_size(r, 0.4) == pytest.approx(4 * determine_marker_size(r, 0.2))
    assert determine_font_size(r, 0.2) == pytest.approx(2 * determine_font_size(r, 0.1))
    plt.close(r.figure)


# --------------------------------------------------------------------------------------------
# Graph
# --------------------------------------------------------------------------------------------

def test_fixed_laplacians_by_hand():
    np.testing.assert_array_equal(cycle_GL(4), [[2, -1, 0, -1], [-1, 2, -1, 0], [0, -1, 2, -1], [-1, 0, -1, 2]])
    np.testing.assert_array_equal(lineGL(4), [[1, -1, 0, 0], [-1, 2, -1, 0], [0, -1, 2, -1], [0, 0, -1, 1]])
    np.testing.assert_array_equal(completeGL(3), [[2, -1, -1], [-1, 2, -1], [-1, -1, 2]])
    # Fix: degenerate sizes are Laplacians (rps: cycle_GL(1) = [[-1]], cycle_GL(2) rows sum to 1,
    # lineGL(1) = [[1]]).
    np.testing.assert_array_equal(cycle_GL(1), [[0]])
    np.testing.assert_array_equal(cycle_GL(2), [[1, -1], [-1, 1]])
    np.testing.assert_array_equal(lineGL(1), [[0]])
    np.testing.assert_array_equal(completeGL(1), [[0]])


def _is_laplacian(L):
    off = L - np.diag(np.diag(L))
    return (np.array_equal(L, L.T) and np.allclose(L.sum(axis=1), 0)
            and set(np.unique(off)) <= {0.0, -1.0})


@pytest.mark.parametrize("v,e", [(1, 0), (2, 3), (6, 0), (6, 4), (8, 100)])
def test_random_laplacians(v, e):
    L = random_connectedGL(v, e)
    assert _is_laplacian(L)
    edges = np.count_nonzero(np.triu(L, 1))
    assert edges == v - 1 + min(e, (v - 1) * (v - 2) // 2)
    assert v == 1 or np.sort(np.linalg.eigvalsh(L))[1] > 1e-9   # connected
    R = randomGL(v, e)
    assert _is_laplacian(R) and np.count_nonzero(np.triu(R, 1)) == min(e, v * (v - 1) // 2)


def test_topological_neighbors_leaves_L_alone():
    L = cycle_GL(5)
    before = L.copy()
    np.testing.assert_array_equal(topological_neighbors(L, 0), [1, 4])
    np.testing.assert_array_equal(topological_neighbors(L, np.int64(2)), [1, 3])
    np.testing.assert_array_equal(L, before)   # Fix: rps zeroed L[agent, agent]
    assert topological_neighbors(completeGL(1), 0).size == 0


def test_delta_disk_neighbors_inclusive_and_excluding_self():
    poses = np.array([[0, 0.5, 0, 2.0], [0, 0, 0.25, 0], [0, 1, 2, 3]])
    np.testing.assert_array_equal(delta_disk_neighbors(poses, 0, 0.5), [1, 2])
    np.testing.assert_array_equal(delta_disk_neighbors(poses, 0, 0.4), [2])
    np.testing.assert_array_equal(delta_disk_neighbors(poses, 3, 1.0), [])
    np.testing.assert_array_equal(delta_disk_neighbors(poses[:2], 1, 10), [0, 2, 3])


# --------------------------------------------------------------------------------------------
# Argument errors: RobotariumError (also an AssertionError, as rps's asserts) naming the argument
# --------------------------------------------------------------------------------------------

_si = create_si_to_uni_dynamics()
_map, _states = create_si_to_uni_mapping()
_ctl = create_si_position_controller()
_hyb = create_hybrid_unicycle_pose_controller()
_Z2, _Z3 = np.zeros((2, 3)), np.zeros((3, 3))

BAD_CALLS = [
    ("linear_velocity_gain", lambda: create_si_to_uni_dynamics(linear_velocity_gain=0)),
    ("angular_velocity_limit", lambda: create_si_to_uni_dynamics(angular_velocity_limit=-1)),
    ("angular_velocity_limit", lambda: create_si_to_uni_dynamics(angular_velocity_limit=np.inf)),
    ("linear_velocity_gain", lambda: create_si_to_uni_dynamics_with_backwards_motion(linear_velocity_gain="1")),
    ("angular_velocity_limit", lambda: create_si_to_uni_mapping(angular_velocity_limit=-0.5)),
    ("projection_distance", lambda: create_si_to_uni_mapping(projection_distance=0)),
    ("projection_distance", lambda: create_uni_to_si_dynamics(projection_distance=np.nan)),
    ("dxi", lambda: _si([[1.0], [0.0]], np.zeros((3, 1)))),
    ("dxi", lambda: _si(np.zeros((3, 3)), _Z3)),
    ("poses", lambda: _si(_Z2, np.zeros((3, 2)))),
    ("poses", lambda: _si(_Z2, np.zeros((2, 3)))),
    ("dxi", lambda: _si(np.array([[np.nan, 0, 0], [0, 0, 0]]), _Z3)),
    ("poses", lambda: _map(_Z2, np.array([[0, 0, 0], [0, 0, 0], [np.inf, 0, 0]]))),
    ("poses", lambda: _states(np.zeros(3))),
    ("dxu", lambda: create_uni_to_si_dynamics()(np.zeros((2, 3), dtype=object), _Z3)),
    ("x_velocity_gain", lambda: create_si_position_controller(x_velocity_gain=-1)),
    ("y_velocity_gain", lambda: create_si_position_controller(y_velocity_gain=True)),
    ("velocity_magnitude_limit", lambda: create_si_position_controller(velocity_magnitude_limit=-0.1)),
    ("positions", lambda: _ctl(_Z2, np.zeros((2, 4)))),
    ("linear_velocity_gain", lambda: create_clf_unicycle_position_controller(linear_velocity_gain=-1)),
    ("positions", lambda: create_clf_unicycle_position_controller()(_Z3, _Z3)),
    ("desired_angle_gain", lambda: create_clf_unicycle_pose_controller(desired_angle_gain=np.nan)),
    ("states", lambda: create_clf_unicycle_pose_controller()(_Z2, _Z3)),
    ("position_epsilon", lambda: create_hybrid_unicycle_pose_controller(position_epsilon=-0.01)),
    ("rotation_error", lambda: create_hybrid_unicycle_pose_controller(rotation_error=None)),
    ("input_approach_state", lambda: _hyb(_Z3, _Z3, np.ones(4))),
    ("input_approach_state", lambda: _hyb(_Z3, _Z3, [1, 1, 1])),
    ("N", lambda: generate_initial_conditions(0)),
    ("N", lambda: generate_initial_conditions(51)),
    ("N", lambda: generate_initial_conditions(2.0)),
    ("spacing", lambda: generate_initial_conditions(3, spacing=0)),
    ("width", lambda: generate_initial_conditions(3, width=np.inf)),
    ("height", lambda: generate_initial_conditions(3, spacing=0.5, height=0.4)),
    ("N", lambda: generate_initial_conditions(20, spacing=0.5, width=2, height=2)),
    ("N", lambda: generate_initial_conditions(8, spacing=0.5, width=2, height=1)),   # rps: N < cells
    ("poses", lambda: at_pose(_Z3, np.zeros((3, 2)))),
    ("rotation_error", lambda: at_pose(_Z3, _Z3, rotation_error=-1)),
    ("points", lambda: at_position(_Z3, _Z3)),
    ("position_error", lambda: at_position(_Z3, _Z2, position_error="0.1")),
    ("robotarium_instance", lambda: determine_marker_size(type("R", (), {"axes": [], "boundaries": [-1.6, -1, 3.2, 2]})(), 0.1)),
    ("robotarium_instance", lambda: determine_font_size(object(), 0.1)),
    ("N", lambda: cycle_GL(0)),
    ("N", lambda: lineGL(np.float64(3))),
    ("N", lambda: completeGL(-2)),
    ("v", lambda: random_connectedGL(0, 1)),
    ("e", lambda: random_connectedGL(3, -1)),
    ("v", lambda: randomGL(1.5, 1)),
    ("e", lambda: randomGL(3, -1)),
    ("agent", lambda: topological_neighbors(cycle_GL(3), 3)),
    ("agent", lambda: topological_neighbors(cycle_GL(3), -1)),
    ("L", lambda: topological_neighbors(np.zeros((2, 3)), 0)),
    ("agent", lambda: delta_disk_neighbors(_Z3, 3, 1.0)),
    ("delta", lambda: delta_disk_neighbors(_Z3, 0, -1.0)),
    ("poses", lambda: delta_disk_neighbors(np.array([[0, np.nan], [0, 0]]), 0, 1.0)),
]


@pytest.mark.parametrize("name,call", BAD_CALLS, ids=["%d-%s" % (i, n) for i, (n, _) in enumerate(BAD_CALLS)])
def test_bad_arguments_raise_naming_the_argument(name, call):
    with pytest.raises(RobotariumError) as info:
        call()
    assert isinstance(info.value, AssertionError) and isinstance(info.value, ValueError)
    message = str(info.value)
    assert name in message and "received" in message and "must" in message


def test_marker_size_argument_checked():
    r = _Figure(*FIGURES[0])
    with pytest.raises(RobotariumError, match="marker_size_meters"):
        determine_marker_size(r, -0.1)
    with pytest.raises(RobotariumError, match="font_height_meters"):
        determine_font_size(r, np.nan)
    plt.close(r.figure)


# --------------------------------------------------------------------------------------------
# Star imports
# --------------------------------------------------------------------------------------------

def _star(module):
    namespace = {}
    exec("from rps.utilities.%s import *" % module, namespace)
    namespace.pop("__builtins__")
    return namespace


@pytest.mark.parametrize("module", ["transformations", "controllers", "misc", "graph"])
def test_star_import_brings_np(module):
    namespace = _star(module)
    assert namespace["np"] is np
    assert not any(name.startswith("_") for name in namespace)
    if module == "misc":
        assert namespace["plt"] is plt


def test_barrier_certificate_shims():
    pytest.importorskip("robotarium_safety.barrier_certificates")
    one, two = _star("barrier_certificates"), _star("barrier_certificates2")
    expected = {
        "create_single_integrator_barrier_certificate", "create_single_integrator_barrier_certificate_with_boundary",
        "create_single_integrator_barrier_certificate2", "create_unicycle_barrier_certificate",
        "create_unicycle_barrier_certificate_with_boundary", "create_unicycle_barrier_certificate2",
        "create_unicycle_differential_drive_barrier_certificate",
        "create_unicycle_differential_drive_barrier_certificate_with_boundary",
        "create_si_barrier_certificate", "create_si_barrier_certificate_with_boundary",
        "create_uni_barrier_certificate", "create_uni_barrier_certificate_with_boundary",
    }
    assert expected | set(_star("transformations")) <= set(one)
    safety = pytest.importorskip("robotarium_safety.barrier_certificates")
    assert all(one[name] is getattr(safety, name) for name in expected)   # re-exported, not copied
    assert one["create_si_to_uni_mapping"] is create_si_to_uni_mapping
    assert one["np"] is np and two["np"] is np
    assert two["create_robust_barriers"] is safety.create_robust_barriers


def test_guide_import_header_gives_the_toolbox():
    # The guide's scripts start with these star imports (guide 4.1) and then use np, plt and the
    # toolbox without importing them again.
    pytest.importorskip("robotarium_safety.barrier_certificates")
    namespace = {}
    exec("from rps.utilities.transformations import *\n"
         "from rps.utilities.graph import *\n"
         "from rps.utilities.barrier_certificates import *\n"
         "from rps.utilities.misc import *\n"
         "from rps.utilities.controllers import *\n", namespace)
    assert namespace["np"] is np and namespace["plt"] is plt
    for name in ("create_si_to_uni_mapping", "create_si_position_controller", "cycle_GL",
                 "generate_initial_conditions", "at_pose", "determine_marker_size",
                 "create_unicycle_barrier_certificate_with_boundary"):
        assert callable(namespace[name]), name


# --------------------------------------------------------------------------------------------
# Agreement with the reference simulator on random inputs
# --------------------------------------------------------------------------------------------

N_RANDOM = 40
_rng = np.random.default_rng(20240611)
INPUTS = {
    "dxi": _rng.normal(scale=0.2, size=(2, N_RANDOM)),
    "dxu": np.vstack((_rng.uniform(-0.2, 0.2, N_RANDOM), _rng.uniform(-3, 3, N_RANDOM))),
    "states": np.vstack((_rng.uniform(-1.5, 1.5, (1, N_RANDOM)), _rng.uniform(-0.9, 0.9, (1, N_RANDOM)),
                         _rng.uniform(-PI, PI, (1, N_RANDOM)))),
    "goals": np.vstack((_rng.uniform(-1.5, 1.5, (1, N_RANDOM)), _rng.uniform(-0.9, 0.9, (1, N_RANDOM)),
                        _rng.uniform(-PI, PI, (1, N_RANDOM)))),
}
# Goals close to the states, so the "close enough" tests and the hybrid controller's turn and
# stop modes are exercised as well as its approach mode.
_near = _rng.uniform(0, 0.07, N_RANDOM) * np.exp(1j * _rng.uniform(-PI, PI, N_RANDOM))
INPUTS["near"] = INPUTS["states"] + np.vstack((_near.real, _near.imag, _rng.uniform(-0.4, 0.4, N_RANDOM)))
INPUTS["figures"] = FIGURES
INPUTS["seeds"] = [0, 1, 7, 123]
INPUTS["graph_sizes"] = [(1, 0), (2, 1), (5, 0), (5, 3), (7, 4), (9, 40)]

_REFERENCE_CODE = """
import io, contextlib
import numpy as np
from rps.utilities.transformations import *
from rps.utilities.controllers import *
from rps.utilities.misc import *
from rps.utilities.graph import *

def star(module):
    ns = {}
    exec("from rps.utilities.%s import *" % module, ns)
    return sorted(k for k in ns if k != "__builtins__")
result["star"] = {m: star(m) for m in ("transformations", "controllers", "misc", "graph")}

result["si_to_uni"] = create_si_to_uni_dynamics()(dxi, states)
result["si_to_uni_gain"] = create_si_to_uni_dynamics(0.7, 1.3)(dxi, states)
result["backwards"] = create_si_to_uni_dynamics_with_backwards_motion(1.2, 2.0)(dxi, states)
m, s = create_si_to_uni_mapping(projection_distance=0.08, angular_velocity_limit=2.0)
result["mapping"] = m(dxi, states)
result["mapping_states"] = s(states)
result["uni_to_si"] = create_uni_to_si_dynamics(0.07)(dxu, states)

result["si_ctl"] = create_si_position_controller()(states[:2], goals[:2])
result["si_ctl_gains"] = create_si_position_controller(1.3, 0.7, 0.1)(states[:2], near[:2])
result["clf_pos"] = create_clf_unicycle_position_controller()(states, goals[:2])
result["clf_pos_gains"] = create_clf_unicycle_position_controller(0.5, 2)(states, near[:2])
with contextlib.redirect_stdout(io.StringIO()):   # rps's pose controller prints
    result["clf_pose"] = create_clf_unicycle_pose_controller()(states, goals)
    result["clf_pose_gains"] = create_clf_unicycle_pose_controller(0.8, 3, 1.5)(states, near)
hybrid = create_hybrid_unicycle_pose_controller(position_epsilon=0.03)
result["hybrid_far"] = hybrid(states, goals)
result["hybrid_near"] = hybrid(states, near)
result["hybrid_gains"] = create_hybrid_unicycle_pose_controller(0.8, 1.5, 0.1, 2.0, 0.04, 0.01, 0.1)(states, near)

result["at_pose"] = at_pose(states, near)[0]
result["at_pose_loose"] = at_pose(states, near, 0.06, 0.3)[0]
try:
    at_position(states, near[:2], 0.04)
    result["at_position_error"] = None
except Exception as error:   # rps's at_position refers to an undefined name
    result["at_position_error"] = type(error).__name__

result["initial"] = []
for seed in seeds:
    for N, kwargs in ((1, {}), (12, {}), (50, {}), (20, dict(spacing=0.2, width=2.5, height=1.5)),
                      (6, dict(spacing=0.35, width=2.9, height=1.7))):
        np.random.seed(seed)
        result["initial"].append(generate_initial_conditions(N, **kwargs))

result["fixed_graphs"] = [(cycle_GL(n), lineGL(n), completeGL(n)) for n in range(3, 9)]
result["random_graphs"] = []
for seed in seeds:
    for v, e in graph_sizes:
        np.random.seed(seed)
        a = random_connectedGL(v, e)
        b = randomGL(v, e)
        result["random_graphs"].append((a, b, np.random.rand()))   # and where the stream ended
result["topological"] = [[topological_neighbors(L.copy(), i) for i in range(L.shape[0])]
                         for L, _, _ in result["random_graphs"]]
result["delta_disk"] = [[delta_disk_neighbors(states, i, d) for i in range(states.shape[1])] for d in (0.3, 0.8)]
""" + _FIGURE_CODE


@pytest.fixture(scope="module")
def ref():
    if not reference_available():
        pytest.skip("the reference venv (.venv-reference) is missing: run ./robotarium setup")
    return run_reference(_REFERENCE_CODE, **INPUTS)


def test_reference_star_import_names(ref):
    for module, names in ref["star"].items():
        assert sorted(_star(module)) == names, module


def test_reference_transformations(ref):
    dxi, dxu, states = INPUTS["dxi"], INPUTS["dxu"], INPUTS["states"]
    np.testing.assert_allclose(create_si_to_uni_dynamics()(dxi, states), ref["si_to_uni"], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(create_si_to_uni_dynamics(0.7, 1.3)(dxi, states), ref["si_to_uni_gain"],
                               rtol=1e-12, atol=1e-14)
    # rps's backwards mapping is the forward one, and so is ours
    ours = create_si_to_uni_dynamics_with_backwards_motion(1.2, 2.0)(dxi, states)
    np.testing.assert_allclose(ours, ref["backwards"], rtol=1e-12, atol=1e-14)
    m, s = create_si_to_uni_mapping(projection_distance=0.08, angular_velocity_limit=2.0)
    np.testing.assert_allclose(m(dxi, states), ref["mapping"], rtol=1e-12, atol=1e-14)
    assert np.any(np.abs(ref["mapping"][1]) == 2.0)   # the clip is exercised
    np.testing.assert_allclose(s(states), ref["mapping_states"], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(create_uni_to_si_dynamics(0.07)(dxu, states), ref["uni_to_si"], rtol=1e-12, atol=1e-14)


def test_reference_controllers(ref):
    states, goals, near = INPUTS["states"], INPUTS["goals"], INPUTS["near"]
    close = dict(rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(create_si_position_controller()(states[:2], goals[:2]), ref["si_ctl"], **close)
    np.testing.assert_allclose(create_si_position_controller(1.3, 0.7, 0.1)(states[:2], near[:2]),
                               ref["si_ctl_gains"], **close)
    np.testing.assert_allclose(create_clf_unicycle_position_controller()(states, goals[:2]), ref["clf_pos"], **close)
    np.testing.assert_allclose(create_clf_unicycle_position_controller(0.5, 2)(states, near[:2]),
                               ref["clf_pos_gains"], **close)
    np.testing.assert_allclose(create_clf_unicycle_pose_controller()(states, goals), ref["clf_pose"], **close)
    np.testing.assert_allclose(create_clf_unicycle_pose_controller(0.8, 3, 1.5)(states, near),
                               ref["clf_pose_gains"], **close)
    hybrid = create_hybrid_unicycle_pose_controller()   # our default epsilon is rps's later 0.03
    np.testing.assert_allclose(hybrid(states, goals), ref["hybrid_far"], **close)
    near_out = hybrid(states, near)
    np.testing.assert_allclose(near_out, ref["hybrid_near"], **close)
    # All three modes occur among the near goals.
    assert np.any(near_out[0] != 0) and np.any((near_out[0] == 0) & (near_out[1] != 0))
    assert np.any(np.all(near_out == 0, axis=0))
    np.testing.assert_allclose(create_hybrid_unicycle_pose_controller(0.8, 1.5, 0.1, 2.0, 0.04, 0.01, 0.1)(states, near),
                               ref["hybrid_gains"], **close)


def test_reference_misc(ref):
    states, near = INPUTS["states"], INPUTS["near"]
    np.testing.assert_array_equal(at_pose(states, near)[0], ref["at_pose"])
    np.testing.assert_array_equal(at_pose(states, near, 0.06, 0.3)[0], ref["at_pose_loose"])
    assert 0 < len(ref["at_pose_loose"]) < N_RANDOM
    # Fix: rps's at_position never worked (NameError); ours matches the same test done by hand.
    assert ref["at_position_error"] == "NameError"
    distance = np.linalg.norm(states[:2] - near[:2], axis=0)
    np.testing.assert_array_equal(at_position(states, near[:2], 0.04)[0], np.nonzero(distance <= 0.04)[0])
    assert 0 < np.count_nonzero(distance <= 0.04) < N_RANDOM
    ours = []
    for seed in INPUTS["seeds"]:
        for N, kwargs in ((1, {}), (12, {}), (50, {}), (20, dict(spacing=0.2, width=2.5, height=1.5)),
                          (6, dict(spacing=0.35, width=2.9, height=1.7))):
            np.random.seed(seed)
            ours.append(generate_initial_conditions(N, **kwargs))
    assert len(ours) == len(ref["initial"])
    for a, b in zip(ours, ref["initial"]):
        np.testing.assert_array_equal(a, b)


def test_reference_plot_sizes(ref):
    for (figsize, dpi), expected in zip(FIGURES, ref["sizes"]):
        r = _Figure(figsize, dpi)
        ours = [determine_marker_size(r, m) for m in (0.05, 0.2, 0.5)] + [determine_font_size(r, h) for h in (0.05, 0.1)]
        plt.close(r.figure)
        np.testing.assert_allclose(ours, expected, rtol=1e-12)


def test_reference_graphs(ref):
    for n, (c, l, k) in zip(range(3, 9), ref["fixed_graphs"]):
        np.testing.assert_array_equal(cycle_GL(n), c)
        np.testing.assert_array_equal(lineGL(n), l)
        np.testing.assert_array_equal(completeGL(n), k)
    index = 0
    for seed in INPUTS["seeds"]:
        for v, e in INPUTS["graph_sizes"]:
            np.random.seed(seed)
            a, b = random_connectedGL(v, e), randomGL(v, e)
            ref_a, ref_b, ref_next = ref["random_graphs"][index]
            np.testing.assert_array_equal(a, ref_a)
            np.testing.assert_array_equal(b, ref_b)
            assert np.random.rand() == ref_next   # same number of draws from the global stream
            for i in range(v):
                np.testing.assert_array_equal(topological_neighbors(a, i), ref["topological"][index][i])
            index += 1
    states = INPUTS["states"]
    for d, expected in zip((0.3, 0.8), ref["delta_disk"]):
        for i in range(states.shape[1]):
            np.testing.assert_array_equal(delta_disk_neighbors(states, i, d), expected[i])
