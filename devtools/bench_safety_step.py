"""CPU time of the safety node's per-step pure work, in this process (no ROS): parse the poses and
the request, filter (guard.filter_commands with the testbed certificate), build cmd_safe and
safety_report; and the simulator's poses. bench_scaling's scene at its first step and mid-way.
Run: ./robotarium shell -c "python devtools/bench_safety_step.py [--robots 5 20 100]"
"""
import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "bench")]


def per_call(function, seconds=0.3):
    """CPU µs per call (time.process_time), the best of 3 batches."""
    function()
    best = np.inf
    for _ in range(3):
        calls, start = 0, time.process_time()
        while time.process_time() - start < seconds / 3:
            for _ in range(20):
                function()
            calls += 20
        best = min(best, (time.process_time() - start) / calls)
    return best * 1e6


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--robots", type=int, nargs="+", default=[5, 20, 100])
    args = parser.parse_args()
    import bench_scaling

    from robotarium_core import cdr
    from robotarium_core.config import DEFAULT
    from robotarium_safety.guard import filter_commands
    from robotarium_safety.testbed_certificate import TestbedCertificate
    from rps.utilities.controllers import create_clf_unicycle_position_controller

    controller = create_clf_unicycle_position_controller()
    print("CPU µs per call, in process")
    print("%5s %10s %10s %10s %10s %10s %10s" % ("N", "filter", "build cmd", "build rep", "parse pose", "parse cmd",
                                              "build pose"))
    for n in args.robots:
        x = bench_scaling.grid(n)
        goals = -x[:2]
        certificate = TestbedCertificate(DEFAULT)
        dxu = controller(x, goals)
        filter_call = lambda: filter_commands(certificate, dxu, x, DEFAULT)   # noqa: E731
        ids = np.arange(n)
        cmd = lambda: cdr.TWIST_ARRAY.build(sec=1, nanosec=2, frame_id="arena", token="k" * 32, step=7, ids=ids,   # noqa: E731
                                            twists=cdr.twists(dxu[0], dxu[1]), requested_exceeds_limits=False,
                                            refreshed=False)
        report = lambda: cdr.SAFETY_REPORT.build(sec=1, nanosec=2, frame_id="arena", number_of_robots=n,   # noqa: E731
                                                 solve_time=0.001, step=7, refreshed=False, pose_age=0.0, status=2,
                                                 solver_status="passthrough", max_change=0.0, robots_changed=0,
                                                 ideal_change=0.0, foreign=0, stale=0)
        pose_bytes = cdr.ROBOT_POSES.build(sec=1, nanosec=2, frame_id="arena", run_id="r" * 20, key="p" * 32,
                                           step=7, sim_time=0.2, ids=ids, x=x[0], y=x[1], theta=x[2])
        pose = lambda: cdr.ROBOT_POSES.build(sec=1, nanosec=2, frame_id="arena", run_id="r" * 20, key="p" * 32,   # noqa: E731
                                             step=7, sim_time=0.2, ids=ids, x=x[0], y=x[1], theta=x[2])
        cmd_bytes = cmd()
        print("%5d %10.1f %10.1f %10.1f %10.1f %10.1f %10.1f" % (
            n, per_call(filter_call), per_call(cmd), per_call(report),
            per_call(lambda: cdr.ROBOT_POSES.parse(pose_bytes, max_elements=n)),
            per_call(lambda: cdr.parse_commands(cmd_bytes, n, token="k" * 32)), per_call(pose)))


if __name__ == "__main__":
    main()
