"""How the whole stack scales with the number of robots in lockstep, and which process pays.

One local testbed (simulator, safety node and, unless --no-record, the recorder: what
`./robotarium run` starts) on a DDS domain of its own, with a testbed configuration that admits
up to the largest N asked for; the client is this process, the real `Robotarium` class. For each N the robots
start on a 0.2 m grid and drive, with the guide's unicycle position controller, to the grid point
mirrored through the arena's centre, so every path crosses the middle and the safety node's
barrier certificate has work to do. Beyond 100 robots the arena grows with the largest N asked for
(`arena_for`: the packaged arena scaled by sqrt(N / 100), so the robots' density stays that of
100 robots in the packaged arena); the same arena serves every N of one run. Printed per N: steps
per second of the loop, and the CPU time each process spent per step (the client's includes its
own controller, which is small), with each one's share of the total.
With --api 2 the client is the 2.x Robotarium (robotarium_client.robotarium2, distance sensors on,
no drive-on phase), so the simulator publishes the 2.x sensors too, and --standard-sensor-rate R
sets the rate of their per-robot standard topics (robot_<i>/imu, mag, range; 0: off) to compare.
Run: ./robotarium bench scaling [--robots 1 5 10 20 50 100 200 400] [--steps 600] [--no-record] [--api 2]
     [--standard-sensor-rate R]
"""
import argparse
import contextlib
import io
import os
import platform
import shutil
import tempfile
import time

import numpy as np
import yaml

from devtools.rosutil import unique_domain_id

ROBOT_LIMIT = 400   # the packaged configuration says 50 (the guide's simulator); the model has no limit
ROBOTS_IN_PACKAGED_ARENA = 100   # up to this many, the packaged arena; more get a larger one (arena_for)
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid):
    """User + system CPU time of a process (all its threads) so far."""
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def grid(n, spacing=0.2):
    """n positions on a grid centred in the arena, rows filled first, with random headings."""
    columns = int(np.ceil(np.sqrt(n * 1.6)))
    rows = int(np.ceil(n / columns))
    k = np.arange(n)
    x = (k % columns - (columns - 1) / 2) * spacing
    y = (k // columns - (rows - 1) / 2) * spacing
    return np.array([x, y, np.random.default_rng(n).uniform(-np.pi, np.pi, n)])


def arena_for(n):
    """The packaged arena, scaled about its centre by sqrt(n / 100) when n > 100 robots (so that
    the grid of `grid` fits with room to drive, and the density stays that of 100 robots)."""
    from robotarium_core.config import DEFAULT
    scale = max(1.0, np.sqrt(n / ROBOTS_IN_PACKAGED_ARENA))
    x_min, x_max, y_min, y_max = DEFAULT.arena
    cx, cy, hx, hy = (x_min + x_max) / 2, (y_min + y_max) / 2, (x_max - x_min) / 2, (y_max - y_min) / 2
    return [float(round(v, 3)) for v in (cx - scale * hx, cx + scale * hx, cy - scale * hy, cy + scale * hy)]


def write_config(folder, standard_sensor_rate=None, robots=ROBOT_LIMIT):
    """A testbed configuration (the packaged one) that admits `robots` robots in arena_for(robots)."""
    from robotarium_core.config import DEFAULT
    values = dict(DEFAULT.to_dict(), max_robots=max(robots, DEFAULT.max_robots), arena=arena_for(robots))
    if standard_sensor_rate is not None:
        values["standard_sensor_rate"] = standard_sensor_rate
    path = os.path.join(folder, "testbed_%d_robots.yaml" % robots)
    with open(path, "w") as f:
        yaml.safe_dump({"/**": {"ros__parameters": values}}, f, sort_keys=False)
    return path


def run(n, steps, config_file, processes, api=""):
    from robotarium_client import session
    from robotarium_client.robotarium import Robotarium
    from rps.utilities.controllers import create_clf_unicycle_position_controller

    session.options = session.RunOptions(real_time=False, local_testbed=False, experiment_name="scaling_%d" % n,
                                         progress_interval=0.0, config_file=config_file)
    start = grid(n)
    goals = -start[:2]
    controller = create_clf_unicycle_position_controller()
    if api == "2":
        from robotarium_client.robotarium2 import Robotarium as Robotarium2
        r = Robotarium2(number_of_robots=n, show_figure=False, initial_conditions=start, sim_in_real_time=False,
                        skip_initialization=True, use_distance_sensors=True)
    else:
        r = Robotarium(number_of_robots=n, show_figure=False, initial_conditions=start, sim_in_real_time=False)
    for _ in range(5):   # warm up (first messages, first QP set-up)
        x = r.get_poses()
        r.set_velocities(np.arange(n), controller(x, goals))
        r.step()
    cpu0 = {name: cpu_seconds(pid) for name, pid in processes.items()}
    client0, wall0 = time.process_time(), time.perf_counter()
    for _ in range(steps):
        x = r.get_poses()
        r.set_velocities(np.arange(n), controller(x, goals))
        r.step()
    wall = time.perf_counter() - wall0
    cpu = {"client": time.process_time() - client0}
    cpu.update({name: cpu_seconds(pid) - cpu0[name] for name, pid in processes.items()})
    with contextlib.redirect_stdout(io.StringIO()):
        r.call_at_scripts_end()
    counts = {k: getattr(r.run_info, k) for k in ("collisions", "boundary_violations")}
    return steps / wall, {name: seconds / steps * 1e3 for name, seconds in cpu.items()}, counts


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 5, 10, 20, 50, 100, 200, 400])
    parser.add_argument("--steps", type=int, default=600, help="lockstep steps per N")
    parser.add_argument("--no-record", action="store_true", help="leave the recorder out")
    parser.add_argument("--api", choices=["", "2"], default="", help="'2': the 2.x client (sensors published)")
    parser.add_argument("--standard-sensor-rate", type=float, default=None,
                        help="Hz of the 2.x sensors' per-robot standard topics (default: the configuration's)")
    args = parser.parse_args()
    if max(args.robots) > ROBOT_LIMIT:
        parser.error("at most %d robots" % ROBOT_LIMIT)

    os.environ["ROS_DOMAIN_ID"] = str(unique_domain_id())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROBOTARIUM_RPS"] = "guide"   # rps is the guide's (its controller); --api 2 imports the 2.x class itself
    from robotarium_bringup.testbed import LocalTestbed

    work = tempfile.mkdtemp(prefix="robotarium-scaling-")
    testbed = LocalTestbed(log_dir=os.path.join(work, "log"), record=not args.no_record,
                           bags_dir=os.path.join(work, "bags"), ns="/scaling",
                           config_file=write_config(work, args.standard_sensor_rate, max(args.robots)))
    os.environ["ROBOTARIUM_NAMESPACE"] = "/scaling"
    print("scaling benchmark, %s, %s, %d cores, Python %s, load average %.1f, recorder %s, api %s%s" % (
        time.strftime("%Y-%m-%d"), platform.machine(), os.cpu_count(), platform.python_version(),
        os.getloadavg()[0], "off" if args.no_record else "on", args.api or "guide",
        "" if args.standard_sensor_rate is None else ", standard_sensor_rate %g" % args.standard_sensor_rate))
    names = ["client", "safety", "simulator"] + ([] if args.no_record else ["recorder"])
    print("arena %s (arena_for(%d))" % (arena_for(max(args.robots)), max(args.robots)))
    print("CPU time per step (ms) and share of the total, per process:")
    print("%5s %9s %9s | %s | %s" % ("N", "steps/s", "ms/step", " ".join("%9s" % n for n in names),
                                     " ".join("%9s" % n for n in names)))
    try:
        testbed.start()
        processes = {name: process.pid for name, (process, _) in testbed.processes.items()}
        for n in args.robots:
            rate, cpu, counts = run(n, args.steps, testbed.config_file, processes, args.api)
            total = sum(cpu.values())
            print("%5d %9.0f %9.3f | %s | %s" % (
                n, rate, 1e3 / rate, " ".join("%9.3f" % cpu[name] for name in names),
                " ".join("%8.0f%%" % (100 * cpu[name] / total) for name in names)), flush=True)
            if any(counts.values()):
                print("      (the run had %(collisions)d collision and %(boundary_violations)d boundary iterations)" % counts)
    finally:
        testbed.stop()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
