"""Real time under load: N = 50 robots at 30 Hz through the whole testbed (simulator, safety node,
recorder: what `./robotarium run` starts) with a real client script, while other processes keep
the cores busy.

The client is this process, the real `Robotarium` class in real time, driving every robot with the
guide's unicycle position controller to a random goal (seeded). `--busy K` starts K processes that
spin a core each for the whole run (default 1: on this project's 2-core machines, one of the two
cores). Read back from the recorded bag:
  - the simulator's tick period and jitter: |period - 1/30 s| between consecutive poses stamps;
  - the safety node's stops (safety_report status STOP_*) and the command timeouts (status);
  - lost messages: poses in the bag against the simulator's steps;
  - CPU share of each process over the run.
Beyond 100 robots the testbed gets a configuration with an arena sized for them (bench_scaling.arena_for:
the packaged arena scaled by sqrt(N / 100)), the robots start on bench_scaling's 0.2 m grid and the
goals are drawn over that arena; issue 26's line is `--robots 200 --busy 0` (goal: jitter p99 < 2 ms,
no safety stop).
Run: ./robotarium bench realtime [--robots 50] [--seconds 30] [--busy 1]
"""
import argparse
import contextlib
import io
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
from bench_scaling import ROBOTS_IN_PACKAGED_ARENA, arena_for, cpu_seconds, grid, write_config  # noqa: E402

from devtools.rosutil import unique_domain_id

BUSY = "while True: pass"


def spaced_points(n, spacing, arena, rng, margin=0.2):
    """n points at least `spacing` apart, drawn uniformly over the arena less `margin` on each side."""
    x_min, x_max, y_min, y_max = arena
    points = np.empty((0, 2))
    while len(points) < n:
        p = rng.uniform([x_min + margin, y_min + margin], [x_max - margin, y_max - margin])
        if not len(points) or np.min(np.hypot(*(points - p).T)) >= spacing:
            points = np.vstack([points, p])
    return points.T


def drive(n, seconds):
    import rps.robotarium
    from rps.utilities.controllers import create_clf_unicycle_position_controller
    from rps.utilities.misc import generate_initial_conditions

    np.random.seed(7)
    if n <= ROBOTS_IN_PACKAGED_ARENA:
        goals = generate_initial_conditions(n, spacing=0.2, width=2.5, height=1.5)[:2]
    else:   # rps draws at most 50: points 0.15 m apart over the larger arena (0.2 m cannot be drawn at random for 200)
        goals = spaced_points(n, 0.15, arena_for(n), np.random.default_rng(7))
    controller = create_clf_unicycle_position_controller(linear_velocity_gain=0.5)
    start = grid(n) if n > ROBOTS_IN_PACKAGED_ARENA else np.array([])   # rps draws them in the packaged arena
    r = rps.robotarium.Robotarium(number_of_robots=n, show_figure=False, sim_in_real_time=True,
                                  initial_conditions=start)
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        x = r.get_poses()
        r.set_velocities(np.arange(n), controller(x, goals))
        r.step()
    with contextlib.redirect_stdout(io.StringIO()):
        r.call_at_scripts_end()
    return r.run_info


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", type=int, default=50)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--busy", type=int, default=1, help="processes that spin a core each during the run")
    args = parser.parse_args()

    os.environ["ROS_DOMAIN_ID"] = str(unique_domain_id())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROBOTARIUM_NAMESPACE"] = "/realtime"
    from robotarium_bringup.testbed import LocalTestbed, testbed_answers
    from robotarium_client import session
    from robotarium_msgs.msg import SafetyReport
    from robotarium_recording.bag import Bag

    work = tempfile.mkdtemp(prefix="robotarium-realtime-")
    config = write_config(work, robots=args.robots) if args.robots > ROBOTS_IN_PACKAGED_ARENA else None
    session.options = session.RunOptions(local_testbed=False, experiment_name="realtime", progress_interval=0.0,
                                         config_file=config)
    testbed = LocalTestbed(log_dir=os.path.join(work, "log"), bags_dir=os.path.join(work, "bags"), ns="/realtime",
                           config_file=config)
    busy = []
    print("real-time benchmark, %s, %s, %d cores, Python %s, load average %.1f" % (
        time.strftime("%Y-%m-%d"), platform.machine(), os.cpu_count(), platform.python_version(),
        os.getloadavg()[0]))
    try:
        testbed.start()
        if not testbed_answers(timeout=60):
            raise RuntimeError("the testbed did not come up (logs in %s)" % testbed.log_dir)
        pids = {name: process.pid for name, (process, _) in testbed.processes.items()}
        busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(args.busy)]
        cpu0, wall0, client0 = {k: cpu_seconds(p) for k, p in pids.items()}, time.monotonic(), time.process_time()
        info = drive(args.robots, args.seconds)
        wall = time.monotonic() - wall0
        cpu = {"client": time.process_time() - client0, **{k: cpu_seconds(p) - cpu0[k] for k, p in pids.items()}}
        for process in busy:
            process.kill()
        deadline = time.monotonic() + 15
        while not os.path.exists(os.path.join(info["recording"], "metadata.yaml")) and time.monotonic() < deadline:
            time.sleep(0.2)
        time.sleep(1.5)   # the recorder's grace period: the bag is closed after it
        bag = Bag(info["recording"])
        poses = bag.poses()
        reports = [int(msg.status) for _, msg in bag.decoded([bag.topic("safety_report")])]
        statuses = bag.statuses()
    finally:
        for process in busy:
            process.kill()
            process.wait()
        testbed.stop()

    periods = np.diff(poses.stamp_ns[poses.steps > 0]) / 1e6
    jitter = np.abs(periods - 1e3 / 30)
    stops = {name: reports.count(getattr(SafetyReport, name)) for name in dir(SafetyReport)
             if name.startswith("STATUS_STOP_")}
    timeouts = max((s.command_timeouts for s in statuses), default=0)
    print("N = %d, real time 30 Hz, %.1f s, %d steps, %d busy process(es)" % (
        args.robots, wall, info["steps"], args.busy))
    print("  tick period        mean %.3f ms, jitter p50 %.3f ms, p99 %.3f ms, max %.3f ms" % (
        periods.mean(), np.percentile(jitter, 50), np.percentile(jitter, 99), jitter.max()))
    print("  safety stops       %s" % ", ".join("%s %d" % (k[len("STATUS_STOP_"):].lower(), v) for k, v in stops.items()))
    print("  command timeouts   %d" % timeouts)
    print("  poses recorded     %d of %d (lost %d)" % (len(poses.steps), info["steps"] + 1,
                                                       info["steps"] + 1 - len(poses.steps)))
    print("  CPU share          %s" % ", ".join("%s %.0f%%" % (k, 100 * v / wall) for k, v in cpu.items()))
    if config:
        print("  arena              %s (arena_for(%d))" % (arena_for(args.robots), args.robots))
    p99 = np.percentile(jitter, 99)
    print("  goals: jitter p99 < 1 ms (N = 50) -> %s; < 2 ms (N = 200, issue 26) -> %s; no safety stops -> %s"
          % ("met" if p99 < 1 else "NOT met", "met" if p99 < 2 else "NOT met", "met" if not sum(stops.values()) else "NOT met"))
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
