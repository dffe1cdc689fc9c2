"""Barrier certificates of the Robotarium (guide §4.5, §4.6), solved with OSQP.

Each creator has the name, parameters and defaults of the guide and of the Robotarium Python
simulator it documents (robotarium-python-simulator 0.0.0, "rps": rps/utilities/
barrier_certificates.py and barrier_certificates2.py), and returns a function with the guide's
call signature that poses the same minimally invasive QP as its rps namesake, carrying `info`
(barrier_qp.new_info) about its last call. (The safety node's own certificate is
robotarium_safety.testbed_certificate: no QP.) Plain numpy + scipy + osqp: no ROS, no matplotlib.

The formulas, where they differ from rps on purpose and how they are solved:
docs/safety.md#the-certificates-in-formulas.
"""
import math
import numbers
import time

import numpy as np

from robotarium_core.model import (
    ARENA_X_MAX,
    ARENA_X_MIN,
    ARENA_Y_MAX,
    ARENA_Y_MIN,
    BASE_LENGTH,
    MAX_LINEAR_VELOCITY,
    MAX_WHEEL_VELOCITY,
    WHEEL_RADIUS,
    RobotariumError,
)

from .barrier_qp import NeighbourCache, QPSolver, Rows, cubic_cutoff_distance, end_call, new_info, reset_info

__all__ = [
    "create_single_integrator_barrier_certificate",
    "create_single_integrator_barrier_certificate_with_boundary",
    "create_single_integrator_barrier_certificate2",
    "create_unicycle_barrier_certificate",
    "create_unicycle_barrier_certificate_with_boundary",
    "create_unicycle_barrier_certificate2",
    "create_unicycle_differential_drive_barrier_certificate",
    "create_unicycle_differential_drive_barrier_certificate_with_boundary",
    "create_robust_barriers",
    "create_si_barrier_certificate",
    "create_si_barrier_certificate_with_boundary",
    "create_uni_barrier_certificate",
    "create_uni_barrier_certificate_with_boundary",
    "RobotariumError",
]

# Guide §4.5: "Safety Radius ... must be greater than or equal to 0.12 m"; for the differential-drive
# certificates (§4.5.7-4.5.8) "greater than or equal to 0.17 m".
MIN_SAFETY_RADIUS = 0.12
MIN_SAFETY_RADIUS_DIFFERENTIAL_DRIVE = 0.17
# rps create_si_to_uni_mapping(angular_velocity_limit=np.pi), used by the unicycle certificates.
ANGULAR_VELOCITY_LIMIT = np.pi
# The arena [x_min, x_max, y_min, y_max] (guide §4.5.2 default boundary_points).
_ARENA = (ARENA_X_MIN, ARENA_X_MAX, ARENA_Y_MIN, ARENA_Y_MAX)

# Leave out the pairs that provably cannot matter (the answer is the same either way). Tests turn
# it off to compare; it is read when a certificate is created.
PRUNING = True
# The single-integrator QP bounds no speed, so pruning assumes a bound on the answer's speeds and
# checks it afterwards (see _SingleIntegratorQP); after this many widenings it poses every pair.
_MAX_PRUNED_ROUNDS = 4
# The first guess for that bound, as a multiple of magnitude_limit (one pushing neighbour can add at
# most the request's own bound; more is rare and then detected).
_SPEED_BOUND_FACTOR = 2.0


# ---------------------------------------------------------------------------------------------
# Validation


def _number(where, name, what, value):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise RobotariumError(
            f"In the function {where}, {what} ({name}) must be an integer or float. "
            f"Received type {type(value).__name__!r}.")
    value = float(value)
    if not math.isfinite(value):
        raise RobotariumError(f"In the function {where}, {what} ({name}) must be finite. Received {value!r}.")
    return value


def _positive(where, name, what, value):
    value = _number(where, name, what, value)
    if not value > 0:
        raise RobotariumError(f"In the function {where}, {what} ({name}) must be positive (> 0). Received {value!r}.")
    return value


def _at_least(where, name, what, value, minimum, why=""):
    value = _number(where, name, what, value)
    if not value >= minimum:
        raise RobotariumError(
            f"In the function {where}, {what} ({name}) must be greater than or equal to {minimum}{why}. "
            f"Received {value!r}.")
    return value


def _magnitude_limit(where, value):
    what = "the maximum linear velocity of the robot"
    value = _positive(where, "magnitude_limit", what, value)
    if value > MAX_LINEAR_VELOCITY:
        raise RobotariumError(
            f"In the function {where}, {what} (magnitude_limit) must be less than or equal to the max speed "
            f"of the robot ({MAX_LINEAR_VELOCITY} m/s). Received {value!r}.")
    return value


def _safety_radius(where, value, minimum=MIN_SAFETY_RADIUS):
    why = (" m (the diameter of the robot, guide §4.5)" if minimum == MIN_SAFETY_RADIUS else
           " m (guide §4.5.7: the diameter of the robot plus the projection distance)")
    return _at_least(where, "safety_radius", "the safe distance between robots", value, minimum, why)


def _count(where, name, what, value, minimum):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise RobotariumError(
            f"In the function {where}, {what} ({name}) must be an integer. Received type {type(value).__name__!r}.")
    if value < minimum:
        raise RobotariumError(
            f"In the function {where}, {what} ({name}) must be greater than or equal to {minimum}. Received {value!r}.")
    return int(value)


def _boundary_points(where, value):
    what = "the arena boundary [x_min, x_max, y_min, y_max]"
    try:
        points = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise RobotariumError(
            f"In the function {where}, {what} (boundary_points) must be 4 numbers. Received {value!r}.") from None
    if points.shape != (4,) or not np.all(np.isfinite(points)):
        raise RobotariumError(
            f"In the function {where}, {what} (boundary_points) must be 4 finite numbers. Received {value!r}.")
    if not (points[0] < points[1] and points[2] < points[3]):
        raise RobotariumError(
            f"In the function {where}, {what} (boundary_points) must have x_min < x_max and y_min < y_max. "
            f"Received {value!r}.")
    return points


def _matrix(where, name, what, value, rows):
    """A float copy of a rows x N numpy array of finite numbers, or a RobotariumError."""
    if not isinstance(value, np.ndarray):
        raise RobotariumError(
            f"In the function returned by {where}, {what} ({name}) must be a {rows} x N numpy array. "
            f"Received type {type(value).__name__!r}.")
    if value.ndim != 2 or value.shape[0] != rows:
        raise RobotariumError(
            f"In the function returned by {where}, {what} ({name}) must be a {rows} x N numpy array. "
            f"Received shape {value.shape}.")
    if not (np.issubdtype(value.dtype, np.integer) or np.issubdtype(value.dtype, np.floating)):
        raise RobotariumError(
            f"In the function returned by {where}, {what} ({name}) must hold real numbers. "
            f"Received dtype {value.dtype}.")
    array = np.array(value, dtype=float)  # a copy: the caller's array is never changed
    bad = ~np.all(np.isfinite(array), axis=0)
    if bad.any():
        raise RobotariumError(
            f"In the function returned by {where}, {what} ({name}) must be finite. "
            f"Received NaN or inf in column(s) {np.flatnonzero(bad).tolist()}.")
    return array


def _same_count(where, a_name, a, b_name, b):
    if a.shape[1] != b.shape[1]:
        raise RobotariumError(
            f"In the function returned by {where}, the number of columns of {a_name} and {b_name} must be equal "
            f"(one per robot). Received {a_name} of shape {a.shape} and {b_name} of shape {b.shape}.")


def _obstacles(where, value, maximum, maximum_name):
    if value is None or (isinstance(value, np.ndarray) and value.size == 0):
        return np.empty((0, 2))
    obstacles = _matrix(where, "obstacles", "the obstacle positions", value, 2)
    if obstacles.shape[1] > maximum:
        raise RobotariumError(
            f"In the function returned by {where}, the number of obstacle points (obstacles) must be at most "
            f"{maximum} ({maximum_name}). Received {obstacles.shape[1]}.")
    return np.ascontiguousarray(obstacles.T)


# ---------------------------------------------------------------------------------------------
# Single integrator


def _single_integrator_pair_rate(speed_bound):
    """Pruning rule for the single-integrator pair rows.

    The row of pair (i, j) is  -2 e.(u_i - u_j) <= g h^3, with d = |e|. If every robot's answer
    has |u_k| <= S, its left side is at most 2 d (|u_i| + |u_j|) <= 4 S d, so for h >= 0 and
    g h^3 >= 4 S d the row holds whatever the answer is. Dropping rows only enlarges the feasible
    set; if the minimiser of the smaller QP still satisfies the dropped rows, it is feasible for the
    full QP and so is its (unique: the objective is strictly convex) minimiser. The pairs to keep
    are therefore those with d < d*, where g (d*^2 - r^2)^3 = 4 S d* (cubic_cutoff_distance).
    rps bounds only the request, not the answer, so S is checked after the solve (see __call__).
    """
    return 4.0 * speed_bound


class _SingleIntegratorQP:
    def __init__(self, barrier_gain, unsafe_barrier_gain, safety_radius, magnitude_limit, boundary_points):
        self.gain = barrier_gain
        self.unsafe_gain = unsafe_barrier_gain   # None: one gain everywhere
        self.radius = safety_radius
        self.limit = magnitude_limit
        self.boundary = boundary_points
        self.pruning = PRUNING
        self.info = new_info()
        self._solver = QPSolver(self.info)
        self._neighbours = NeighbourCache()
        self._identity = {}
        self._boundary_pattern = (-1,)
        self._first_bound = _SPEED_BOUND_FACTOR * magnitude_limit
        self._first_cutoff = cubic_cutoff_distance(
            barrier_gain, safety_radius, _single_integrator_pair_rate(self._first_bound))

    def _p_blocks(self, n):
        if n not in self._identity:
            self._identity = {n: np.tile(np.eye(2), (n, 1, 1))}
        return self._identity[n]

    def _boundary_rows(self, p):
        n = len(p)
        if self.boundary is None:
            return np.empty(0, dtype=np.intp), np.empty(0, dtype=np.intp), np.empty((0, 2)), np.empty(0), np.empty(0)
        if self._boundary_pattern[0] != n:  # which robot, key, coefficients: fixed for a given N
            self._boundary_pattern = (n, np.repeat(np.arange(n, dtype=np.intp), 2), np.arange(2 * n),
                                      np.tile(np.eye(2), (n, 1)))
        x_min, x_max, y_min, y_max = self.boundary
        k, half = 0.4 * self.gain, self.radius / 2
        lower = -k * (p - [x_min + half, y_min + half]) ** 3
        upper = k * ([x_max - half, y_max - half] - p) ** 3
        return (*self._boundary_pattern[1:3], self._boundary_pattern[3], lower.ravel(), upper.ravel())

    def _rows(self, p, pairs, boundary):
        e = p[pairs[:, 0]] - p[pairs[:, 1]]
        h = np.einsum("ij,ij->i", e, e) - self.radius ** 2
        gain = self.gain if self.unsafe_gain is None else np.where(h >= 0, self.gain, self.unsafe_gain)
        coef = np.hstack([-2 * e, 2 * e])
        bound = gain * h ** 3
        return Rows(len(p), pairs, coef, np.full(len(pairs), -np.inf), bound, *boundary)

    def __call__(self, dxi, x):
        """dxi, x: 2 x N float arrays this object may modify. Returns (answer 2 x N, unchanged)."""
        n = dxi.shape[1]
        info = self.info
        reset_info(info, n)
        # rps: scale each requested velocity down to magnitude_limit before the QP.
        norms = np.hypot(dxi[0], dxi[1])
        over = norms > self.limit
        dxi[:, over] *= self.limit / norms[over]
        z0 = np.ascontiguousarray(dxi.T)
        p = np.ascontiguousarray(x.T)
        boundary = self._boundary_rows(p)

        bound = self._first_bound
        for widenings in range(_MAX_PRUNED_ROUNDS + 1):
            if not self.pruning or widenings == _MAX_PRUNED_ROUNDS:
                cutoff = np.inf
            elif bound == self._first_bound:
                cutoff = self._first_cutoff
            else:
                cutoff = cubic_cutoff_distance(self.gain, self.radius, _single_integrator_pair_rate(bound))
            rows = self._rows(p, self._neighbours.pairs(p, cutoff), boundary)
            info["num_constraints"], info["num_pairs"] = len(rows), len(rows.pairs)
            slack0 = rows.slack(z0)
            if len(rows) == 0 or slack0.min() >= 0:
                # The (limited) request satisfies every row: it is the QP's answer. Its speeds are
                # <= magnitude_limit <= bound, so the rows left out hold as well.
                info["status"] = "passthrough"
                return dxi, not over.any()
            z = self._solver.solve(self._p_blocks(n), -z0.ravel(), rows, n, z0, slack0)
            if z is None:
                info["status"], info["fallback"] = "fallback", True
                return np.zeros((2, n)), False
            peak = float(np.sqrt(np.einsum("ij,ij->i", z, z).max()))
            if cutoff == np.inf or peak <= bound:
                return np.ascontiguousarray(z.T), False
            # Some answer is faster than assumed: rows left out might bind. Widen and solve again.
            bound = 1.5 * peak
            info["widenings"] += 1


def create_single_integrator_barrier_certificate(barrier_gain=100, safety_radius=0.17, magnitude_limit=0.2):
    """Barrier certificate for single integrators (guide §4.5.1): f(dxi, x) -> safe dxi.

    barrier_gain > 0: how quickly robots may approach each other; safety_radius >= 0.12 m: how far
    apart they stay; magnitude_limit in (0, 0.2] m/s: requests are scaled down to it first.
    """
    where = "create_single_integrator_barrier_certificate"
    return _single_integrator_function(where, barrier_gain, None, safety_radius, magnitude_limit, None)


def create_single_integrator_barrier_certificate_with_boundary(
        barrier_gain=100, safety_radius=0.17, magnitude_limit=0.2,
        boundary_points=np.array(_ARENA)):
    """As create_single_integrator_barrier_certificate, and robots stay inside boundary_points
    [x_min, x_max, y_min, y_max] (guide §4.5.2)."""
    where = "create_single_integrator_barrier_certificate_with_boundary"
    return _single_integrator_function(where, barrier_gain, None, safety_radius, magnitude_limit, boundary_points)


def create_single_integrator_barrier_certificate2(barrier_gain=100, unsafe_barrier_gain=1e6, safety_radius=0.17,
                                                  magnitude_limit=0.2):
    """As create_single_integrator_barrier_certificate, with gain unsafe_barrier_gain > 0 for pairs
    already closer than safety_radius (guide §4.5.3)."""
    where = "create_single_integrator_barrier_certificate2"
    return _single_integrator_function(where, barrier_gain, unsafe_barrier_gain, safety_radius, magnitude_limit, None,
                                       gain_what="the barrier gain inside the safe set")


def _single_integrator_function(where, barrier_gain, unsafe_barrier_gain, safety_radius, magnitude_limit,
                                boundary_points, gain_what="the barrier gain"):
    gain = _positive(where, "barrier_gain", gain_what, barrier_gain)
    unsafe = None
    if unsafe_barrier_gain is not None:
        unsafe = _positive(where, "unsafe_barrier_gain", "the barrier gain outside the safe set", unsafe_barrier_gain)
    radius = _safety_radius(where, safety_radius)
    limit = _magnitude_limit(where, magnitude_limit)
    boundary = None if boundary_points is None else _boundary_points(where, boundary_points)
    core = _SingleIntegratorQP(gain, unsafe, radius, limit, boundary)

    def f(dxi, x):
        start = time.perf_counter()
        dxi = _matrix(where, "dxi", "the single-integrator robot velocity command", dxi, 2)
        x = _matrix(where, "x", "the single-integrator robot states ([x; y] per robot)", x, 2)
        _same_count(where, "dxi", dxi, "x", x)
        answer, _ = core(dxi, x)
        end_call(core.info, start)
        return answer

    f.info = core.info
    return f


# ---------------------------------------------------------------------------------------------
# Unicycle (through the single integrator at a point ahead of the robot)


def _unicycle_function(where, barrier_gain, unsafe_barrier_gain, safety_radius, projection_distance,
                       magnitude_limit, boundary_points, gain_what="the barrier gain"):
    gain = _positive(where, "barrier_gain", gain_what, barrier_gain)
    unsafe = None
    if unsafe_barrier_gain is not None:
        unsafe = _positive(where, "unsafe_barrier_gain", "the barrier gain outside the safe set", unsafe_barrier_gain)
    radius = _safety_radius(where, safety_radius)
    distance = _positive(where, "projection_distance",
                         "the projected point distance for the diffeomorphism between single integrator and unicycle",
                         projection_distance)
    limit = _magnitude_limit(where, magnitude_limit)
    boundary = None if boundary_points is None else _boundary_points(where, boundary_points)
    # rps: the single-integrator certificate with radius safety_radius + projection_distance.
    core = _SingleIntegratorQP(gain, unsafe, radius + distance, limit, boundary)

    def f(dxu, x):
        start = time.perf_counter()
        dxu = _matrix(where, "dxu", "the unicycle robot velocity command ([v; w] per robot)", dxu, 2)
        x = _matrix(where, "x", "the unicycle robot states ([x; y; theta] per robot)", x, 3)
        _same_count(where, "dxu", dxu, "x", x)
        c, s = np.cos(x[2]), np.sin(x[2])
        points = x[:2] + distance * np.stack([c, s])
        dxi = np.stack([c * dxu[0] - distance * s * dxu[1], s * dxu[0] + distance * c * dxu[1]])
        safe, unchanged = core(dxi, points)
        if unchanged and np.all(np.abs(dxu[1]) <= ANGULAR_VELOCITY_LIMIT):
            answer = dxu   # the request was safe and within the limits: return it exactly
        else:
            answer = np.stack([c * safe[0] + s * safe[1], (-s * safe[0] + c * safe[1]) / distance])
            np.clip(answer[1], -ANGULAR_VELOCITY_LIMIT, ANGULAR_VELOCITY_LIMIT, out=answer[1])
        end_call(core.info, start)
        return answer

    f.info = core.info
    return f


def create_unicycle_barrier_certificate(barrier_gain=100, safety_radius=0.12, projection_distance=0.05,
                                        magnitude_limit=0.2):
    """Barrier certificate for unicycles (guide §4.5.4): f(dxu, x) -> safe dxu, x is 3 x N.

    The single-integrator certificate (radius safety_radius + projection_distance) on the point
    projection_distance ahead of each robot.
    """
    where = "create_unicycle_barrier_certificate"
    return _unicycle_function(where, barrier_gain, None, safety_radius, projection_distance, magnitude_limit, None)


def create_unicycle_barrier_certificate_with_boundary(barrier_gain=100, safety_radius=0.12, projection_distance=0.05,
                                                      magnitude_limit=0.2, boundary_points=np.array(_ARENA)):
    """As create_unicycle_barrier_certificate, and robots stay inside boundary_points (guide §4.5.5)."""
    where = "create_unicycle_barrier_certificate_with_boundary"
    return _unicycle_function(where, barrier_gain, None, safety_radius, projection_distance, magnitude_limit,
                              boundary_points)


def create_unicycle_barrier_certificate2(barrier_gain=500, unsafe_barrier_gain=1e6, safety_radius=0.12,
                                         projection_distance=0.05, magnitude_limit=0.2):
    """As create_unicycle_barrier_certificate, with unsafe_barrier_gain for pairs already too close
    (guide §4.5.6)."""
    where = "create_unicycle_barrier_certificate2"
    return _unicycle_function(where, barrier_gain, unsafe_barrier_gain, safety_radius, projection_distance,
                              magnitude_limit, None, gain_what="the barrier gain inside the safe set")


# ---------------------------------------------------------------------------------------------
# Differential drive (wheel speeds as decision variables, robust to wheel disturbances)


class _DifferentialDriveQP:
    """Pruning rule: the wheel limits |w| <= W are rows of this QP, so every feasible answer obeys
    them. The pair row  hi.w_i + hj.w_j >= -g h^3 + d (|hi|_1 + |hj|_1)  has a left side of at least
    -W (|hi|_1 + |hj|_1) for any such w, so it always holds when g h^3 >= (W + d)(|hi|_1 + |hj|_1).
    With hi = 2 (M_i D)' e:  (M_i D)' e = D' (a, b) where a = (cos t, sin t).e, |a| <= |e|, and
    b = l (-sin t, cos t).e, |b| <= l |e|;  |D' (a, b)|_1 = |R/2 a - R/B b| + |R/2 a + R/B b|
    = 2 max(R/2 |a|, R/B |b|) <= 2 max(R/2, l R/B) |e| =: k |e|.  So |hi|_1 + |hj|_1 <= 4 k d and
    the row can be left out when g h^3 >= 4 k (W + d) d, i.e. beyond cubic_cutoff_distance. An
    obstacle row needs only half of that, so the same distance covers it. Exact, no check needed.
    """

    def __init__(self, barrier_gain, safety_radius, projection_distance, disturbance, wheel_vel_limit, base_length,
                 wheel_radius, boundary_points, max_num_robots, max_num_obstacles):
        self.gain = barrier_gain
        self.radius = safety_radius
        self.distance = projection_distance
        self.disturbance = disturbance
        self.wheel_limit = wheel_vel_limit
        self.boundary = boundary_points
        self.max_robots = max_num_robots
        self.max_obstacles = max_num_obstacles
        self.D = np.array([[wheel_radius / 2, wheel_radius / 2],
                           [-wheel_radius / base_length, wheel_radius / base_length]])
        self.D_inv = np.linalg.inv(self.D)
        L = np.diag([1.0, projection_distance]) @ self.D
        hessian = L.T @ L
        self.hessian = hessian / np.abs(hessian).max()   # a constant factor does not move the minimiser
        k = 2 * max(wheel_radius / 2, projection_distance * wheel_radius / base_length)
        self.cutoff = np.inf if not PRUNING else cubic_cutoff_distance(
            barrier_gain, safety_radius, 4 * k * (wheel_vel_limit + disturbance))
        self.info = new_info()
        self._solver = QPSolver(self.info)
        self._neighbours = NeighbourCache()
        self._blocks = {}

    def _p_blocks(self, n):
        if n not in self._blocks:
            self._blocks = {n: np.tile(self.hessian, (n, 1, 1))}
        return self._blocks[n]

    def __call__(self, dxu, x, obstacles):
        """dxu 2 x N, x 3 x N, obstacles M x 2 (validated). Returns the safe dxu, 2 x N."""
        n = dxu.shape[1]
        info = self.info
        reset_info(info, n)
        g, r, l, d, wheel = self.gain, self.radius, self.distance, self.disturbance, self.wheel_limit
        z0 = np.ascontiguousarray((self.D_inv @ dxu).T)            # requested wheel speeds, N x 2
        c, s = np.cos(x[2]), np.sin(x[2])
        p = np.ascontiguousarray(x[:2].T) + l * np.stack([c, s], axis=1)
        # M_i D: velocity of the point ahead of robot i per unit wheel speed, N x 2 x 2.
        M = np.stack([np.stack([c, -l * s], axis=1), np.stack([s, l * c], axis=1)], axis=1)
        MD = M @ self.D

        pairs = self._neighbours.pairs(p, self.cutoff)
        i, j = pairs[:, 0], pairs[:, 1]
        e = p[i] - p[j]
        h = np.einsum("ij,ij->i", e, e) - r * r
        hi = 2 * np.einsum("ka,kab->kb", e, MD[i])
        hj = -2 * np.einsum("ka,kab->kb", e, MD[j])
        pair_lower = -g * h ** 3 + d * (np.abs(hi).sum(1) + np.abs(hj).sum(1))

        robots, keys, coefs, lowers, uppers = [], [], [], [], []
        near = self._neighbours.obstacle_pairs(p, obstacles, self.cutoff)
        if len(near):
            robot, obstacle = near[:, 0], near[:, 1]
            eo = p[robot] - obstacles[obstacle]
            ho = np.einsum("ij,ij->i", eo, eo) - r * r
            hio = 2 * np.einsum("ka,kab->kb", eo, MD[robot])
            robots.append(robot)
            keys.append(4 * n + robot * len(obstacles) + obstacle)
            coefs.append(hio)
            lowers.append(-g * ho ** 3 + d * np.abs(hio).sum(1))
            uppers.append(np.full(len(near), np.inf))
        every = np.arange(n, dtype=np.intp)
        if self.boundary is not None:
            x_min, x_max, y_min, y_max = self.boundary
            k, half = 0.4 * g, r / 2
            robots.append(np.repeat(every, 2))
            keys.append(np.arange(2 * n))
            coefs.append(MD.reshape(2 * n, 2))                        # rows (M_i D)_x, (M_i D)_y
            lowers.append((-k * np.stack([p[:, 0] - x_min - half, p[:, 1] - y_min - half], axis=1) ** 3).ravel())
            uppers.append((k * np.stack([x_max - half - p[:, 0], y_max - half - p[:, 1]], axis=1) ** 3).ravel())
        robots.append(np.repeat(every, 2))                             # wheel limits
        keys.append(2 * n + np.arange(2 * n))
        coefs.append(np.tile(np.eye(2), (n, 1)))
        lowers.append(np.full(2 * n, -wheel))
        uppers.append(np.full(2 * n, wheel))

        rows = Rows(n, pairs, np.hstack([hi, hj]), pair_lower, np.full(len(pairs), np.inf), np.concatenate(robots),
                    np.concatenate(keys), np.concatenate(coefs), np.concatenate(lowers), np.concatenate(uppers))
        info["num_constraints"], info["num_pairs"] = len(rows), len(pairs)
        slack0 = rows.slack(z0)
        if len(rows) == 0 or slack0.min() >= 0:
            info["status"] = "passthrough"
            return dxu
        z = self._solver.solve(self._p_blocks(n), -(z0 @ self.hessian).ravel(), rows, n, z0, slack0)
        if z is None:
            info["status"], info["fallback"] = "fallback", True
            return np.zeros((2, n))
        return self.D @ z.T


def _differential_drive_function(where, name_of, max_num_obstacles, max_num_robots, disturbance, wheel_vel_limit,
                                 base_length, wheel_radius, projection_distance, barrier_gain, safety_radius,
                                 minimum_radius, boundary_points):
    max_obstacles = _count(where, name_of["max_num_obstacles"], "the maximum number of obstacle points",
                           max_num_obstacles, 0)
    max_robots = _count(where, "max_num_robots", "the maximum number of robots", max_num_robots, 1)
    dist = _at_least(where, name_of["disturbance"], "the wheel-speed disturbance", disturbance, 0)
    wheel = _positive(where, "wheel_vel_limit", "the wheel velocity limit", wheel_vel_limit)
    base = _positive(where, "base_length", "the distance between the wheels", base_length)
    radius_w = _positive(where, "wheel_radius", "the wheel radius", wheel_radius)
    distance = _positive(where, "projection_distance",
                         "the projected point distance for the diffeomorphism between single integrator and unicycle",
                         projection_distance)
    gain = _positive(where, name_of["barrier_gain"], "the barrier gain", barrier_gain)
    radius = _safety_radius(where, safety_radius, minimum_radius)
    boundary = None if boundary_points is None else _boundary_points(where, boundary_points)
    core = _DifferentialDriveQP(gain, radius, distance, dist, wheel, base, radius_w, boundary, max_robots,
                                max_obstacles)

    def robust_barriers(dxu, x, obstacles=None):
        start = time.perf_counter()
        dxu = _matrix(where, "dxu", "the unicycle robot velocity command ([v; w] per robot)", dxu, 2)
        x = _matrix(where, "x", "the unicycle robot states ([x; y; theta] per robot)", x, 3)
        _same_count(where, "dxu", dxu, "x", x)
        if dxu.shape[1] > max_robots:
            raise RobotariumError(
                f"In the function returned by {where}, the number of robots must be at most {max_robots} "
                f"(max_num_robots). Received {dxu.shape[1]}.")
        obstacle_points = _obstacles(where, obstacles, max_obstacles, name_of["max_num_obstacles"])
        answer = core(dxu, x, obstacle_points)
        end_call(core.info, start)
        return answer

    robust_barriers.info = core.info
    return robust_barriers


def create_unicycle_differential_drive_barrier_certificate(
        max_num_obstacle_points=100, max_num_robots=30, disturbance=5, wheel_vel_limit=MAX_WHEEL_VELOCITY,
        base_length=BASE_LENGTH, wheel_radius=WHEEL_RADIUS, projection_distance=0.05, barrier_gain=150,
        safety_radius=0.17):
    """Differential-drive barrier certificate robust to wheel-speed disturbances (guide §4.5.7,
    Emam et al. 2022): f(dxu, x, obstacles=None) -> safe dxu; obstacles is 2 x M or None."""
    where = "create_unicycle_differential_drive_barrier_certificate"
    names = {"max_num_obstacles": "max_num_obstacle_points", "disturbance": "disturbance",
             "barrier_gain": "barrier_gain"}
    return _differential_drive_function(where, names, max_num_obstacle_points, max_num_robots, disturbance,
                                        wheel_vel_limit, base_length, wheel_radius, projection_distance, barrier_gain,
                                        safety_radius, MIN_SAFETY_RADIUS_DIFFERENTIAL_DRIVE, None)


def create_unicycle_differential_drive_barrier_certificate_with_boundary(
        max_num_obstacle_points=100, max_num_robots=30, disturbance=5, wheel_vel_limit=MAX_WHEEL_VELOCITY,
        base_length=BASE_LENGTH, wheel_radius=WHEEL_RADIUS, projection_distance=0.05, barrier_gain=150,
        safety_radius=0.17, boundary_points=np.array(_ARENA)):
    """As create_unicycle_differential_drive_barrier_certificate, and robots stay inside
    boundary_points (guide §4.5.8)."""
    where = "create_unicycle_differential_drive_barrier_certificate_with_boundary"
    names = {"max_num_obstacles": "max_num_obstacle_points", "disturbance": "disturbance",
             "barrier_gain": "barrier_gain"}
    return _differential_drive_function(where, names, max_num_obstacle_points, max_num_robots, disturbance,
                                        wheel_vel_limit, base_length, wheel_radius, projection_distance, barrier_gain,
                                        safety_radius, MIN_SAFETY_RADIUS_DIFFERENTIAL_DRIVE, boundary_points)


def create_robust_barriers(max_num_obstacles=100, max_num_robots=30, d=5, wheel_vel_limit=MAX_WHEEL_VELOCITY,
                           base_length=BASE_LENGTH, wheel_radius=WHEEL_RADIUS, projection_distance=0.05, gamma=150,
                           safety_radius=0.12):
    """Robust barriers for differential drives (guide §4.6.1, rps barrier_certificates2.py):
    robust_barriers(dxu, x, obstacles) -> safe dxu; obstacles is 2 x M (may be empty or None)."""
    where = "create_robust_barriers"
    names = {"max_num_obstacles": "max_num_obstacles", "disturbance": "d", "barrier_gain": "gamma"}
    return _differential_drive_function(where, names, max_num_obstacles, max_num_robots, d, wheel_vel_limit,
                                        base_length, wheel_radius, projection_distance, gamma, safety_radius,
                                        MIN_SAFETY_RADIUS, None)


# The names of the newer Robotarium simulators (the MATLAB simulator's create_si_* / create_uni_*),
# with the same parameters and defaults as the guide's functions above.
create_si_barrier_certificate = create_single_integrator_barrier_certificate
create_si_barrier_certificate_with_boundary = create_single_integrator_barrier_certificate_with_boundary
create_uni_barrier_certificate = create_unicycle_barrier_certificate
create_uni_barrier_certificate_with_boundary = create_unicycle_barrier_certificate_with_boundary


