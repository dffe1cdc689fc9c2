"""Which threads of each testbed process spend the CPU of a lockstep step: each node's main thread
(its executor and callbacks: Python) against Fast DDS's own threads (receive, events: C++).
bench_scaling's scene; the client is this process.
Run: ./robotarium shell -c "python devtools/thread_cpu.py --robots 5 20 --steps 1000"
"""
import argparse
import collections
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "bench")]
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def threads(pid):
    """{thread name: CPU seconds} of a process ("main" for its main thread; Fast DDS's threads by name)."""
    times = collections.Counter()
    for tid in os.listdir("/proc/%d/task" % pid):
        try:
            with open("/proc/%d/task/%s/stat" % (pid, tid)) as f:
                fields = f.read().rsplit(")", 1)[1].split()
            with open("/proc/%d/task/%s/comm" % (pid, tid)) as f:
                name = f.read().strip()
        except OSError:
            continue
        name = "main" if int(tid) == pid else name.rstrip("0123456789.")   # one row per kind of thread
        times[name] += (int(fields[11]) + int(fields[12])) / CLOCK_TICKS
    return times


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robots", type=int, nargs="+", default=[5, 20])
    parser.add_argument("--steps", type=int, default=1000)
    args = parser.parse_args()
    from devtools.rosutil import unique_domain_id
    os.environ["ROS_DOMAIN_ID"] = str(unique_domain_id())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROBOTARIUM_RPS"] = "guide"
    os.environ["ROBOTARIUM_NAMESPACE"] = "/threads"
    import bench_scaling

    from robotarium_bringup.testbed import LocalTestbed

    work = tempfile.mkdtemp(prefix="robotarium-threads-")
    config = bench_scaling.write_config(work, robots=max(args.robots))
    testbed = LocalTestbed(log_dir=work, bags_dir=os.path.join(work, "bags"), ns="/threads", config_file=config)
    try:
        testbed.start()
        processes = {name: process.pid for name, (process, _) in testbed.processes.items()}
        processes["client"] = os.getpid()
        for n in args.robots:
            before = {name: threads(pid) for name, pid in processes.items()}
            rate, _, _ = bench_scaling.run(n, args.steps, config, {})
            print("N = %d: %.0f steps/s (load average %.1f); CPU ms/step per thread (>= 0.02):" % (
                n, rate, os.getloadavg()[0]))
            for name, pid in processes.items():
                after = threads(pid)
                spent = {k: (after[k] - before[name].get(k, 0)) / (args.steps + 5) * 1e3 for k in after}
                print("  %-10s %6.3f  %s" % (name, sum(spent.values()), "  ".join(
                    "%s %.3f" % (k, v) for k, v in sorted(spent.items(), key=lambda kv: -kv[1]) if v >= 0.02)))
    finally:
        testbed.stop()


if __name__ == "__main__":
    main()
