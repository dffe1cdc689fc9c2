"""The machinery under the barrier certificates: sparse QP rows, neighbour search, OSQP.

`Rows` holds the constraint rows (each touching one robot or a pair) as index and coefficient
arrays, built with numpy; `QPSolver` hands them to OSQP (osqp 1.x API) as a CSC matrix, set up
again only when the set of rows changes, otherwise updated in place and warm-started. Two things
keep a call cheap without changing its answer: `NeighbourCache` + `cubic_cutoff_distance` (pairs
too far apart to bind are no rows), and `QPSolver.solve`'s working set of rows, grown until the
answer satisfies every row (constraint generation), then polished to round-off.
Plain numpy + scipy + osqp: no ROS import. Why each step is exact: docs/safety.md#the-certificates-in-formulas.
"""
import functools
import time

import numpy as np
import osqp
import scipy.sparse as sparse

# OSQP settings: a moderate tolerance, then polishing (see QPSolver._run), which makes the answer
# exact to round-off whenever it succeeds. Tests may change these (for example max_iter=1 to force
# a failure); they are read at every OSQP setup.
OSQP_SETTINGS = {
    "verbose": False,
    "eps_abs": 1e-4,
    "eps_rel": 1e-4,
    "polishing": True,
    "max_iter": 10000,
    # rho adapted every 25 iterations, not at an interval OSQP derives from its set-up time: runs do
    # not depend on the machine's speed, and ADMM does not stall (with the timed interval a 2-robot
    # QP whose robot rows are parallel to its pair row ran to max_iter: robotarium_safety/test/test_safety_guarantee.py).
    "adaptive_rho_interval": 25,
}
# Where polishing fails, OSQP goes on to this tolerance (and polishes again).
TIGHT_TOLERANCE = 1e-6

# Constraint generation (QPSolver.solve). The working set starts with the rows the request comes
# within ENTRY_SLACK of breaking (the rows it breaks, and those the corrections are likely to push
# over) and the rows within STICKY_SLACK of binding at the previous answer; a row left out joins when
# the answer breaks it by more than ADD_TOLERANCE (relative, see _magnitude). The slacks are in m/s
# for the single integrators (rows have unit coefficient norm); they only trade fewer re-solves
# against smaller QPs, never the answer. Measured on bench scenes: 0.05 / 0.02 suit up to 50 robots
# and uncongested crowds; a jammed crowd prefers ENTRY_SLACK = 0.
CONSTRAINT_GENERATION = True
ADD_TOLERANCE = 1e-9
ENTRY_SLACK = 0.05
STICKY_SLACK = 0.02

# A solution whose worst row violation (rows are scaled to unit coefficient norm, so this is in the
# units of the decision variable, and relative to the answer's size when that is above 1) exceeds
# this is not trusted: the certificate falls back to a stop.
FEASIBILITY_TOLERANCE = 1e-4

# Neighbour search: pairs are found within (pruning radius + NEIGHBOUR_MARGIN) and that set is kept
# while no robot has moved far enough for a pair outside it to come within the pruning radius; the
# QP's sparsity pattern then stays the same and OSQP is only updated, not set up again.
NEIGHBOUR_MARGIN = 0.1
# Below this many robots, checking all N(N-1)/2 distances with numpy beats building a k-d tree.
BRUTE_FORCE_MAX_ROBOTS = 48


@functools.lru_cache(maxsize=64)
def all_pairs(n):
    """Every pair i < j of n robots as a (K, 2) int array, in the order rps builds its rows."""
    i, j = np.triu_indices(n, 1)
    pairs = np.stack([i, j], axis=1).astype(np.intp)
    pairs.setflags(write=False)
    return pairs


def pairs_within(points, radius):
    """All pairs i < j of points (N x 2) at distance <= radius, sorted by (i, j)."""
    n = len(points)
    if n < 2:
        return np.empty((0, 2), dtype=np.intp)
    if not np.isfinite(radius):
        return all_pairs(n)
    if n <= BRUTE_FORCE_MAX_ROBOTS:
        pairs = all_pairs(n)
        diff = points[pairs[:, 0]] - points[pairs[:, 1]]
        return pairs[np.einsum("ij,ij->i", diff, diff) <= radius * radius]
    from scipy.spatial import cKDTree  # here, not at import: scipy.spatial takes ~0.5 s to import
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray").astype(np.intp)
    # query_pairs gives no order; sort so the same set always gives the same matrix pattern.
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


class NeighbourCache:
    """Pairs of robots (and robot-obstacle pairs) that may be closer than a radius, with hysteresis.

    The set is found within radius + NEIGHBOUR_MARGIN and reused while it provably still contains
    every pair within the radius asked for: if no robot has moved more than `moved` since the set
    was built, a pair now closer than `radius` was closer than radius + 2*moved then (triangle
    inequality), so the set is still a superset while radius + 2*moved <= the radius it was built
    with. Extra pairs are real constraints of the full QP, so they never change its answer.
    """

    def __init__(self):
        self._points = None
        self._radius = -1.0
        self._pairs = None
        self._obstacle_key = None
        self._obstacle_points = None
        self._obstacle_radius = -1.0
        self._obstacle_pairs = None

    @staticmethod
    def _moved(points, then):
        if then is None or len(then) != len(points):
            return np.inf
        if len(points) == 0:
            return 0.0
        d = points - then
        return float(np.sqrt(np.einsum("ij,ij->i", d, d).max()))

    def pairs(self, points, radius):
        if radius + 2 * self._moved(points, self._points) <= self._radius:
            return self._pairs
        build = radius + NEIGHBOUR_MARGIN
        self._pairs = pairs_within(points, build)
        self._points, self._radius = points.copy(), build
        return self._pairs

    def obstacle_pairs(self, points, obstacles, radius):
        """(robot, obstacle) index pairs at distance <= radius; obstacles is M x 2 (fixed points)."""
        if len(points) == 0 or len(obstacles) == 0:
            return np.empty((0, 2), dtype=np.intp)
        key = obstacles.tobytes()
        if key == self._obstacle_key and radius + self._moved(points, self._obstacle_points) <= self._obstacle_radius:
            return self._obstacle_pairs
        build = radius + NEIGHBOUR_MARGIN
        d = points[:, None, :] - obstacles[None, :, :]
        robot, obstacle = np.nonzero(np.einsum("ijk,ijk->ij", d, d) <= build * build)
        self._obstacle_pairs = np.stack([robot, obstacle], axis=1).astype(np.intp)
        self._obstacle_key, self._obstacle_points, self._obstacle_radius = key, points.copy(), build
        return self._obstacle_pairs


def cubic_cutoff_distance(gain, radius, rate):
    """The distance d* > radius at which gain * (d^2 - radius^2)^3 = rate * d.

    For d >= d*, gain * h^3 >= rate * d (h = d^2 - radius^2): (d^2 - r^2)^3 / d is increasing for
    d > r (its derivative is (d^2 - r^2)^2 (5 d^2 + r^2) / d^2 > 0), so beyond the crossing it
    stays above. Solved by bisection: a few microseconds.
    """
    if not np.isfinite(rate):
        return np.inf
    lo, hi = radius, radius + 1.0
    while gain * (hi * hi - radius * radius) ** 3 < rate * hi:
        lo, hi = hi, 2 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if gain * (mid * mid - radius * radius) ** 3 < rate * mid:
            lo = mid
        else:
            hi = mid
    return hi


class Rows:
    """Constraint rows l <= a.z <= u of a QP in z = (z_0x, z_0y, z_1x, z_1y, ...).

    Pair rows touch robots i and j (4 coefficients: i's two, then j's two); robot rows touch one
    robot (2 coefficients). Every row is scaled to unit coefficient norm (when it has one), which
    makes tolerances mean the same thing in every row and helps OSQP. Each row has a key that names
    the same constraint from one call to the next (pair (i, j): i N + j; robot rows: N^2 + the key
    the certificate gives), so that the rows active last tick can be found again.
    """

    def __init__(self, n_robots, pairs, pair_coef, pair_l, pair_u, robots, robot_keys, robot_coef, robot_l, robot_u):
        self.pairs = pairs
        self.robots = robots
        self.keys = np.concatenate([pairs[:, 0] * n_robots + pairs[:, 1], n_robots * n_robots + robot_keys])
        self.coef_pair, self.l_pair, self.u_pair = self._unit(pair_coef, pair_l, pair_u)
        self.coef_robot, self.l_robot, self.u_robot = self._unit(robot_coef, robot_l, robot_u)

    @staticmethod
    def _unit(coef, l, u):
        norm = np.sqrt(np.einsum("ij,ij->i", coef, coef))
        scale = np.ones_like(norm)
        np.divide(1.0, norm, out=scale, where=norm > 0)
        return coef * scale[:, None], l * scale, u * scale

    def subset(self, mask):
        """The rows where mask (one bool per row) is True."""
        sub = Rows.__new__(Rows)
        k = len(self.pairs)
        pm, rm = mask[:k], mask[k:]
        sub.pairs, sub.robots, sub.keys = self.pairs[pm], self.robots[rm], self.keys[mask]
        sub.coef_pair, sub.l_pair, sub.u_pair = self.coef_pair[pm], self.l_pair[pm], self.u_pair[pm]
        sub.coef_robot, sub.l_robot, sub.u_robot = self.coef_robot[rm], self.l_robot[rm], self.u_robot[rm]
        return sub

    def __len__(self):
        return len(self.pairs) + len(self.robots)

    @property
    def lower(self):
        return np.concatenate([self.l_pair, self.l_robot])

    @property
    def upper(self):
        return np.concatenate([self.u_pair, self.u_robot])

    def products(self, z):
        """a.z for every row; z is N x 2 (robot-major)."""
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        pair = (np.einsum("ij,ij->i", self.coef_pair[:, :2], z[i]) +
                np.einsum("ij,ij->i", self.coef_pair[:, 2:], z[j]))
        robot = np.einsum("ij,ij->i", self.coef_robot, z[self.robots])
        return np.concatenate([pair, robot])

    def slack(self, z):
        """How far inside its bounds each row is at z (negative: violated by that much)."""
        az = self.products(z)
        with np.errstate(invalid="ignore"):  # inf - inf cannot happen: l and u are never both infinite
            return np.minimum(self.upper - az, az - self.lower)

    def violation(self, z):
        """The largest amount by which z breaks a row (0 when z satisfies them all)."""
        if len(self) == 0:
            return 0.0
        return max(0.0, -float(self.slack(z).min()))

    def pattern(self, n_robots):
        """(row, column) of every coefficient, in the order of `values()`."""
        k, m = len(self.pairs), len(self.robots)
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        pair_cols = np.stack([2 * i, 2 * i + 1, 2 * j, 2 * j + 1], axis=1).ravel()
        pair_rows = np.repeat(np.arange(k), 4)
        robot_cols = np.stack([2 * self.robots, 2 * self.robots + 1], axis=1).ravel()
        robot_rows = np.repeat(np.arange(k, k + m), 2)
        return np.concatenate([pair_rows, robot_rows]), np.concatenate([pair_cols, robot_cols])

    def values(self):
        return np.concatenate([self.coef_pair.ravel(), self.coef_robot.ravel()])


def _member(keys, sorted_keys):
    """keys (any order) that are in sorted_keys, as a bool array: a binary search, no table as
    large as the largest key (np.isin's "table" kind allocates max - min, O(N^2) for pair keys)."""
    if len(sorted_keys) == 0:
        return np.zeros(len(keys), dtype=bool)
    at = np.minimum(np.searchsorted(sorted_keys, keys), len(sorted_keys) - 1)
    return sorted_keys[at] == keys


def _magnitude(z):
    """max(1, |z|_inf): tolerances are absolute for ordinary answers, relative for huge ones (a
    pair already overlapping under unsafe_barrier_gain = 1e6 can ask for hundreds of m/s)."""
    return max(1.0, float(np.abs(z).max())) if z.size else 1.0


def _block_diagonal_upper(blocks):
    """The upper triangle of a block-diagonal matrix of 2x2 blocks (N x 2 x 2) as CSC, keeping
    explicit zeros so that the pattern never depends on the values."""
    n = len(blocks)
    data = np.stack([blocks[:, 0, 0], blocks[:, 0, 1], blocks[:, 1, 1]], axis=1).ravel()
    base = 2 * np.arange(n)
    indices = np.stack([base, base, base + 1], axis=1).ravel()
    indptr = np.concatenate([[0], np.cumsum(np.tile([1, 2], n))])
    return sparse.csc_matrix((data, indices, indptr), shape=(2 * n, 2 * n))


def new_info():
    """What a certificate reports about its last call (the dict is updated in place)."""
    return {
        "status": "not called",   # OSQP status string ("solved"), "passthrough" or "fallback"
        "solve_time": 0.0,        # seconds for the whole call, validation included
        "fallback": False,        # True when the answer is the stop command (all zeros)
        "reason": "",             # why it fell back (OSQP status or error), else ""
        "num_robots": 0,
        "num_constraints": 0,     # rows of the QP that was posed (after pruning)
        "num_pairs": 0,           # pairwise rows kept (rps poses N(N-1)/2)
        "iterations": 0,          # OSQP iterations (0 when no solve was needed)
        "setup": False,           # True when OSQP was set up (new sparsity pattern) in this call
        "rounds": 0,              # QPs solved in this call (constraint generation, pruning widened)
        "widenings": 0,           # times the pruning radius had to grow in this call
        "working_rows": 0,        # rows in the QP that OSQP finally solved (the rest provably hold)
        "max_violation": 0.0,     # worst row violation of the answer returned (unit-scaled rows)
        "polished": False,        # True when OSQP's polishing made the answer exact
        "clamped": 0.0,           # m/s, the most the testbed certificate changed a robot's speed
    }


class QPSolver:
    """min 1/2 z'Pz + q'z subject to Rows, with one OSQP instance kept between calls."""

    def __init__(self, info):
        self.info = info
        self._solver = None
        self._structure = None   # (n_robots, row keys) of the problem OSQP holds
        self._order = None       # permutation from Rows.values() to CSC data order
        self._last_x = None
        # The previous answer's duals by row key (sorted keys, their y) and OSQP's last step size:
        # a new set-up (another working set) starts from them, so ADMM resumes near the answer
        # instead of from y = 0 and the default rho (at 100 robots in a jam: ~1000 iterations a
        # call from cold duals).
        self._last_duals = None
        self._last_rho = None
        self._sticky_keys = np.empty(0, dtype=np.int64)

    def _setup(self, p_blocks, q, rows, n_robots):
        r, c = rows.pattern(n_robots)
        order = np.lexsort((r, c))   # CSC: by column, then row
        indptr = np.concatenate([[0], np.cumsum(np.bincount(c, minlength=2 * n_robots))])
        a = sparse.csc_matrix((rows.values()[order], r[order], indptr), shape=(len(rows), 2 * n_robots))
        if self._solver is None:
            # One OSQP object, set up again for each new pattern: constructing one costs more
            # than setting up a small problem (it probes which linear-algebra backends exist).
            self._solver = osqp.OSQP()
            self._infinity = self._solver.constant("OSQP_INFTY")
        settings = OSQP_SETTINGS if self._last_rho is None else dict(OSQP_SETTINGS, rho=self._last_rho)
        self._solver.setup(_block_diagonal_upper(p_blocks), q, a, rows.lower, rows.upper, **settings)
        if self._last_x is not None and len(self._last_x) == len(q):
            self._solver.warm_start(x=self._last_x, y=self._duals_for(rows.keys))
        self._order = order
        self._structure = (n_robots, rows.keys.copy())
        self.info["setup"] = True

    def _update(self, q, rows):
        """New values in the pattern OSQP holds. The extension's own update calls, not
        OSQP.update: that wrapper also keeps copies for OSQP's derivatives (unused here), which
        cost more than the update itself at small N (osqp 1.1.3, pinned in requirements.txt).
        Bounds beyond +-OSQP_INFTY are clipped as the wrapper does."""
        infinity = self._infinity
        solver = self._solver._solver
        solver.update_data_vec(q=q, l=np.maximum(rows.lower, -infinity), u=np.minimum(rows.upper, infinity))
        solver.update_data_mat(P_x=None, P_i=None, A_x=rows.values()[self._order], A_i=None)

    def _duals_for(self, keys):
        """The previous answer's dual of each row named by `keys` (0 for rows it did not have)."""
        y = np.zeros(len(keys))
        if self._last_duals is not None and len(self._last_duals[0]) and len(keys):
            old_keys, old_y = self._last_duals
            at = np.minimum(np.searchsorted(old_keys, keys), len(old_keys) - 1)
            found = old_keys[at] == keys
            y[found] = old_y[at[found]]
        return y

    def _same_structure(self, rows, n_robots):
        if self._structure is None:
            return False
        n, keys = self._structure
        return n == n_robots and np.array_equal(keys, rows.keys)

    def solve(self, p_blocks, q, rows, n_robots, z0, slack0=None):
        """The minimiser over all `rows` as an N x 2 array, or None (info["reason"] says why).

        Most rows are not active at the answer, so OSQP is given only a working set: the rows the
        request z0 breaks or nearly breaks and those that were nearly active in the previous call. If the answer
        breaks a row left out, that row joins and the QP is solved again. When no row is broken,
        the answer of the smaller QP is feasible for the full one, whose feasible set is smaller,
        and so it is also the full QP's answer (constraint generation: exact, not a heuristic).
        """
        slack = rows.slack(z0) if slack0 is None else slack0
        if CONSTRAINT_GENERATION:
            working = (slack < ENTRY_SLACK) | _member(rows.keys, self._sticky_keys)
        else:
            working = np.ones(len(rows), dtype=bool)
        while True:
            sub = rows.subset(working)
            z = self._solve(p_blocks, q, sub, n_robots)
            self.info["rounds"] += 1
            if z is None:
                self._sticky_keys = np.empty(0, dtype=np.int64)
                return None
            slack = rows.slack(z)
            broken = (slack < -ADD_TOLERANCE * _magnitude(z)) & ~working
            if not broken.any():
                break
            working |= broken
        self.info["working_rows"] = int(working.sum())
        # Rows close to binding now are likely to bind next tick: start from them then.
        self._sticky_keys = np.sort(rows.keys[working & (slack < STICKY_SLACK)])
        self.info["max_violation"] = max(0.0, -float(slack.min()))
        return z

    def _solve(self, p_blocks, q, rows, n_robots):
        """Solve with OSQP over `rows`: z (N x 2) or None, with info["reason"] set."""
        try:
            fresh = not self._same_structure(rows, n_robots)
            if fresh:
                self._setup(p_blocks, q, rows, n_robots)
            else:
                self._update(q, rows)
            z, reason = self._run(rows)
            if z is None and not fresh:
                # A warm start can stall where a cold start does not: try once from scratch.
                self._setup(p_blocks, q, rows, n_robots)
                z, reason = self._run(rows)
        except Exception as error:  # OSQP rejects the data (e.g. l > u): no trusted answer
            self._structure = None
            z, reason = None, f"OSQP error: {error}"
        self.info["reason"] = reason
        self._last_x = None if z is None else z.ravel().copy()
        if z is None:
            self._last_duals = self._last_rho = None
        return z

    def _run(self, rows):
        """Solve; (z, "") if OSQP reports the QP solved and its answer satisfies every row, else (None, why).

        First to a moderate tolerance, then polished: OSQP solves the QP again with the rows it found
        active held as equalities, which gives the exact answer when that guess is right (nearly
        always). When polishing fails (a jammed crowd), OSQP carries on to a tight tolerance from
        where it stopped and polishes again; failing that, its answer is accurate to ~1e-6.
        """
        result = self._iterate()
        if result.info.status_val == osqp.SolverStatus.OSQP_SOLVED and result.info.status_polish != 1:
            self._solver.update_settings(eps_abs=TIGHT_TOLERANCE, eps_rel=TIGHT_TOLERANCE)
            try:
                result = self._iterate()
            finally:
                self._solver.update_settings(eps_abs=OSQP_SETTINGS["eps_abs"], eps_rel=OSQP_SETTINGS["eps_rel"])
        info = result.info
        self.info["status"] = str(info.status)
        self.info["polished"] = info.status_polish == 1
        if info.status_val != osqp.SolverStatus.OSQP_SOLVED:
            return None, str(info.status)
        z = np.array(result.x, dtype=float).reshape(-1, 2)
        order = np.argsort(rows.keys)
        self._last_duals = (rows.keys[order], np.array(result.y, dtype=float)[order])
        self._last_rho = float(info.rho_estimate) if np.isfinite(info.rho_estimate) and info.rho_estimate > 0 else None
        if not np.all(np.isfinite(z)):
            return None, "non-finite solution"
        violation = rows.violation(z)
        if violation > FEASIBILITY_TOLERANCE * _magnitude(z):
            return None, f"the solution violates a constraint by {violation:.3g}"
        return z, ""

    def _iterate(self):
        result = self._solver.solve(raise_error=False)
        self.info["iterations"] += int(result.info.iter)
        return result


def reset_info(info, n_robots):
    """Reset the per-call fields of info at the start of a call."""
    info.update(status="", fallback=False, reason="", num_robots=n_robots, num_constraints=0,
                num_pairs=0, iterations=0, setup=False, rounds=0, max_violation=0.0, polished=False,
                working_rows=0, widenings=0, clamped=0.0)


def end_call(info, start):
    """Record the time of the whole call, from `start` (time.perf_counter() on entry)."""
    info["solve_time"] = time.perf_counter() - start
