"""Recorder benchmark: CPU share, bytes per robot-second and lost messages at N = 50 and 30 Hz.

It starts the simulator (real time, 30 Hz) and the recorder in subprocesses on a private DDS
domain, and plays the client and the safety node from this process: for every poses message it
publishes cmd_requested, cmd_safe and safety_report of that step, so that every topic of a full
testbed carries its real load. After --seconds the experiment ends and the bag is read back:
  - recorder CPU share: (user + system CPU time of the recorder process over the run, from
    /proc/<pid>/stat) / wall time of the run;
  - bytes per robot-second: size of the run folder / (N x run seconds);
  - per topic, messages published (simulator: steps + 1 poses and pose_arrays; statuses as heard
    by this process; our own publications counted as sent) against messages in the bag: lost
    must be 0.
Run: ./robotarium bench recorder [--seconds 60] [--robots 50]
"""
import argparse
import os
import platform
import tempfile
import time

from geometry_msgs.msg import Twist  # noqa: E402

from devtools.rosutil import NodeProcess, RosProbe, SafetyStandIn, unique_domain_id  # noqa: E402
from robotarium_core.topics import TESTBED_QOS  # noqa: E402
from robotarium_msgs.msg import RobotPoses, SafetyReport, TestbedStatus, TwistArray  # noqa: E402
from robotarium_msgs.srv import EndExperiment, StartExperiment  # noqa: E402
from robotarium_recording.bag import Bag  # noqa: E402

NS = "/robotarium"


def cpu_seconds(pid):
    """User + system CPU time of a process, from /proc/<pid>/stat (fields 14 and 15, in ticks)."""
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(n, seconds, work):
    domain = unique_domain_id()
    bags = os.path.join(work, "bags_%d" % n)
    sim = NodeProcess("robotarium_sim.simulator_node", domain, log_path=os.path.join(work, "simulator_%d.log" % n))
    recorder = NodeProcess("robotarium_recording.recorder_node", domain, ros_args=["-p", "bags_dir:=%s" % bags],
                           log_path=os.path.join(work, "recorder_%d.log" % n))
    probe = RosProbe(domain, name="bench_recorder")
    try:
        node = probe.node
        safety = SafetyStandIn(probe)
        pubs = {name: node.create_publisher(cls, NS + "/" + name, TESTBED_QOS) for name, cls in
                (("cmd_requested", TwistArray), ("safety_report", SafetyReport))}
        pubs["cmd_safe"] = safety.publisher
        sent = dict.fromkeys(pubs, 0)
        latest = []
        node.create_subscription(RobotPoses, NS + "/poses", lambda m: latest.append(m.step), 100)
        statuses = probe.collect(TestbedStatus, NS + "/status", 1000)
        ready = lambda: (pubs["cmd_safe"].get_subscription_count() >= 2  # noqa: E731
                         and node.count_subscribers(NS + "/pose_array") >= 1 and node.count_publishers(NS + "/status") >= 1)
        if not probe.spin_until(ready, 60):
            raise RuntimeError("nodes did not come up (logs in %s)" % work)
        probe.spin_for(1.0)
        cmd = TwistArray(ids=list(range(n)), twists=[Twist() for _ in range(n)])
        for i, twist in enumerate(cmd.twists):
            twist.linear.x, twist.angular.z = 0.02, 0.3 * (-1) ** i
        report = SafetyReport(status=SafetyReport.STATUS_PASSTHROUGH, number_of_robots=n)

        started = probe.hold_client_presence(probe.call(StartExperiment, NS + "/start_experiment",
                                                        StartExperiment.Request(name="bench", number_of_robots=n,
                                                                                real_time=True, seed=7)))
        assert started.success, started.message
        safe_cmd = TwistArray(ids=cmd.ids, twists=cmd.twists, token=safety.armed.safety_key)
        cmd.token = started.token
        cpu0, t0 = cpu_seconds(recorder.proc.pid), time.monotonic()
        answered = -1
        while time.monotonic() - t0 < seconds:
            probe.executor.spin_once(timeout_sec=0.05)
            if latest and latest[-1] != answered:   # as client + safety would: one command set per step
                answered = latest[-1]
                stamp = node.get_clock().now().to_msg()
                cmd.step = safe_cmd.step = report.step = answered + 1
                cmd.header.stamp = safe_cmd.header.stamp = report.header.stamp = stamp
                for name, msg in (("cmd_requested", cmd), ("cmd_safe", safe_cmd), ("safety_report", report)):
                    pubs[name].publish(msg)
                    sent[name] += 1
        probe.spin_for(0.2)
        ended = probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request(token=started.token))
        wall = time.monotonic() - t0
        probe.spin_for(1.5)                      # the recorder's grace period, then it closes the bag
        cpu = cpu_seconds(recorder.proc.pid) - cpu0
    finally:
        probe.close()
        recorder.close()
        sim.close()
    path = ended.recording or os.path.join(bags, ended.run_id)
    bag = Bag(path)
    # The simulator's statuses of this run, as an independent subscriber (this process) heard them:
    # RUNNING ones of the run id (every step, and once a second), then the IDLE one.
    running = sum(1 for m in statuses if m.run_id == ended.run_id and m.state == TestbedStatus.STATE_RUNNING)
    published = {"poses": ended.steps + 1, "pose_array": ended.steps + 1, "status": running + 1, **sent}
    recorded = {name: bag.topics.get(NS + "/" + name).count if NS + "/" + name in bag.topics else 0 for name in published}
    size = sum(os.path.getsize(os.path.join(path, f)) for f in os.listdir(path))
    return {"n": n, "wall": wall, "steps": ended.steps, "cpu": cpu, "size": size, "published": published,
            "recorded": recorded, "complete": bag.complete, "path": path}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60.0, help="length of the recorded run (default 60)")
    parser.add_argument("--robots", type=int, nargs="+", default=[50])
    args = parser.parse_args()
    print("recorder benchmark, %s, %s, %d cores, Python %s, load average %.1f" % (
        time.strftime("%Y-%m-%d"), platform.processor() or platform.machine(), os.cpu_count(),
        platform.python_version(), os.getloadavg()[0]))
    with tempfile.TemporaryDirectory(prefix="bench_recorder_") as work:
        for n in args.robots:
            r = run(n, args.seconds, work)
            lost_total = 0
            print("\nN = %d robots, real time 30 Hz, %.1f s, %d steps (%.1f Hz)" % (
                n, r["wall"], r["steps"], r["steps"] / r["wall"]))
            print("  %-15s %10s %10s %6s" % ("topic", "published", "recorded", "lost"))
            for name, count in r["published"].items():
                lost = count - r["recorded"][name]
                lost_total += max(lost, 0)
                print("  %-15s %10d %10d %6d" % (name, count, r["recorded"][name], lost))
            print("  %-15s %10d %10d %6d" % ("all", sum(r["published"].values()), sum(r["recorded"].values()), lost_total))
            print("  recorder CPU share      %6.1f %%  (%.2f s CPU in %.1f s)"
                  % (100 * r["cpu"] / r["wall"], r["cpu"], r["wall"]))
            print("  bag size                %6.2f MB  (%s, closed: %s)"
                  % (r["size"] / 1e6, os.path.basename(r["path"]), r["complete"]))
            print("  bytes per robot-second  %6.0f" % (r["size"] / (n * r["wall"])))
            print("  goal: 0 lost  ->  %s" % ("met" if lost_total == 0 else "NOT met"))


if __name__ == "__main__":
    main()
