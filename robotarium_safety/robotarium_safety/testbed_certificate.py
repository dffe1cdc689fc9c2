"""The safety node's certificate: the least change to a command array that keeps robot centres
apart and inside the arena, one step at a time. Plain numpy, no QP, no ROS.

A centre moves only with the forward speed v (a turn never moves it), so every row (a pair closes
at most `rate` of its remaining gap a step, an edge's gap shrinks at most by `rate`) bounds one
robot's v alone: the change is each v moved into the interval its rows allow, and omega is never
touched. Where a command may act late (real time, a declared `latency`), each row holds for every
heading the robot may have turned to meanwhile, and the distances grow by what a robot covers in
the latency. The rows, the guarantee, its assumptions and its proof: docs/safety.md.
"""
import math
import time

import numpy as np

from robotarium_core.config import DEFAULT
from robotarium_core.model import RobotariumError

from .barrier_qp import NeighbourCache, end_call, new_info, reset_info


class TestbedCertificate:
    """f(dxu, x) -> safe dxu (2 x N, x 3 x N); `info` describes the last call (barrier_qp.new_info).
    Set per experiment: `real_time` (a command may act a tick after the poses it was filtered at)
    and `latency` (s more until the robots obey it)."""

    __test__ = False   # not a pytest class, whatever its name

    def __init__(self, config=DEFAULT, latency=0.0, real_time=False):
        self.arena = np.array(config.arena, dtype=float)
        self.distance = config.robot_diameter + config.collision_margin
        self.margin = config.boundary_margin
        self.rate = config.barrier_rate
        self.time_step = config.time_step
        self.max_speed = config.max_linear_velocity
        self.max_turn_rate = config.max_angular_velocity
        x_min, x_max, y_min, y_max = self.arena
        if 2 * self.margin >= min(x_max - x_min, y_max - y_min):
            raise RobotariumError("boundary_margin (%g m) must be less than half the arena's width and height."
                                  % self.margin)
        self.latency = latency
        self.real_time = real_time
        self.info = new_info()
        self._neighbours = NeighbourCache()

    @property
    def reach(self):
        """m a robot may cover before it obeys a command: max_speed x latency."""
        return self.max_speed * max(0.0, float(self.latency))

    @property
    def turn(self):
        """rad a robot may turn between the poses a command is filtered at and its acting."""
        delay = max(0.0, float(self.latency)) + (self.time_step if self.real_time else 0.0)
        return self.max_turn_rate * delay

    def cutoff(self, speed):
        """Centres at least this far apart need no row at |v| <= speed: the rows of the pair hold
        when rate h / T >= 4 speed d (the left sides are at most 2 d speed each)."""
        a = 2 * speed * self.time_step / self.rate
        distance = self.distance + 2 * self.reach
        return a + math.sqrt(a * a + distance * distance)

    def intervals(self, x, speed):
        """(low, high): per robot, the forward speeds every row allows (both hold 0)."""
        n = x.shape[1]
        c, s = np.cos(x[2]), np.sin(x[2])
        x_min, x_max, y_min, y_max = self.arena
        m = self.margin + self.reach
        turn = self.turn
        # Each row is  coef v + slack |v| <= bound  (bound >= 0): v <= bound / (coef + slack) and
        # v >= -bound / (slack - coef), where those are positive. The four edge rows of every robot
        # come as 4 x N arrays (one call per operation whatever N: at small N numpy's per-call cost,
        # not the arithmetic, is the step's); the pair rows, few, follow with minimum.at. A minimum
        # is exact whatever the order, so the intervals are those of one pass over all rows.
        gaps = np.empty((4, n))
        gaps[0] = x_max - m - x[0]
        gaps[1] = x[0] - x_min - m
        gaps[2] = y_max - m - x[1]
        gaps[3] = x[1] - y_min - m
        bound = np.maximum(self.rate * gaps / self.time_step, 0.0)
        coef = np.empty((4, n))
        coef[0] = c
        np.negative(c, out=coef[1])
        coef[2] = s
        np.negative(s, out=coef[3])
        up, down = coef + turn, turn - coef   # |d(cos t)|, |d(sin t)| <= the turn: the slack
        high = np.full((4, n), np.inf)
        low = np.full((4, n), -np.inf)
        with np.errstate(over="ignore"):   # a vanishing coefficient bounds nothing: +-inf is the right limit
            np.divide(bound, up, out=high, where=up > 0)
            np.divide(-bound, down, out=low, where=down > 0)
        high, low = high.min(axis=0), low.max(axis=0)
        centre = np.ascontiguousarray(x[:2].T)
        pairs = self._neighbours.pairs(centre, self.cutoff(speed))
        if len(pairs):
            i, j = pairs[:, 0], pairs[:, 1]
            e = centre[i] - centre[j]
            distance = self.distance + 2 * self.reach
            half = np.maximum(self.rate * (np.einsum("ij,ij->i", e, e) - distance ** 2) / self.time_step, 0.0) / 2
            robots = np.concatenate([i, j])
            coef = np.concatenate([-2 * (e[:, 0] * c[i] + e[:, 1] * s[i]), 2 * (e[:, 0] * c[j] + e[:, 1] * s[j])])
            slack = np.tile(2 * np.hypot(e[:, 0], e[:, 1]) * turn, 2)   # |d(e.n)| <= |e| x the turn
            bound = np.concatenate([half, half])
            up, down = coef + slack > 0, slack - coef > 0
            with np.errstate(over="ignore"):
                np.minimum.at(high, robots[up], bound[up] / (coef + slack)[up])
                np.maximum.at(low, robots[down], -bound[down] / (slack - coef)[down])
        return low, high

    def __call__(self, dxu, x):
        start = time.perf_counter()
        dxu, x = np.asarray(dxu, dtype=float), np.asarray(x, dtype=float)
        if dxu.ndim != 2 or dxu.shape[0] != 2 or x.shape != (3, dxu.shape[1]):
            raise RobotariumError("the testbed certificate takes dxu 2 x N and x 3 x N; received %s and %s"
                                  % (dxu.shape, x.shape))
        n = dxu.shape[1]
        reset_info(self.info, n)
        speed = float(np.abs(dxu[0]).max()) if n else 0.0
        low, high = self.intervals(x, speed)
        v = np.minimum(np.maximum(dxu[0], low), high)
        changed = v != dxu[0]
        self.info["num_constraints"] = 4 * n
        if changed.any():
            self.info["status"] = "clamped"
            self.info["clamped"] = float(np.abs(v - dxu[0]).max())
            safe = np.array([v, dxu[1]])
        else:
            self.info["status"] = "passthrough"
            safe = dxu.copy()
        end_call(self.info, start)
        return safe

