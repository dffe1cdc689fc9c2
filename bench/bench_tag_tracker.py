"""The camera path against the fleet's truth: a simulated fleet tracked by the camera stand-in (30 Hz JPEG
frames: perspective, blur, noise) and the tag tracker node, the robots driving circles; prints the pose
error (median, p99) of the tracker's poses against where the bodies really were when each frame was
taken, the latency from that moment to the pose's arrival, the frames that came, and the tracker's CPU
per frame. With the date, the machine and its load.

Real processes: the robots (robot_node), the camera stand-in, the tag tracker; the truth from the fleet's
world file (robotarium_hardware.world), sampled every 2 ms and carried forward along each body's arc to a
frame's stamp.

Run: ./robotarium bench tag_tracker [--robots N] [--seconds S]
"""
import argparse
import math
import os
import platform
import sys
import tempfile
import threading
import time

import numpy as np

from devtools.rosutil import NodeProcess, RosProbe, node_env, unique_domain_id


def cpu_seconds(pid):
    """User + system CPU seconds of process `pid` so far."""
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=6)
    parser.add_argument("--seconds", type=float, default=20.0, help="of measurement, after a warm-up of 3 s")
    args = parser.parse_args()
    from geometry_msgs.msg import PoseStamped, Twist, TwistStamped

    from robotarium_hardware.sim_fleet import SimulatedFleet
    from robotarium_hardware.tracking import yaw_from_quaternion
    from robotarium_hardware.world import OMEGA, STAMP, THETA, V, X, Y

    domain = unique_domain_id()
    folder = tempfile.mkdtemp(prefix="bench-tag-tracker-")
    fleet = SimulatedFleet(args.robots, "camera", os.path.join(folder, "fleet.yaml"), env=node_env(domain),
                           log_dir=folder)
    fleet.start(say=lambda line: None)
    tracker = probe = None
    try:
        if not fleet.wait_ready():
            sys.exit("the fleet did not come up: %s (logs in %s)" % (fleet.failed(), folder))
        tracker = NodeProcess("robotarium_hardware.tag_tracker_node", domain,
                              ros_args=["-p", "fleet_file:=%s" % fleet.fleet_file],
                              log_path=os.path.join(folder, "tag_tracker.log"))
        probe = RosProbe(domain, "bench_tag_tracker")
        received = []   # (robot, arrival time.time(), stamp, x, y, theta)
        commands = []
        for k, robot in enumerate(fleet.fleet.robots):
            stamped = robot.cmd_type == "TwistStamped"
            commands.append((probe.node.create_publisher(TwistStamped if stamped else Twist, "/%s/cmd_vel" % robot.name,
                                                         10), stamped))

            def heard(msg, k=k):
                o = msg.pose.orientation
                received.append((k, time.time(), msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
                                 msg.pose.position.x, msg.pose.position.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)))
            probe.node.create_subscription(PoseStamped, fleet.fleet.pose_topic(robot), heard, 50)
        truth, stop = [], threading.Event()

        def sample():   # the bodies every 2 ms
            while not stop.is_set():
                truth.append(fleet.world.read())
                time.sleep(0.002)
        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()

        def drive(until):   # circles of 0.2 m radius, commands at 10 Hz (the robots' own timeout is 0.3 s)
            next_command = 0.0
            while time.monotonic() < until:
                if time.monotonic() >= next_command:
                    for publisher, stamped in commands:
                        msg = TwistStamped() if stamped else Twist()
                        twist = msg.twist if stamped else msg
                        twist.linear.x, twist.angular.z = 0.1, 0.5
                        publisher.publish(msg)
                    next_command = time.monotonic() + 0.1
                probe.executor.spin_once(timeout_sec=0.01)
        drive(time.monotonic() + 3.0)   # warm-up: matching, the robots up to speed
        received.clear()
        cpu_before, wall_before = cpu_seconds(tracker.proc.pid), time.monotonic()
        drive(time.monotonic() + args.seconds)
        cpu, wall = cpu_seconds(tracker.proc.pid) - cpu_before, time.monotonic() - wall_before
        stop.set()
        sampler.join()
    finally:
        if probe is not None:
            probe.node.destroy_node()
        if tracker is not None:
            tracker.close()
        fleet.stop()

    samples = np.array(truth)   # (looks, robots, fields)
    position, heading, latency = [], [], []
    for k, arrived, stamp, x, y, theta in received:
        rows = samples[:, k]
        before = rows[rows[:, STAMP] <= stamp]
        if not len(before):
            continue
        s = before[np.argmax(before[:, STAMP])]   # the body's newest state at the frame's moment, carried forward
        dt = stamp - s[STAMP]
        middle = s[THETA] + s[OMEGA] * dt / 2
        tx, ty = s[X] + s[V] * dt * math.cos(middle), s[Y] + s[V] * dt * math.sin(middle)
        position.append(math.hypot(x - tx, y - ty))
        heading.append(abs(math.remainder(theta - (s[THETA] + s[OMEGA] * dt), 2 * math.pi)))
        latency.append(arrived - stamp)
    frames = len({stamp for _, _, stamp, *_ in received})
    position, heading, latency = (np.array(v) for v in (position, heading, latency))
    load = os.getloadavg()
    print("bench_tag_tracker: %s, %s (%s, %d cores), load %.2f %.2f %.2f" % (
        time.strftime("%Y-%m-%d %H:%M"), platform.node(), platform.machine(), os.cpu_count(), *load))
    print("%d robots driving circles (0.1 m/s, 0.5 rad/s); camera stand-in 1280 x 800 JPEG at 30 Hz; %.0f s"
          % (args.robots, args.seconds))
    print("frames tracked     %d (%.1f a second), %d poses (%.2f robots a frame)" % (
        frames, frames / args.seconds, len(position), len(position) / max(frames, 1)))
    print("position error     median %.2f mm, p99 %.2f mm, max %.2f mm" % (
        1e3 * np.median(position), 1e3 * np.percentile(position, 99), 1e3 * position.max()))
    print("heading error      median %.2f deg, p99 %.2f deg" % (
        math.degrees(np.median(heading)), math.degrees(np.percentile(heading, 99))))
    print("latency            median %.1f ms, p99 %.1f ms (frame taken -> pose received)" % (
        1e3 * np.median(latency), 1e3 * np.percentile(latency, 99)))
    print("tracker CPU        %.1f ms a frame (%.0f %% of a core)" % (1e3 * cpu / max(frames, 1), 100 * cpu / wall))


if __name__ == "__main__":
    main()
