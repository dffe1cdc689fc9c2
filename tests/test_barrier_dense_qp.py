"""An independent statement of every barrier QP, for checking robotarium_safety.barrier_certificates.

The QPs are written out densely, row by row with plain loops, straight from rps 0.0.0
(rps/utilities/barrier_certificates.py and barrier_certificates2.py), with every pair and no
pruning, and solved exactly with a different solver (quadprog, an active-set method, not OSQP).
The tests and bench/bench_barrier_certificates.py import the helpers below; the tests in this file
check the helpers themselves against closed forms.
"""
import numpy as np
import pytest
import quadprog

ARENA = np.array([-1.6, 1.6, -1.0, 1.0])


def limit_request(dxi, limit):
    dxi = np.array(dxi, dtype=float)
    for k in range(dxi.shape[1]):
        norm = np.linalg.norm(dxi[:, k])
        if norm > limit:
            dxi[:, k] *= limit / norm
    return dxi


def si_qp(dxi, x, gain=100, radius=0.17, limit=0.2, boundary=None, unsafe_gain=None):
    """(H, f, A, b, u_request) with the QP  min 1/2 u'Hu + f'u  s.t.  A u <= b  in u = vec(dxi)."""
    n = dxi.shape[1]
    dxi = limit_request(dxi, limit)
    rows, rhs = [], []
    for i in range(n - 1):
        for j in range(i + 1, n):
            e = x[:, i] - x[:, j]
            h = e @ e - radius ** 2
            row = np.zeros(2 * n)
            row[2 * i:2 * i + 2] = -2 * e
            row[2 * j:2 * j + 2] = 2 * e
            g = unsafe_gain if (unsafe_gain is not None and h < 0) else gain
            rows.append(row)
            rhs.append(g * h ** 3)
    if boundary is not None:
        for k in range(n):
            for axis, sign, value in ((1, 1, boundary[3] - radius / 2 - x[1, k]),
                                      (1, -1, -boundary[2] - radius / 2 + x[1, k]),
                                      (0, 1, boundary[1] - radius / 2 - x[0, k]),
                                      (0, -1, -boundary[0] - radius / 2 + x[0, k])):
                row = np.zeros(2 * n)
                row[2 * k + axis] = sign
                rows.append(row)
                rhs.append(0.4 * gain * value ** 3)
    A = np.array(rows).reshape(-1, 2 * n)
    return 2 * np.eye(2 * n), -2 * dxi.ravel(order="F"), A, np.array(rhs), dxi


def solve_le(H, f, A, b):
    """Exact minimiser of 1/2 u'Hu + f'u subject to A u <= b (quadprog)."""
    if len(b) == 0:
        return np.linalg.solve(H, -f)
    return quadprog.solve_qp(H, -f, -A.T, -b)[0]


def si_exact(dxi, x, **kw):
    H, f, A, b, _ = si_qp(dxi, x, **kw)
    return solve_le(H, f, A, b).reshape(2, -1, order="F")


def uni_to_si(dxu, x, l):
    c, s = np.cos(x[2]), np.sin(x[2])
    return np.vstack([c * dxu[0] - l * s * dxu[1], s * dxu[0] + l * c * dxu[1]]), x[:2] + l * np.vstack([c, s])


def si_to_uni(dxi, x, l):
    c, s = np.cos(x[2]), np.sin(x[2])
    return np.vstack([c * dxi[0] + s * dxi[1], np.clip((-s * dxi[0] + c * dxi[1]) / l, -np.pi, np.pi)])


def uni_exact(dxu, x, gain=100, radius=0.12, l=0.05, limit=0.2, boundary=None, unsafe_gain=None):
    dxi, p = uni_to_si(dxu, x, l)
    return si_to_uni(si_exact(dxi, p, gain=gain, radius=radius + l, limit=limit, boundary=boundary,
                              unsafe_gain=unsafe_gain), x, l)


def dd_qp(dxu, x, obstacles=None, d=5, wheel_limit=12.5, base=0.105, wheel_r=0.016, l=0.05, gain=150, radius=0.17,
          boundary=None):
    """(H, f, A, b, D) with  min 1/2 w'Hw + f'w  s.t.  A w >= b  in the wheel speeds w."""
    n = dxu.shape[1]
    D = np.array([[wheel_r / 2, wheel_r / 2], [-wheel_r / base, wheel_r / base]])
    L = np.array([[1, 0], [0, l]]) @ D
    corners = np.array([[-d, -d, d, d], [-d, d, d, -d]])
    p = np.zeros((2, n))
    MD = []
    for k in range(n):
        c, s = np.cos(x[2, k]), np.sin(x[2, k])
        p[:, k] = x[:2, k] + l * np.array([c, s])
        MD.append(np.array([[c, -l * s], [s, l * c]]) @ D)
    rows, rhs = [], []
    for i in range(n - 1):
        for j in range(i + 1, n):
            e = p[:, i] - p[:, j]
            h = e @ e - radius ** 2
            hi, hj = 2 * e @ MD[i], -2 * e @ MD[j]
            row = np.zeros(2 * n)
            row[2 * i:2 * i + 2], row[2 * j:2 * j + 2] = hi, hj
            rows.append(row)
            rhs.append(-gain * h ** 3 - np.min(hi @ corners) - np.min(hj @ corners))
    if obstacles is not None:
        for i in range(n):
            for o in range(obstacles.shape[1]):
                e = p[:, i] - obstacles[:, o]
                h = e @ e - radius ** 2
                hi = 2 * e @ MD[i]
                row = np.zeros(2 * n)
                row[2 * i:2 * i + 2] = hi
                rows.append(row)
                rhs.append(-gain * h ** 3 - np.min(hi @ corners))
    if boundary is not None:
        for k in range(n):
            for axis, sign, value in ((1, -1, boundary[3] - radius / 2 - p[1, k]),
                                      (1, 1, -boundary[2] - radius / 2 + p[1, k]),
                                      (0, -1, boundary[1] - radius / 2 - p[0, k]),
                                      (0, 1, -boundary[0] - radius / 2 + p[0, k])):
                row = np.zeros(2 * n)
                row[2 * k:2 * k + 2] = sign * MD[k][axis]
                rows.append(row)
                rhs.append(-0.4 * gain * value ** 3)
    for k in range(2 * n):
        for sign in (-1, 1):
            row = np.zeros(2 * n)
            row[k] = sign
            rows.append(row)
            rhs.append(-wheel_limit)
    L_all = np.kron(np.eye(n), L)
    w_request = (np.linalg.inv(D) @ dxu).ravel(order="F")
    H = 2 * L_all.T @ L_all
    return H, -H @ w_request, np.array(rows), np.array(rhs), D


def dd_exact(dxu, x, **kw):
    H, f, A, b, D = dd_qp(dxu, x, **kw)
    w = quadprog.solve_qp(H, -f, A.T, b)[0]
    return D @ w.reshape(2, -1, order="F")


# ---- the helpers against closed forms -------------------------------------------------------


def test_si_exact_two_robots_is_the_projection_onto_one_half_plane():
    x = np.array([[0.0, 0.3], [0.0, 0.0]])
    dxi = np.array([[0.15, -0.1], [0.02, 0.0]])
    e = x[:, 0] - x[:, 1]
    a = np.concatenate([-2 * e, 2 * e])
    b = 100 * (e @ e - 0.17 ** 2) ** 3
    u0 = dxi.ravel(order="F")
    expected = u0 - a * max(0.0, a @ u0 - b) / (a @ a)
    assert a @ u0 > b  # the request is unsafe, so the projection moves it
    np.testing.assert_allclose(si_exact(dxi, x), expected.reshape(2, 2, order="F"), atol=1e-12)


def test_si_exact_boundary_rows_clip_each_axis():
    x = np.array([[1.5], [0.0]])
    dxi = np.array([[0.2], [0.0]])
    bound = 0.4 * 100 * (1.6 - 0.085 - 1.5) ** 3
    np.testing.assert_allclose(si_exact(dxi, x, boundary=ARENA), [[bound], [0.0]], atol=1e-12)


def test_dd_exact_clips_wheels_along_the_cheapest_direction():
    # One robot far from everything asks for too fast a spin: only the wheel limits bind, and the
    # minimiser of (v - v0)^2 + l^2 (w - w0)^2 over |wheels| <= 12.5 keeps v = 0.
    dxu = np.array([[0.0], [10.0]])
    out = dd_exact(dxu, np.zeros((3, 1)))
    assert out[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert out[1, 0] == pytest.approx(12.5 * 0.016 / 0.105 * 2, rel=1e-9)
