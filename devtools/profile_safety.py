"""cProfile of the safety node (or, with --node, the simulator, the recorder or the client) in a lockstep run
(bench_scaling's scene): where its per-step time goes.

Starts the other nodes as `./robotarium run` does, and the profiled node under cProfile; drives N
robots for --steps lockstep steps with the real client, stops the node (SIGINT, so cProfile writes its
numbers) and prints the top functions by cumulative and by own time.
Run: ./robotarium shell -c "python devtools/profile_safety.py --robots 5 --steps 2000"
"""
import argparse
import os
import pstats
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "bench")]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", type=int, default=5)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--top", type=int, default=35)
    parser.add_argument("--node", default="safety", choices=("safety", "simulator", "recorder", "client"),
                        help="the node run under cProfile (default: safety; client: this process's client and "
                             "controller, the loop only)")
    parser.add_argument("--wall", action="store_true",
                        help="time the profile by the wall clock (default: the node's main thread's CPU time, "
                             "which on a loaded machine does not charge a function for waiting for a core)")
    args = parser.parse_args()
    from devtools.rosutil import unique_domain_id
    os.environ["ROS_DOMAIN_ID"] = str(unique_domain_id())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROBOTARIUM_RPS"] = "guide"
    os.environ["ROBOTARIUM_NAMESPACE"] = "/profile"
    import bench_scaling

    from robotarium_bringup.testbed import LocalTestbed

    work = tempfile.mkdtemp(prefix="robotarium-profile-")
    config = bench_scaling.write_config(work, robots=args.robots)
    testbed = LocalTestbed(log_dir=work, bags_dir=os.path.join(work, "bags"), ns="/profile", config_file=config)
    stats = os.path.join(work, "%s.prof" % args.node)
    if args.node == "client":
        client_profile(testbed, config, args, stats)
    else:
        node_profile(testbed, config, args, stats, work)
    time.sleep(0.2)
    for key in ("cumulative", "tottime"):
        pstats.Stats(stats).sort_stats(key).print_stats(args.top)


def node_profile(testbed, config, args, stats, work):
    """The testbed with the node args.node under cProfile, driven by this process's client."""
    import bench_scaling

    from robotarium_bringup.testbed import node_command
    from robotarium_core import lifeline
    testbed.names = [name for name in testbed.names if name != args.node]
    command = node_command(args.node, "/profile", (), config)
    if args.wall:
        command[1:1] = ["-m", "cProfile", "-o", stats]
    else:
        command[1:2] = [os.path.join(ROOT, "devtools", "cpu_profile.py"), stats, "-m"]
    env, pass_fds = lifeline.for_child(os.environ)
    profiled = subprocess.Popen(command, env=env, pass_fds=pass_fds, start_new_session=True,
                                stdout=open(os.path.join(work, "%s.log" % args.node), "wb"), stderr=subprocess.STDOUT)
    try:
        testbed.start()
        processes = {name: process.pid for name, (process, _) in testbed.processes.items()}
        processes[args.node] = profiled.pid
        rate, cpu, _ = bench_scaling.run(args.robots, args.steps, config, processes)
        print("N = %d: %.0f steps/s; CPU ms/step %s" % (args.robots, rate, {k: round(v, 3) for k, v in cpu.items()}))
    finally:
        testbed.stop()
        os.killpg(profiled.pid, signal.SIGINT)
        profiled.wait(timeout=30)


def client_profile(testbed, config, args, stats):
    """The whole testbed, and this process's client (bench_scaling.run: start, loop, end) under cProfile."""
    import cProfile

    import bench_scaling
    profile = cProfile.Profile() if args.wall else cProfile.Profile(time.thread_time)
    try:
        testbed.start()
        processes = {name: process.pid for name, (process, _) in testbed.processes.items()}
        profile.enable()
        rate, cpu, _ = bench_scaling.run(args.robots, args.steps, config, processes)
        profile.disable()
        print("N = %d: %.0f steps/s; CPU ms/step %s" % (args.robots, rate, {k: round(v, 3) for k, v in cpu.items()}))
    finally:
        testbed.stop()
    profile.dump_stats(stats)


if __name__ == "__main__":
    main()
