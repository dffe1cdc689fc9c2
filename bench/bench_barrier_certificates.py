"""Benchmark: robotarium_safety's barrier certificates (OSQP) against rps 0.0.0's (cvxopt).

    .venv/bin/python bench/bench_barrier_certificates.py [--ticks 120]

Scenes: N robots start spread over the arena and drive to random goals (a new goal when one is
reached) under the single-integrator position controller of rps (gain 1, speed <= 0.15 m/s), the
certificate under test keeping them apart. Each tick's (request, state) pair is recorded once; then
both libraries are timed on the very same sequence: ours here, the reference in its own venv
(tests/reference.py), each timing its own calls with time.perf_counter. "exact" is the same QP
(every pair) solved with quadprog (tests/test_barrier_dense_qp.py). Printed: median and 95th
percentile wall time per call, the speed-up (reference median / ours), the largest differences
between the answers, and the share of calls that needed a QP (the others were already safe).
For unicycles the differences are in (v, w): w is 1/projection_distance = 20 times more sensitive
than the single-integrator velocity the QP is posed in.
"""
import argparse
import os
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "tests"))   # the dense QP the certificates are checked against

import test_barrier_dense_qp as dense  # noqa: E402

from devtools.reference import reference_available, run_reference  # noqa: E402
from robotarium_safety import barrier_certificates as bc  # noqa: E402

DT = 0.033
PROJECTION = 0.05
ARENA = np.array([-1.6, 1.6, -1.0, 1.0])


def initial_positions(n, rng, scale=1.0):
    """n well-spaced positions in the arena (scaled by `scale`), and whether they are crowded:
    random cells of a 0.3 m grid (as rps's generate_initial_conditions) while they fit, else a
    random subset of the widest hexagonal lattice that holds them."""
    width, height = 3.0 * scale, 1.8 * scale
    spacing = 0.3
    nx, ny = int(width / spacing), int(height / spacing)
    if nx * ny >= 1.5 * n:
        cells = rng.choice(nx * ny, n, replace=False)
        corner = np.array([[-width / 2 + 0.15], [-height / 2 + 0.15]])
        return corner + spacing * np.vstack([cells // ny, cells % ny]), False
    for spacing in (0.3, 0.27, 0.25, 0.23, 0.21, 0.2, 0.19, 0.18, 0.175):
        row_step = spacing * np.sqrt(3) / 2
        half_w, half_h = 1.6 * scale - 0.15, 1.0 * scale - 0.15
        points = np.array([(x + (k % 2) * spacing / 2, y)
                           for k, y in enumerate(np.arange(-half_h, half_h + 1e-9, row_step))
                           for x in np.arange(-half_w, half_w - spacing / 2 + 1e-9, spacing)]).T
        if points.shape[1] >= 1.2 * n or spacing == 0.175:
            break
    return points[:, rng.choice(points.shape[1], n, replace=False)], True


def goals_for(n, rng, scale=1.0):
    return scale * np.vstack([rng.uniform(-1.4, 1.4, n), rng.uniform(-0.8, 0.8, n)])


def position_controller(points, goals):
    dxi = goals - points
    norms = np.linalg.norm(dxi, axis=0)
    over = norms > 0.15
    dxi[:, over] *= 0.15 / norms[over]
    return dxi


def si_scenes(n, ticks, seed):
    """[(dxi, x)] from single integrators driving to random goals under our SI certificate."""
    rng = np.random.default_rng(seed)
    x, _ = initial_positions(n, rng)
    goals = goals_for(n, rng)
    cert = bc.create_single_integrator_barrier_certificate_with_boundary()
    scenes = []
    for _ in range(ticks):
        reached = np.linalg.norm(goals - x, axis=0) < 0.05
        goals[:, reached] = goals_for(int(reached.sum()), rng)
        dxi = position_controller(x, goals)
        scenes.append((dxi.copy(), x.copy()))
        x = x + DT * cert(dxi, x)
    return scenes


def uni_scenes(n, ticks, seed, scale=1.0):
    """[(dxu, x)] from unicycles driving to random goals under our unicycle certificate, in the
    arena scaled by `scale` (the certificate's boundary too)."""
    rng = np.random.default_rng(seed)
    positions, crowded = initial_positions(n, rng, scale)
    # In a crowd, the points ahead of the robots are only as far apart as the robots when all
    # robots face the same way; random headings would start some pairs inside the safety radius.
    headings = np.zeros(n) if crowded else rng.uniform(-np.pi, np.pi, n)
    x = np.vstack([positions, headings])
    goals = goals_for(n, rng, scale)
    cert = bc.create_unicycle_barrier_certificate_with_boundary(boundary_points=scale * ARENA)
    scenes = []
    for _ in range(ticks):
        c, s = np.cos(x[2]), np.sin(x[2])
        points = x[:2] + PROJECTION * np.vstack([c, s])
        reached = np.linalg.norm(goals - points, axis=0) < 0.05
        goals[:, reached] = goals_for(int(reached.sum()), rng, scale)
        dxu = dense.si_to_uni(position_controller(points, goals), x, PROJECTION)
        scenes.append((dxu.copy(), x.copy()))
        safe = cert(dxu, x)
        x = x + DT * np.vstack([safe[0] * c, safe[0] * s, safe[1]])
        x[2] = np.arctan2(np.sin(x[2]), np.cos(x[2]))
    return scenes


def time_ours(f, scenes):
    """Wall time per call, the answers, and counts of QP calls, fallbacks and pairs kept."""
    times, answers, solved, fallbacks, pairs = [], [], 0, 0, []
    for request, state in scenes:
        start = time.perf_counter()
        answers.append(f(request, state))
        times.append(time.perf_counter() - start)
        solved += f.info["status"] != "passthrough"
        fallbacks += f.info["fallback"]
        pairs.append(f.info["num_pairs"])
    return np.array(times), answers, solved, fallbacks, np.mean(pairs)


REFERENCE_CODE = """
import time
import numpy as np
from rps.utilities import barrier_certificates as bc
f = getattr(bc, name)()
times, answers = [], []
for request, state in scenes:
    request = request.copy()  # rps scales the request in place
    start = time.perf_counter()
    answer = f(request, state)
    times.append(time.perf_counter() - start)
    answers.append(np.array(answer, dtype=float))
result["times"] = times
result["answers"] = answers
"""


def time_reference(name, scenes):
    out = run_reference(REFERENCE_CODE, name=name, scenes=scenes)
    return np.array(out["times"]), out["answers"]


def exact_answers(kind, scenes):
    if kind == "si":
        return [dense.si_exact(r, s, boundary=dense.ARENA) for r, s in scenes]
    return [dense.uni_exact(r, s, boundary=dense.ARENA) for r, s in scenes]


def largest_difference(a, b):
    return max(float(np.abs(x - y).max()) for x, y in zip(a, b))


def ms(seconds):
    return f"{1e3 * seconds:8.3f}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=120, help="calls per scene sequence (default 120)")
    parser.add_argument("--sizes", type=int, nargs="*", default=[5, 10, 20, 50])
    parser.add_argument("--large", type=int, nargs="*", default=[100, 200])
    args = parser.parse_args()
    if not reference_available():
        sys.exit("The reference venv (.venv-reference) is missing: ./robotarium setup creates it.")

    kinds = [("si", "create_single_integrator_barrier_certificate_with_boundary", si_scenes),
             ("uni", "create_unicycle_barrier_certificate_with_boundary", uni_scenes)]
    print(f"{args.ticks} calls per row, times in ms per call (wall clock); speed-up = reference median / ours;")
    print("diff columns: largest |difference| over all calls (m/s for single integrators, (v, w) for unicycles);")
    print("exact = the full QP (every pair) solved by quadprog. QP% = calls that needed a QP.\n")
    header = (f"{'certificate (create_...)':<48} {'N':>4} {'ours med':>8} {'ours p95':>8} {'ref med':>8} "
              f"{'ref p95':>8} {'speed-up':>8} {'ours-exact':>10} {'ref-exact':>9} {'ours-ref':>8} {'QP%':>4}")
    print(header)
    print("-" * len(header))
    for kind, name, make_scenes in kinds:
        for n in args.sizes:
            scenes = make_scenes(n, args.ticks, seed=n)
            ours, our_answers, solved, fallbacks, _ = time_ours(getattr(bc, name)(), scenes)
            ref, ref_answers = time_reference(name, scenes)
            exact = exact_answers(kind, scenes)
            print(f"{name[7:]:<48} {n:>4} {ms(np.median(ours))} {ms(np.percentile(ours, 95))} "
                  f"{ms(np.median(ref))} {ms(np.percentile(ref, 95))} {np.median(ref) / np.median(ours):>7.1f}x "
                  f"{largest_difference(our_answers, exact):>10.1e} {largest_difference(ref_answers, exact):>9.1e} "
                  f"{largest_difference(our_answers, ref_answers):>8.1e} {100 * solved / len(scenes):>3.0f}%"
                  + (f"  ({fallbacks} fallbacks)" if fallbacks else ""))

    name = "create_unicycle_barrier_certificate_with_boundary"
    print(f"\nours only, {name}:")
    header = (f"{'scene':<44} {'N':>4} {'ours med':>8} {'ours p95':>8} {'max':>8} {'pairs kept':>10} "
              f"{'of':>6} {'QP%':>4}")
    print(header)
    print("-" * len(header))
    runs = [(n, 1.0, "the 3.2 m x 2 m arena (a jam at these N)") for n in args.large]
    # The same number of robots at the density of 50 in the arena: the arena scaled by 2 per side.
    runs += [(n, 2.0, "6.4 m x 4 m (the density of 50 in the arena)") for n in args.large if n == 200]
    for n, scale, label in runs:
        scenes = uni_scenes(n, args.ticks, seed=n, scale=scale)
        times, _, solved, fallbacks, kept = time_ours(
            bc.create_unicycle_barrier_certificate_with_boundary(boundary_points=scale * ARENA), scenes)
        print(f"{label:<44} {n:>4} {ms(np.median(times))} {ms(np.percentile(times, 95))} {ms(times.max())} "
              f"{kept:>10.0f} {n * (n - 1) // 2:>6} {100 * solved / len(scenes):>3.0f}%"
              + (f"  ({fallbacks} fallbacks)" if fallbacks else ""))


if __name__ == "__main__":
    main()
