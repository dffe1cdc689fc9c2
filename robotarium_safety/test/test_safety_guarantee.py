"""The safety node's guarantee, searched for counter-examples (issue 16).

The guarantee (robotarium_safety.barrier_certificates, module docstring): whatever the requested
commands, the commands the safety node sends keep every two robot centres more than
robot_diameter apart (the collision rule of the simulator and the debug report) and every robot
inside the arena, step after step. Here the requests of random and adversarial scripts go
through the node's certificate, built from the testbed configuration as the node builds it, and
the node's own processing (scaling to the wheel limits along the arc before the certificate and,
where it changed a command, after it; a stop on a solver failure) into robotarium_core.model.Testbed,
the simulator's model: its collision and boundary counters must stay at zero. An adversary may
also scale or stop any robot's command after the filter (a command timeout, a dropped message):
the guarantee holds for any such scaling.

hypothesis draws the scenes (pairs head-on, side by side and back to back, lines, crowds up to
50, robots at the walls, goals packed 0.2 m apart) and the scripts (constant, random, huge,
pursuing the nearest robot, reversing, bang-bang, going to packed goals); derandomized, so CI runs
the same cases every time. Every counter-example a search ever found, minimised, is kept below as
an explicit regression case (REGRESSIONS), with what it broke.
"""
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robotarium_core import model
from robotarium_core.config import DEFAULT, TestbedConfig
from robotarium_safety import barrier_certificates as bc
from robotarium_safety.guard import Guard, filter_commands
from robotarium_safety.testbed_certificate import TestbedCertificate

ARENA = DEFAULT.arena


def node_certificate(config=DEFAULT, latency=0.0, real_time=False):
    """The safety node's certificate, made as the node makes it (SafetyNode.__init__, on_arm)."""
    return TestbedCertificate(config, latency, real_time)


def closest_pair(poses):
    if poses.shape[1] < 2:
        return np.inf
    i, j = model.robot_pairs(poses.shape[1])
    return float(np.hypot(poses[0, i] - poses[0, j], poses[1, i] - poses[1, j]).min())


def run_guarded(poses, script, steps, adversary=None, config=DEFAULT, allow_fallback=False):
    """Run `script(k, poses) -> 2 x N request` for `steps` steps through the node's filter and
    the model; fail on any collision or boundary violation the model counts. Returns
    (closest centre distance seen, the testbed)."""
    testbed = model.Testbed(poses, config)
    certificate = node_certificate(config)
    n = testbed.number_of_robots
    closest = closest_pair(testbed.poses)
    for k in range(steps):
        requested = np.array(script(k, testbed.poses.copy()), dtype=float).reshape(2, n)
        filtered = filter_commands(certificate, requested, testbed.poses.copy(), config)
        safe = filtered.safe
        assert allow_fallback or not filtered.fell_back, "step %d: the solver failed (%s)" % (
            k, certificate.info["reason"])
        if adversary is not None:
            safe = safe * adversary(k)[None, :]
        testbed.set_commands(np.arange(n), safe[0], safe[1])
        testbed.step()
        closest = min(closest, closest_pair(testbed.poses))
        assert closest > config.robot_diameter, "step %d: centres %.6f m apart" % (k, closest)
        assert not np.any(model.outside_arena(testbed.poses, config.arena)), "step %d: a robot left the arena" % k
    testbed.step()  # the model counts the last poses too
    assert testbed.collisions == 0 and testbed.boundary_violations == 0, testbed.report()
    return closest, testbed


# ---- scenes and scripts, written as data (a failing case prints as a spec to paste below) -------

def pair_scene(distance, bearing, heading_i, heading_j, cx=0.0, cy=0.0):
    """Two robots `distance` apart along `bearing`; headings relative to the bearing from i to j
    (0, 0: one behind the other; 0, pi: head-on; pi, 0: back to back; pi/2, pi/2: side by side)."""
    dx, dy = 0.5 * distance * np.cos(bearing), 0.5 * distance * np.sin(bearing)
    return np.array([[cx - dx, cx + dx], [cy - dy, cy + dy], [bearing + heading_i, bearing + heading_j]])


def line_scene(count, spacing, headings):
    x = (np.arange(count) - (count - 1) / 2) * spacing
    return np.vstack([x, np.zeros(count), np.resize(headings, count)])


def crowd_scene(count, spacing, seed):
    """The Robotarium's own draw of start poses (a grid of `spacing`, random headings)."""
    return model.random_initial_conditions(count, np.random.default_rng(seed), spacing=spacing)


def wall_scene(count, gap, edge, seed):
    """`count` robots `gap` from an edge ("top", "right") or on a diagonal into the top right corner
    (inside the arena, maybe past the boundary margin)."""
    headings = np.random.default_rng(seed).uniform(-np.pi, np.pi, count)
    x_min, x_max, y_min, y_max = ARENA
    along = np.linspace(-0.6, 0.6, count) if count > 1 else np.zeros(1)
    if edge == "top":
        return np.vstack([along, np.full(count, y_max - gap), headings])
    if edge == "right":
        return np.vstack([np.full(count, x_max - gap), 0.8 * along, headings])
    k = 0.15 * np.arange(count)
    return np.vstack([x_max - gap - k, y_max - gap - k, headings])


SCENES = {"pair": pair_scene, "line": line_scene, "crowd": crowd_scene, "wall": wall_scene}


def make_scene(spec):
    return SCENES[spec[0]](*spec[1:])


def constant(v, w):
    return lambda k, x: np.vstack([np.resize(v, x.shape[1]), np.resize(w, x.shape[1])])


def random_commands(seed, speed, turn):
    rng = np.random.default_rng(seed)
    return lambda k, x: np.vstack([rng.uniform(-speed, speed, x.shape[1]), rng.uniform(-turn, turn, x.shape[1])])


def bang_bang(period, v, w):
    return lambda k, x: np.vstack([np.full(x.shape[1], v if (k // period) % 2 else -v),
                                   np.full(x.shape[1], w if (k // (period + 1)) % 2 else -w)])


def pursue(reverse=False):
    """Every robot drives at its nearest neighbour (or backs into it), at full speed."""
    def script(k, x):
        n = x.shape[1]
        d = np.hypot(x[0][:, None] - x[0][None], x[1][:, None] - x[1][None]) + np.eye(n) * 1e9
        near = d.argmin(axis=1)
        facing = np.arctan2(x[1, near] - x[1], x[0, near] - x[0]) + (np.pi if reverse else 0.0)
        error = np.arctan2(np.sin(facing - x[2]), np.cos(facing - x[2]))
        return np.vstack([np.full(n, -0.2 if reverse else 0.2), 4 * error])
    return script


def go_to_goals(seed, gain=2.0):
    """A unicycle go-to-point controller (forwards or backwards, whichever is nearer) to goals
    packed as generate_initial_conditions draws them, on a grid 0.2 m apart."""
    def script(k, x):
        goals = crowd_scene(x.shape[1], 0.2, seed)[:2]
        e = goals - x[:2]
        error = np.arctan2(e[1], e[0]) - x[2]
        error = np.arctan2(np.sin(error), np.cos(error))
        backwards = np.abs(error) > np.pi / 2
        error = np.where(backwards, np.arctan2(np.sin(error + np.pi), np.cos(error + np.pi)), error)
        return np.vstack([gain * np.hypot(e[0], e[1]) * np.where(backwards, -1, 1), 4 * error])
    return script


SCRIPTS = {"constant": constant, "random": random_commands, "bang": bang_bang,
           "pursue": lambda: pursue(), "reverse": lambda: pursue(reverse=True), "goals": go_to_goals}


def make_script(spec):
    return SCRIPTS[spec[0]](*spec[1:])


def make_adversary(spec, count):
    """None, or ("scale", seed, p): with probability p a robot's filtered command is scaled by a
    random factor in [0, 1], often 0 (a stop: a command timeout, a dropped message)."""
    if spec is None:
        return None
    rng = np.random.default_rng(spec[1])
    return lambda k: np.where(rng.random(count) < spec[2], rng.choice([0.0, 0.3, 1.0], count) * rng.random(count), 1.0)


def run_case(scene, script, steps, adversary=None, **kwargs):
    poses = make_scene(scene)
    closest, testbed = run_guarded(poses, make_script(script), steps, make_adversary(adversary, poses.shape[1]),
                                   **kwargs)
    # never closer than the configured distance (or than they started, if they started closer)
    kept = min(closest_pair(poses), DEFAULT.robot_diameter + DEFAULT.collision_margin)
    assert closest >= kept - 1e-12, "centres %.6f m apart; the guard keeps %.6f m" % (closest, kept)
    return closest, testbed


# ---- the named adversarial cases, and every counter-example found so far ---------------------------

CASES = {
    # (scene, script, steps). With the node's certificate before its centre rows (the guide's rows
    # on the points ahead) the three crowds collided within 70 steps.
    "crowd of 50 pursuing their nearest neighbour": (("crowd", 50, 0.2, 3), ("pursue",), 150),
    "crowd of 50 reversing into their nearest neighbour": (("crowd", 50, 0.2, 3), ("reverse",), 150),
    "crowd of 50 going to goals packed 0.2 m apart": (("crowd", 50, 0.2, 3), ("goals", 4), 150),
    "head-on at full speed": (("pair", 0.3, 0.0, 0.0, np.pi), ("constant", 0.2, 0.0), 100),
    "side by side, turning into each other": (("pair", 0.111, np.pi / 2, -np.pi / 2, -np.pi / 2),
                                              ("constant", 0.2, [-3.0, 3.0]), 100),
    "back to back, reversing": (("pair", 0.13, 0.0, np.pi, 0.0), ("constant", -0.2, 0.0), 100),
    "a line of 8 nose to tail, all reversing": (("line", 8, 0.115, 0.0), ("constant", -0.3, 0.0), 100),
    "into a corner at full speed": (("wall", 6, 0.08, "corner", 1), ("constant", 0.2, 0.0), 100),
}

# Minimised counter-examples the search found (in CI and in longer runs with
# ROBOTARIUM_SAFETY_EXAMPLES=2000), each with what it broke: (scene, script, adversary, steps).
REGRESSIONS = {
    # Against the node's certificate before the centre rows: a robot 0.1101 m behind another, both
    # facing the same way; random commands drive the rear one into the front one at step 1 (its
    # point ahead is then inside the front robot, where the guide's rows only push points apart).
    "one robot right behind another, random commands": (
        ("pair", 0.1101, 0.0, 0.0, 0.0), ("random", 0, 0.4, 8.0), None, 200),
    # Liveness (no collision, but the solver failed: a stop at every step, forever). OSQP ran to
    # max_iter on this 2-robot QP, whose centre rows are parallel to its pair row, with the rho-
    # adaptation interval OSQP derives from its set-up time; fixed by a fixed interval
    # (barrier_qp.OSQP_SETTINGS["adaptive_rho_interval"]).
    "back to back 0.1133 m apart, both reversing: the solver stalled": (
        ("pair", 0.1133, 0.0, np.pi, 0.0), ("constant", -0.2, 0.0), None, 30),
    # Liveness: points ahead closer than the guide's 0.17 m had to be pushed apart while the centre
    # rows held robots facing a neighbour: no answer, a stop at every step (found first as 46
    # robots on a 0.15 m grid pursuing; this is its minimised form). Fixed: the node's pair rows
    # hold such points (bound clipped at 0), so standing still satisfies every row and the QP
    # always has an answer.
    "4 robots nose to tail 0.112 m apart: no feasible answer": (
        ("line", 4, 0.112, 0.0), ("constant", 0.2, 0.0), None, 30),
}


@pytest.mark.parametrize("name", list(CASES))
def test_adversarial_scenes_never_collide(name):
    scene, script, steps = CASES[name]
    run_case(scene, script, steps)


@pytest.mark.parametrize("name", list(REGRESSIONS))
def test_counter_examples_found_so_far(name):
    scene, script, adversary, steps = REGRESSIONS[name]
    run_case(scene, script, steps, adversary)


def test_the_guides_certificate_alone_lets_a_crowd_collide():
    """The crowd cases have teeth: with the guide's rows only (points ahead), robots collide."""
    guide = bc.create_unicycle_barrier_certificate_with_boundary()
    testbed = model.Testbed(make_scene(("crowd", 50, 0.2, 3)))
    script = pursue()
    for k in range(150):
        safe = guide(script(k, testbed.poses.copy()), testbed.poses.copy())
        testbed.set_commands(np.arange(50), safe[0], safe[1])
        testbed.step()
        if testbed.collisions:
            break
    assert testbed.collisions > 0


def test_the_guard_follows_the_configured_collision_rule():
    """One collision rule: with bigger robots configured, the node's certificate keeps their
    centres the configured diameter plus margin apart (and the model counts with that diameter)."""
    scene, script = ("crowd", 20, 0.3, 5), ("reverse",)
    closest, _ = run_case(scene, script, 250)
    assert closest < 0.2  # the default robots back up to within 0.2 m of each other
    big = TestbedConfig.from_dict({"robot_diameter": 0.2, "collision_margin": 0.01}, base=DEFAULT)
    closest, _ = run_guarded(make_scene(scene), make_script(script), 250, config=big)
    assert 0.21 - 1e-12 <= closest < 0.22


def test_a_robot_already_closer_than_the_margin_never_gets_closer():
    # 0.112 m apart (inside robot_diameter + collision_margin, outside robot_diameter), facing each other
    closest, testbed = run_case(("pair", 0.112, 0.3, 0.0, np.pi), ("constant", 0.2, 0.0), 100)
    assert closest == pytest.approx(0.112, abs=1e-12)


def test_a_pair_the_certificate_leaves_out_cannot_break_its_barrier_in_one_step():
    # The certificate poses no rows for a pair farther apart than cutoff(S). The bound: a step at
    # forward speed <= S moves each centre at most S T, so |e| shrinks by at most 2 S T and
    # h' >= (d - 2 S T)^2 - D^2 >= h - 4 S T d >= (1 - rate) h, the discrete barrier the rows keep.
    # Checked here on the simulator's own motion, at the cutoff and just beyond it, full speed.
    c = DEFAULT
    certificate = node_certificate()
    distance = certificate.distance
    rng = np.random.default_rng(26)
    limits = dict(c.limits, max_linear=10.0, max_wheel=1e3)   # no thresholding: the speed is S itself
    for speed in (c.max_linear_velocity, 0.4, 1.0):
        cutoff = certificate.cutoff(speed)
        for trial in range(400):
            d = cutoff * (1 + rng.uniform(0, 1e-3) * (trial % 2))
            angle = rng.uniform(-np.pi, np.pi)
            poses = np.array([[0.0, d * np.cos(angle)], [0.0, d * np.sin(angle)], rng.uniform(-np.pi, np.pi, 2)])
            if trial < 100:   # head-on: each centre drives straight at the other
                poses[2] = [angle, angle + np.pi]
            commands = np.array([speed * rng.choice([-1.0, 1.0], 2), rng.uniform(-3, 3, 2) * (trial >= 100)])
            after = model.lookahead_poses(poses, commands, c.time_step, **limits)
            h = d * d - distance ** 2
            h_after = np.sum((after[:2, 0] - after[:2, 1]) ** 2) - distance ** 2
            assert h_after >= (1 - c.barrier_rate) * h - 1e-12
            # ... and the certificate allows that speed either way: leaving the pair out changes nothing.
            low, high = certificate.intervals(poses, speed)
            assert np.all(low <= -speed * (1 - 1e-9)) and np.all(high >= speed * (1 - 1e-9))


def test_the_certificate_changes_nothing_beyond_its_reach():
    """The least change: a robot whose centre is at least cutoff(v_max) from every other and whose
    every edge gap exceeds v_max T / rate is never changed, whatever it is asked (within the limits)."""
    c = DEFAULT
    certificate = node_certificate()
    reach = certificate.cutoff(c.max_linear_velocity)
    edge = c.boundary_margin + c.max_linear_velocity * c.time_step / c.barrier_rate
    assert 0.19 < reach < 0.2 and edge < 0.05   # the numbers docs/safety.md gives
    rng = np.random.default_rng(36)
    x_min, x_max, y_min, y_max = c.arena
    for _ in range(300):
        n = int(rng.integers(2, 12))
        poses = np.vstack([rng.uniform(x_min + edge, x_max - edge, n), rng.uniform(y_min + edge, y_max - edge, n),
                           rng.uniform(-np.pi, np.pi, n)])
        d = np.hypot(poses[0][:, None] - poses[0][None], poses[1][:, None] - poses[1][None]) + np.eye(n) * 9
        free = d.min(axis=1) >= reach
        request = np.vstack([rng.uniform(-0.2, 0.2, n), rng.uniform(-3.6, 3.6, n)])
        safe = certificate(request, poses)
        np.testing.assert_array_equal(safe[:, free], request[:, free])
        np.testing.assert_array_equal(safe[1], request[1])   # a turn never moves a centre: never changed


def test_the_guard_changes_nothing_where_nothing_is_at_risk():
    f = node_certificate()
    request = np.array([[0.1, 0.1, 0.1], [0.5, -0.5, 0.0]])
    np.testing.assert_array_equal(f(request, line_scene(3, 0.5, 0.0)), request)
    assert f.info["status"] == "passthrough" and f.info["clamped"] == 0.0


# ---- the search ---------------------------------------------------------------------------------

angles = st.floats(-np.pi, np.pi)
headings = st.one_of(st.sampled_from([0.0, np.pi, np.pi / 2, -np.pi / 2]), angles)
seeds = st.integers(0, 2 ** 31 - 1)


@st.composite
def scenes(draw):
    kind = draw(st.sampled_from(["pair", "pair", "line", "crowd", "wall"]))
    if kind == "pair":
        return ("pair", draw(st.floats(0.1101, 0.4)), draw(angles), draw(headings), draw(headings),
                draw(st.floats(-1.4, 1.4)), draw(st.floats(-0.8, 0.8)))
    if kind == "line":
        return ("line", draw(st.integers(2, 8)), draw(st.floats(0.1101, 0.25)),
                draw(st.sampled_from([0.0, np.pi, (0.0, np.pi), (np.pi, 0.0), np.pi / 2])))
    if kind == "crowd":  # the slow cases: mostly small, now and then up to 50
        return ("crowd", draw(st.one_of(st.integers(2, 12), st.integers(13, 50))),
                draw(st.sampled_from([0.12, 0.15, 0.2])), draw(seeds))
    return ("wall", draw(st.integers(1, 6)), draw(st.floats(0.001, 0.1)), draw(st.sampled_from(["top", "right", "corner"])),
            draw(seeds))


@st.composite
def scripts(draw):
    kind = draw(st.sampled_from(["constant", "random", "huge", "bang", "pursue", "reverse", "goals"]))
    if kind == "constant":
        return ("constant", draw(st.lists(st.floats(-0.5, 0.5), min_size=1, max_size=6)),
                draw(st.lists(st.floats(-10, 10), min_size=1, max_size=6)))
    if kind == "random":
        return ("random", draw(seeds), 0.4, 8.0)
    if kind == "huge":
        return ("random", draw(seeds), 1e3, 1e3)
    if kind == "bang":
        return ("bang", draw(st.integers(1, 20)), draw(st.floats(0.0, 0.5)), draw(st.floats(0.0, 6.0)))
    if kind == "goals":
        return ("goals", draw(seeds))
    return (kind,)


adversaries = st.one_of(st.none(), st.tuples(st.just("scale"), seeds, st.floats(0.05, 0.5)))


# About 15 s on this project's 2-core machine. Search longer with ROBOTARIUM_SAFETY_EXAMPLES=2000
# (a failure prints the specs of its minimised case: add it to REGRESSIONS).
@pytest.mark.slow
@settings(max_examples=int(os.environ.get("ROBOTARIUM_SAFETY_EXAMPLES", "40")), deadline=None, derandomize=True,
          database=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(scene=scenes(), script=scripts(), adversary=adversaries, steps=st.sampled_from([200, 300]))
def test_search_for_a_collision_finds_none(scene, script, adversary, steps):
    run_case(scene, script, steps, adversary)


# ---- adversarial streams: whatever arrays reach the safety node (issue 22) ----------------------------
#
# The guarantee is about the commands applied, not about who sent them: a process that copied the
# token off the wire may send arrays with any step numbers, in bursts, in any order. Here the
# client's arrays and forged ones, interleaved at random with the deliveries of poses and of
# cmd_safe, go through the safety node's own decisions (robotarium_safety.guard.Guard and
# filter_commands, with the node's merge of a request into every robot's command) and the
# simulator's own rule (model.StepGate) into the model. Every array applied must have been
# filtered at the poses it moves the robots from (lockstep) or at those of the tick before (real
# time), and no step may ever end in a collision or outside the arena.

from robotarium_core import cdr  # noqa: E402


class NodeModel:
    """The safety node's handling of one experiment, without ROS: the guard decides, the node
    merges the request into the commands of all robots and filters them at its newest poses
    (SafetyNode.filter; a malformed request or no poses: a stop of every robot; None: the commands
    in force, filtered again)."""

    def __init__(self, n, real_time, config=DEFAULT):
        self.config, self.n = config, n
        self.guard = Guard(real_time, config.lockstep_wait, config.command_timeout)
        self.certificate = node_certificate(config, real_time=real_time)
        self.commands = np.zeros((2, n))
        self.poses, self.poses_step = None, -1
        self.sent = []   # (step, safe 2 x N, the poses step it was filtered at)

    def on_poses(self, step, poses, now=0.0):
        if step > self.poses_step:
            self.poses, self.poses_step = poses.copy(), step
        self.forward(self.guard.on_poses(step, now)[0])

    def on_requests(self, requests, now):
        """A batch taken at once (take_waiting); in real time only the newest counts."""
        if self.guard.real_time:
            requests = requests[-1:]
        for request in requests:
            self.forward(self.guard.on_request(request, now)[0])

    def forward(self, decisions):
        for request, step in decisions:
            if self.guard.real_time is False and step > 0:
                assert self.poses_step == step - 1, "the guard forwarded step %d at the poses of step %d" % (
                    step, self.poses_step)
            if self.poses is None or (request is not None and model.check_commands(
                    request.ids, request.v, request.omega, self.n) is not None):
                self.commands[:] = 0.0
                self.sent.append((step, np.zeros((2, self.n)), None))
                continue
            if request is not None:
                self.commands[0, request.ids] = request.v
                self.commands[1, request.ids] = request.omega
            safe = filter_commands(self.certificate, self.commands, self.poses, self.config).safe
            self.sent.append((step, safe, self.poses_step))


def commands(ids, v, w, step):
    ids = np.asarray(ids, dtype=np.int64)
    return cdr.Commands("t", step, ids, np.asarray(v, dtype=float), np.asarray(w, dtype=float), False, 0, 0)


def forged_burst(rng, n, seen, kind):
    """Arrays a forger sends at once: steps 0 (unnumbered), around the client's, or anywhere;
    robots all or some; commands full speed ahead, random, huge or malformed."""
    burst = []
    for _ in range(int(rng.integers(1, kind["burst"] + 1))):
        step = int(rng.choice([0, max(0, seen + int(rng.integers(-3, 4))), int(rng.integers(0, 10 ** 6))],
                              p=[0.4, 0.5, 0.1]))
        ids = np.arange(n) if rng.random() < 0.7 else np.sort(rng.choice(n, int(rng.integers(1, n + 1)), replace=False))
        how = rng.choice(["ahead", "random", "huge", "bad"], p=[0.5, 0.3, 0.15, 0.05])
        if how == "ahead":
            v, w = np.full(len(ids), 0.2), np.zeros(len(ids))
        elif how == "random":
            v, w = rng.uniform(-0.3, 0.3, len(ids)), rng.uniform(-5, 5, len(ids))
        elif how == "huge":
            v, w = rng.choice([-1e308, 1e308, 1e3], len(ids)), rng.uniform(-1e3, 1e3, len(ids))
        else:
            v, w = np.full(len(ids), np.nan), np.zeros(len(ids))
        burst.append(commands(ids, v, w, step))
    return burst


def check_step(testbed, config=DEFAULT):
    closest = closest_pair(testbed.poses)
    assert closest > config.robot_diameter, "step %d: centres %.6f m apart" % (testbed.steps, closest)
    outside = np.flatnonzero(model.outside_arena(testbed.poses, config.arena))
    assert not outside.size, "step %d: robots %s outside the arena at %s" % (
        testbed.steps, outside.tolist(), testbed.poses[:2, outside].round(3).tolist())


def run_lockstep_stream(poses, script, steps, seed, kind, config=DEFAULT):
    """A lockstep run of `script` as the client while a forger interleaves bursts: events in a
    random order (poses to the node, arrays to the node in any order, cmd_safe to the simulator,
    the client's next array, a burst, time passing). Returns the testbed."""
    rng = np.random.default_rng(seed)
    testbed, gate = model.Testbed(poses, config), model.StepGate(False)
    n = testbed.number_of_robots
    node = NodeModel(n, False, config)
    history = {0: testbed.poses.copy()}
    poses_queue, pool, safe_queue = [(0, testbed.poses.copy())], [], []
    client_sent, now = 0, 0.0
    for _ in range(steps * 40):
        if testbed.steps >= steps:
            break
        seen = testbed.steps   # the client sees each poses as they come
        action = rng.choice(["poses", "request", "safe", "client", "forge", "time"],
                            p=[0.2, 0.25, 0.2, 0.2, kind["forge"], 0.15 - kind["forge"]])
        if action == "poses" and poses_queue:
            node.on_poses(*poses_queue.pop(0))
        elif action == "request" and pool:
            take = min(len(pool), int(rng.integers(1, 6)))
            batch = [pool.pop(int(rng.integers(len(pool)))) for _ in range(take)]   # any order
            node.on_requests(batch, now)
        elif action == "client" and client_sent <= seen:
            client_sent = seen + 1
            request = np.array(script(seen, history[seen].copy()), dtype=float).reshape(2, n)
            pool.append(commands(np.arange(n), request[0], request[1], client_sent))
        elif action == "forge":
            pool.extend(forged_burst(rng, n, seen, kind))
        elif action == "time":
            now += float(rng.choice([0.01, 1.0, config.lockstep_wait + 0.1]))
            node.guard.expire(now)
        safe_queue.extend(node.sent)
        node.sent.clear()
        if action == "safe" and safe_queue:
            step, safe, filtered_at = safe_queue.pop(0)
            stop = not np.any(safe)
            if gate.admit(step, testbed.steps, stop=stop) is None:
                assert stop or filtered_at == testbed.steps, "applied an array filtered at step %s at step %d" % (
                    filtered_at, testbed.steps)
                testbed.set_commands(np.arange(n), safe[0], safe[1])
                testbed.step()
                check_step(testbed, config)
                history[testbed.steps] = testbed.poses.copy()
                poses_queue.append((testbed.steps, testbed.poses.copy()))
    testbed.step()
    assert testbed.collisions == 0 and testbed.boundary_violations == 0, testbed.report()
    return testbed


def run_real_time_stream(poses, script, ticks, seed, kind, config=DEFAULT):
    """A real-time run: each tick the simulator moves the robots with the commands in force and
    publishes poses; within a tick the poses reach the node, the client's array (computed from
    those poses, filtered at them or, when it came first, at the tick's before) and forged bursts
    reach it in a random order, and what the node sends reaches the simulator before the next tick
    or right after it, at random (the client keeping up with the ticks: README, real time)."""
    rng = np.random.default_rng(seed)
    testbed, gate = model.Testbed(poses, config), model.StepGate(True)
    n = testbed.number_of_robots
    node = NodeModel(n, True, config)
    history = {0: testbed.poses.copy()}
    late = []   # cmd_safe arrays that come after the next tick
    for tick in range(ticks):
        k = testbed.steps
        events = ["poses", "client"] + ["forge"] * int(rng.integers(0, kind["burst"] // 4 + 2) * (kind["forge"] > 0))
        rng.shuffle(events)
        now = tick * config.time_step

        def deliver(arrays):
            for step, safe, filtered_at in arrays:
                stop = not np.any(safe)
                if gate.admit(step, testbed.steps, stop=stop) is None:
                    assert stop or filtered_at in (testbed.steps, testbed.steps - 1), (
                        "applied an array filtered at step %s at step %d" % (filtered_at, testbed.steps))
                    testbed.set_commands(np.arange(n), safe[0], safe[1], now=now)
        deliver(late)
        late = []
        for event in events:
            if event == "poses":
                node.on_poses(k, testbed.poses, now)
            elif event == "client":
                request = np.array(script(k, history[k].copy()), dtype=float).reshape(2, n)
                node.on_requests([commands(np.arange(n), request[0], request[1], 0)], now)
            else:
                node.on_requests(forged_burst(rng, n, k, kind), now)
            if node.sent:
                if rng.random() < kind["late"]:
                    late.extend(node.sent)
                else:
                    deliver(node.sent)
                node.sent.clear()
        testbed.expire_commands(now + config.time_step, config.command_timeout)
        testbed.step()
        check_step(testbed, config)
        history[testbed.steps] = testbed.poses.copy()
    testbed.step()
    assert testbed.collisions == 0 and testbed.boundary_violations == 0, testbed.report()
    return testbed


# The attack: robots 0.3 m from a wall, facing it; the client keeps them still; a process
# with the copied token floods unnumbered arrays driving them at the wall at full speed.
AT_THE_WALL = ("wall", 4, 0.3, "right", 0)
STILL = ("constant", 0.0, 0.0)
FLOOD = {"burst": 40, "forge": 0.14, "late": 0.3}


def test_a_forger_with_the_token_cannot_push_robots_out_in_lockstep():
    poses = make_scene(AT_THE_WALL)
    poses[2] = 0.0   # facing the right wall
    testbed = run_lockstep_stream(poses, make_script(STILL), 300, 1, FLOOD)
    assert testbed.steps >= 300


@pytest.mark.slow
def test_a_forger_with_the_token_cannot_push_robots_out_in_real_time():
    poses = make_scene(AT_THE_WALL)
    poses[2] = 0.0
    run_real_time_stream(poses, make_script(STILL), 300, 1, FLOOD)


def test_without_the_step_rule_the_same_flood_pushes_robots_out():
    """The tests above have teeth: the rule before issue 22 (every forwarded array a lockstep step,
    each filtered at the node's newest poses, unnumbered ones always taken) lets the same forger
    drive the robots out of the arena, as the issue measured (0.3-0.5 m)."""
    poses = make_scene(AT_THE_WALL)
    poses[2] = 0.0
    testbed = model.Testbed(poses)
    certificate = node_certificate()
    n = testbed.number_of_robots
    known = testbed.poses.copy()   # the node's newest poses: a burst is filtered before the next come
    for _ in range(3):
        for _ in range(150):   # a burst of 150 forged step-0 arrays (1 kHz against ~300 steps/s), each a step
            safe = filter_commands(certificate, np.vstack([np.full(n, 0.2), np.zeros(n)]), known, DEFAULT).safe
            testbed.set_commands(np.arange(n), safe[0], safe[1])
            testbed.step()
        known = testbed.poses.copy()
    assert np.any(model.outside_arena(testbed.poses)), testbed.poses
    assert testbed.poses[0].max() > DEFAULT.arena[1] + 0.3


kinds = st.fixed_dictionaries({"burst": st.sampled_from([1, 5, 40]), "forge": st.sampled_from([0.0, 0.05, 0.14]),
                               "late": st.sampled_from([0.0, 0.3, 1.0])})


# About 20 s on this project's 2-core machine; search longer with ROBOTARIUM_STREAM_EXAMPLES=500.
@pytest.mark.slow
@settings(max_examples=int(os.environ.get("ROBOTARIUM_STREAM_EXAMPLES", "30")), deadline=None, derandomize=True,
          database=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(scene=scenes(), script=scripts(), seed=seeds, kind=kinds, real_time=st.booleans(),
       steps=st.sampled_from([100, 150]))
def test_search_for_a_stream_that_breaks_the_guarantee_finds_none(scene, script, seed, kind, real_time, steps):
    poses = make_scene(scene)
    if real_time:
        run_real_time_stream(poses, make_script(script), steps, seed, kind)
    else:
        run_lockstep_stream(poses, make_script(script), steps, seed, kind)
