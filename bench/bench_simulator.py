"""Simulator node benchmark: real-time tick period and jitter, and lockstep steps per second.

For N = 1, 5, 20, 50 robots it starts the simulator node in a subprocess (own DDS domain,
localhost only) and measures
  - real time: the period between consecutive ticks as stamped by the node itself (header
    stamps of the poses), its mean and the 99th percentile of |period - 1/30 s|;
  - lockstep: steps per second when a client publishes a command array on cmd_safe and waits
    for the poses of that step before sending the next (the simulator alone; this process plays
    the safety node's part). The client does what the Robotarium client does: it publishes CDR
    bytes and takes the poses raw (robotarium_core.cdr), here from a bare wait set, so the figure
    is the simulator's round trip, not rclpy's message objects or executor.
Run: ./robotarium bench simulator [--seconds S] [--steps K]
"""
import argparse
import os
import platform
import time

import numpy as np
from rclpy.impl.implementation_singleton import rclpy_implementation  # noqa: E402

from devtools.rosutil import NodeProcess, RosProbe, SafetyStandIn, unique_domain_id  # noqa: E402
from robotarium_core import cdr, model  # noqa: E402
from robotarium_core.topics import TESTBED_QOS  # noqa: E402
from robotarium_msgs.msg import RobotPoses  # noqa: E402
from robotarium_msgs.srv import EndExperiment, StartExperiment  # noqa: E402

NS = "/robotarium"


def start(probe, n, real_time):
    response = probe.hold_client_presence(probe.call(StartExperiment, NS + "/start_experiment", StartExperiment.Request(
        name="bench", number_of_robots=n, real_time=real_time, seed=1)))
    assert response.success, response.message
    probe.token = response.token
    probe.poses_key = response.poses_key   # new for every experiment (two runs can share a run id)
    return response.run_id


def end(probe):
    probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request(token=probe.token))


def real_time_jitter(probe, n, seconds):
    poses = probe.collect(RobotPoses, NS + "/poses")
    start(probe, n, real_time=True)
    probe.spin_for(seconds)
    end(probe)
    # (the subscription also gets the last poses of the lockstep run before: transient-local history)
    stamps = np.array([p.header.stamp.sec + p.header.stamp.nanosec * 1e-9 for p in poses
                       if p.step > 0 and p.key == probe.poses_key])
    periods = np.diff(stamps)
    jitter = np.abs(periods - 1 / 30)
    return periods.mean() * 1e3, np.percentile(jitter, 99) * 1e3, len(stamps)


def lockstep_rate(probe, n, steps):
    """Measured before the real-time part: no other subscriber of this process on poses."""
    node = probe.node
    poses = node.create_subscription(RobotPoses, NS + "/poses", lambda data: None, TESTBED_QOS, raw=True)
    publisher = probe.safety.publisher
    start(probe, n, real_time=False)
    probe.spin_until(lambda: publisher.get_subscription_count() > 0, 10)
    wait_set = rclpy_implementation.WaitSet(1, 0, 0, 0, 0, 0, probe.context.handle)
    newest = [-1]

    def take_poses(timeout):
        wait_set.clear_entities()
        wait_set.add_subscription(poses.handle)
        wait_set.wait(int(timeout * 1e9))
        while (taken := poses.handle.take_message(poses.msg_type, True)) is not None:
            msg = cdr.ROBOT_POSES.parse(taken[0])
            if msg.key == probe.poses_key:   # not the last poses of an earlier run (transient-local history)
                newest[0] = msg.step
    ids, twists = np.arange(n), cdr.twists(np.full(n, 0.01), np.full(n, 0.1))
    key = probe.safety.armed.safety_key
    t0 = time.perf_counter()
    for k in range(1, steps + 1):
        publisher.publish(cdr.TWIST_ARRAY.build(frame_id="arena", token=key, step=k, ids=ids, twists=twists))
        deadline = time.monotonic() + 5
        while newest[0] < k:
            if time.monotonic() > deadline:
                raise RuntimeError("lockstep stalled at step %d" % k)
            take_poses(0.1)
    elapsed = time.perf_counter() - t0
    end(probe)
    node.destroy_subscription(poses)
    return steps / elapsed


def model_rate(n, steps):
    tb = model.Testbed(model.random_initial_conditions(n, np.random.default_rng(1)))
    tb.set_commands(range(n), np.full(n, 0.01), np.full(n, 0.1))
    t0 = time.perf_counter()
    for _ in range(steps):
        tb.step()
    return steps / (time.perf_counter() - t0)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=5.0, help="real-time measurement per N")
    parser.add_argument("--steps", type=int, default=1000, help="lockstep steps per N")
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 5, 20, 50])
    args = parser.parse_args()

    print("simulator benchmark, %s, %s, %d cores, %s" % (
        time.strftime("%Y-%m-%d"), platform.processor() or platform.machine(), os.cpu_count(),
        platform.python_version()))
    print("%4s | %16s %18s %7s | %18s | %16s" % (
        "N", "tick mean (ms)", "jitter p99 (ms)", "ticks", "lockstep steps/s", "model steps/s"))
    for n in args.robots:
        domain = unique_domain_id()
        sim = NodeProcess("robotarium_sim.simulator_node", domain)
        probe = RosProbe(domain, name="bench")
        probe.safety = SafetyStandIn(probe)   # the simulator alone: this process plays the safety node
        try:
            rate = lockstep_rate(probe, n, args.steps)
            mean_ms, p99_ms, ticks = real_time_jitter(probe, n, args.seconds)
        finally:
            probe.close()
            sim.close()
        print("%4d | %16.3f %18.3f %7d | %18.0f | %16.0f" % (n, mean_ms, p99_ms, ticks, rate, model_rate(n, 5000)))
    print("goals: jitter p99 < 1 ms at N = 50; lockstep >= 2000 steps/s at N = 20")


if __name__ == "__main__":
    main()
