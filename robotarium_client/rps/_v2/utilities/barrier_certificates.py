"""Barrier certificates with 2.x's names, signatures and QPs (2.1.0 rps/utilities/barrier_certificates.py).

2.x poses min ||v - v_hat||^2 subject to A v <= b with cvxopt (relative tolerance 1e-2); here the
same rows are solved exactly with quadprog (a dense active-set solver). The rows, as 2.x builds them:
pairs i < j: -2 e.(v_i - v_j) <= g h^3 (e = x_i - x_j, h = |e|^2 - r^2); with a boundary
[x_min, x_max, y_min, y_max], per robot, v_y <= 0.4 g (y_max - r/2 - y)^3 and the same for the other
three walls; and the speed bounded by an 8-sided polygon of radius magnitude_limit cos(pi/8) (the
first row of the single integrator without boundary at magnitude_limit, as 2.x). A failed QP
gives zeros and a warning, as 2.x.
"""
import warnings

import numpy as np
import quadprog

from rps.utilities.transformations import *  # noqa: F401,F403 (2.x's module brings them too)
from rps.utilities.transformations import create_si_to_uni_mapping, create_uni_to_si_mapping

__all__ = ["np", "create_si_barrier_certificate", "create_si_barrier_certificate_with_boundary",
           "create_uni_barrier_certificate", "create_uni_barrier_certificate_with_boundary",
           "create_si_to_uni_mapping", "create_uni_to_si_mapping"]

_POLYGON = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1]], dtype=float)
_POLYGON /= np.linalg.norm(_POLYGON, axis=1)[:, None]


def _solve_qp(N, vhat, A, b):
    """min ||v - vhat||^2 s.t. A v <= b, v = (v_0x, v_0y, v_1x, ...); the 2 x N answer or None."""
    vhat = np.asarray(vhat, dtype=float).reshape(-1, order="F")
    A, b = np.asarray(A, dtype=float), np.asarray(b, dtype=float).reshape(-1)
    try:
        x = quadprog.solve_qp(np.eye(2 * N), vhat, -A.T, -b)[0]
    except ValueError:   # infeasible (or a degenerate constraint set)
        return None
    return np.reshape(x, (2, N), order="F")


def _pair_rows(x, radius, gain):
    n = x.shape[1]
    i, j = np.triu_indices(n, 1)
    e = x[:, i] - x[:, j]
    h = np.einsum("ij,ij->j", e, e) - radius ** 2
    A = np.zeros((len(i), 2 * n))
    rows = np.arange(len(i))
    for k in range(2):
        A[rows, 2 * i + k] = -2 * e[k]
        A[rows, 2 * j + k] = 2 * e[k]
    return A, gain * h ** 3


def _polygon_rows(n, limit, first_row_full):
    A = np.zeros((8 * n, 2 * n))
    b = np.full(8 * n, limit * np.cos(np.pi / 8))
    for i in range(n):
        A[8 * i:8 * i + 8, 2 * i:2 * i + 2] = _POLYGON
        if first_row_full:
            b[8 * i] = limit
    return A, b


def _boundary_rows(x, bp, radius, gain):
    n = x.shape[1]
    A = np.zeros((4 * n, 2 * n))
    b = np.zeros(4 * n)
    half, k = radius / 2, 0.4 * gain
    for i in range(n):
        A[4 * i:4 * i + 4, 2 * i:2 * i + 2] = [[0, 1], [0, -1], [1, 0], [-1, 0]]
        b[4 * i:4 * i + 4] = k * np.array([bp[3] - half - x[1, i], x[1, i] - bp[2] - half,
                                           bp[1] - half - x[0, i], x[0, i] - bp[0] - half]) ** 3
    return A, b


def create_si_barrier_certificate(safety_radius=0.15, barrier_gain=100.0, magnitude_limit=0.2):
    """f(dxi 2xN, x 2xN) -> safe dxi (robots at least safety_radius apart)."""
    def barrier_certificate(dxi, x):
        n = dxi.shape[1]
        if n < 2:
            return dxi
        A1, b1 = _pair_rows(x[:2], safety_radius, barrier_gain)
        A2, b2 = _polygon_rows(n, magnitude_limit, True)
        v = _solve_qp(n, dxi, np.vstack([A1, A2]), np.concatenate([b1, b2]))
        if v is None:
            warnings.warn("create_si_barrier_certificate: QP failed. Commanding zero velocities.", stacklevel=2)
            return np.zeros((2, n))
        return v
    return barrier_certificate


def create_si_barrier_certificate_with_boundary(safety_radius=0.15, barrier_gain=100.0, magnitude_limit=0.2,
                                                boundary_points=None):
    """As create_si_barrier_certificate, and robots stay inside boundary_points (default
    [-1.7, 1.7, -1.1, 1.1], as 2.x)."""
    def barrier_certificate(dxi, x):
        n = dxi.shape[1]
        if n < 2:
            return dxi
        bp = boundary_points if boundary_points is not None else np.array([-1.7, 1.7, -1.1, 1.1])
        A1, b1 = _pair_rows(x[:2], safety_radius, barrier_gain)
        A2, b2 = _boundary_rows(x[:2], bp, safety_radius, barrier_gain)
        A3, b3 = _polygon_rows(n, magnitude_limit, False)
        v = _solve_qp(n, dxi, np.vstack([A1, A2, A3]), np.concatenate([b1, b2, b3]))
        if v is None:
            warnings.warn("create_si_barrier_certificate_with_boundary: QP failed. Commanding zero velocities.", stacklevel=2)
            return np.zeros((2, n))
        return v
    return barrier_certificate


def _unicycle(si_barrier, projection_distance, where):
    si_to_uni, uni_to_si_states = create_si_to_uni_mapping(projection_distance=projection_distance)
    uni_to_si, _ = create_uni_to_si_mapping(projection_distance=projection_distance)

    def barrier_unicycle(dxu, x, obstacles=None):
        n = dxu.shape[1]
        if n < 2:
            return dxu
        xi, dxi = uni_to_si_states(x), uni_to_si(dxu, x)
        if obstacles is not None and np.asarray(obstacles).size > 0:   # fixed points, as 2.x
            obstacles = np.asarray(obstacles, dtype=float)
            xi = np.hstack([xi, obstacles])
            dxi = np.hstack([dxi, np.zeros((2, obstacles.shape[1]))])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            safe = si_barrier(dxi, xi)
        if any("QP failed" in str(w.message) for w in caught):
            warnings.warn("%s: Safety QP failed. Commanding zero velocities." % where, stacklevel=2)
            return np.zeros((2, n))
        return si_to_uni(safe[:, :n], x)
    return barrier_unicycle


def create_uni_barrier_certificate(barrier_gain=100.0, safety_radius=0.15, projection_distance=0.05,
                                   velocity_magnitude_limit=0.2):
    """f(dxu 2xN, x 3xN) -> safe dxu: the single-integrator certificate, radius safety_radius +
    2 projection_distance, on the points projection_distance ahead."""
    si = create_si_barrier_certificate(safety_radius=safety_radius + 2 * projection_distance,
                                       barrier_gain=barrier_gain, magnitude_limit=velocity_magnitude_limit)
    return _unicycle(si, projection_distance, "create_uni_barrier_certificate")


def create_uni_barrier_certificate_with_boundary(safety_radius=0.12, barrier_gain=150.0, projection_distance=0.03,
                                                 velocity_magnitude_limit=0.2, boundary_points=None):
    """As create_uni_barrier_certificate (2.x's defaults differ), with the boundary (default the
    arena) on the points ahead; f(dxu, x, obstacles=None), obstacles 2xM fixed points."""
    bp = boundary_points if boundary_points is not None else np.array([-1.6, 1.6, -1.0, 1.0])
    si = create_si_barrier_certificate_with_boundary(safety_radius=safety_radius + 2 * projection_distance,
                                                     barrier_gain=barrier_gain,
                                                     magnitude_limit=velocity_magnitude_limit, boundary_points=bp)
    return _unicycle(si, projection_distance, "create_uni_barrier_certificate_with_boundary")
