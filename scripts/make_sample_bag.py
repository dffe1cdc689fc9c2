"""Make bags/sample_consensus/: a short recorded run through the real nodes, for replay and report tests.

It starts the simulator, the safety node and the recorder on a private DDS domain, runs 6 robots
in real time (30 Hz) for about 4 s under a consensus controller on a cycle graph (each robot
drives towards the mean of its two neighbours; they start on a wide circle, so they never get
near each other in that time), draws the point they agree on as a script would on r.axes (the
drawing topic), ends the experiment and moves the recorded run folder to
bags/sample_consensus/ (replacing an older one).

Commands: the script publishes on <ns>/cmd_requested as the client would and the safety node
filters them onto cmd_safe.

Run (after ./robotarium setup):  ./robotarium shell, then  python scripts/make_sample_bag.py
"""
import argparse
import math
import os
import shutil
import sys
import tempfile
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)
from geometry_msgs.msg import Twist  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from devtools.rosutil import NodeProcess, RosProbe, unique_domain_id  # noqa: E402
from robotarium_core.topics import LATCHED, TESTBED_QOS  # noqa: E402
from robotarium_msgs.msg import RobotPoses, TwistArray  # noqa: E402
from robotarium_msgs.srv import EndExperiment, StartExperiment  # noqa: E402

NS = "/robotarium"
N = 6


def consensus(poses, gain=0.6, max_speed=0.1):
    """Unicycle commands: single-integrator consensus on a cycle graph, mapped to (v, omega) at a
    look-ahead point as rps' si_to_uni mapping does."""
    x, y, theta = poses
    xy = np.vstack((x, y))
    dxi = gain * (np.roll(xy, 1, axis=1) + np.roll(xy, -1, axis=1) - 2 * xy) / 2
    speed = np.linalg.norm(dxi, axis=0)
    dxi *= np.minimum(1, max_speed / np.maximum(speed, 1e-9))
    v = np.cos(theta) * dxi[0] + np.sin(theta) * dxi[1]
    w = (-np.sin(theta) * dxi[0] + np.cos(theta) * dxi[1]) / 0.05
    return v, np.clip(w, -1.5, 1.5)   # within the wheel limits: no actuator errors


def publish_drawing(probe, started):
    """What an experiment script would draw on r.axes, sent as the client sends it: the point the
    robots agree on (their centroid) marked and labelled, so the sample's video shows a drawing."""
    from robotarium_client.drawing import DrawingWatcher
    from robotarium_core.config import DEFAULT
    from robotarium_core.topics import DRAWING, DRAWING_QOS
    from robotarium_recording.arena_figure import ArenaFigure, pyplot
    from robotarium_recording.drawing import encode
    plt = pyplot()
    poses = np.array([started.x, started.y, started.theta])
    figure = ArenaFigure.live(DEFAULT.arena, DEFAULT.robot_radius, poses, plt=plt)
    watcher = DrawingWatcher(figure.axes, figure.own_artists)
    centre = poses[:2].mean(axis=1)
    figure.axes.scatter(*centre, s=600, marker="s", facecolors="none", edgecolors="tab:green", linewidth=4, zorder=-2)
    figure.axes.text(centre[0], centre[1] + 0.15, "consensus", ha="center", fontsize=12, color="tab:green")
    publisher = probe.node.create_publisher(String, NS + "/" + DRAWING, DRAWING_QOS)
    publisher.publish(String(data=encode(watcher.changes(0))))
    plt.close(figure.figure)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--out", default=os.path.join(REPO, "bags", "sample_consensus"))
    args = parser.parse_args()

    domain = unique_domain_id()
    work = tempfile.mkdtemp(prefix="sample_bag_")
    nodes = [NodeProcess("robotarium_sim.simulator_node", domain, log_path=os.path.join(work, "simulator.log")),
             NodeProcess("robotarium_recording.recorder_node", domain, ros_args=["-p", "bags_dir:=%s" % work],
                         log_path=os.path.join(work, "recorder.log")),
             NodeProcess("robotarium_safety.safety_node", domain, log_path=os.path.join(work, "safety.log"))]
    probe = RosProbe(domain, name="sample_consensus")
    try:
        poses = probe.collect(RobotPoses, NS + "/poses")
        recording = probe.collect(String, NS + "/recording", LATCHED)
        topic = NS + "/cmd_requested"
        publisher = probe.node.create_publisher(TwistArray, topic, TESTBED_QOS)
        ready = lambda: (publisher.get_subscription_count() >= 2  # the safety node and the recorder  # noqa: E731
                         and probe.node.count_subscribers(NS + "/pose_array") >= 1)
        if not probe.spin_until(ready, 30):
            raise RuntimeError("the nodes did not come up; logs in %s" % work)
        probe.spin_for(1.0)
        angles = np.arange(N) * 2 * math.pi / N
        request = StartExperiment.Request(name="sample_consensus", number_of_robots=N, real_time=True)
        request.x = list(0.8 * np.cos(angles) * 1.4)
        request.y = list(0.8 * np.sin(angles))
        request.theta = list(angles + math.pi / 2)
        started = probe.hold_client_presence(probe.call(StartExperiment, NS + "/start_experiment", request))
        if not started.success:
            raise RuntimeError(started.message)
        print(started.message)
        publish_drawing(probe, started)
        step, t_end = 0, time.monotonic() + args.seconds
        while time.monotonic() < t_end:
            probe.spin_until(lambda: poses and poses[-1].step > step, 1.0)
            latest = poses[-1]
            if latest.step == step:
                continue
            step = latest.step
            v, w = consensus(np.array([latest.x, latest.y, latest.theta]))
            msg = TwistArray(step=step, ids=list(range(N)), token=started.token)
            msg.header.stamp = probe.node.get_clock().now().to_msg()
            msg.header.frame_id = "arena"
            for vi, wi in zip(v, w):
                twist = Twist()
                twist.linear.x, twist.angular.z = float(vi), float(wi)
                msg.twists.append(twist)
            publisher.publish(msg)
        ended = probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request(token=started.token))
        print(ended.report)
        probe.spin_until(lambda: recording and recording[-1].data == "", 5)   # the recorder closed the run
        run_dir = ended.recording or os.path.join(work, ended.run_id)
    finally:
        probe.close()
        for node in nodes:
            node.close()
    if os.path.exists(args.out):
        shutil.rmtree(args.out)
    shutil.move(run_dir, args.out)
    size = sum(os.path.getsize(os.path.join(args.out, f)) for f in os.listdir(args.out))
    print("sample run in %s (%d bytes); commands were published on %s" % (args.out, size, topic))


if __name__ == "__main__":
    main()
