"""A careless or hostile neighbour on the testbed's DDS domain: floods both command topics.

    python -m devtools.flood [--namespace /robotarium] [--rate 1000] [--seconds 3] [--robots 8]
                             [--huge-every 500] [--poses RUN_ID]

It publishes, on cmd_requested and on cmd_safe each, `rate` arrays a second for `seconds`,
taking turns: a well-formed array of `robots` twists at full speed with a token that is not the
experiment's, the same with no token, and bytes that are no TwistArray (a wrong encapsulation,
cut short inside the header); every `huge_every`-th array is 100,000 twists (2.4 MB). With
--poses it also publishes poses claiming RUN_ID with every robot 1 m from any other. Publishers
are reliable, keep-all and wait until the testbed's nodes have matched them, so that every array
sent reaches them: it prints "flooding" when it begins, and at the end one JSON line
{topic: {kind: count}} of what it sent.
"""
import argparse
import json
import time

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from robotarium_core import cdr
from robotarium_core.topics import TESTBED_QOS, readers_matched
from robotarium_msgs.msg import RobotPoses, TwistArray

QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.VOLATILE)
HUGE = 100_000


def arrays(robots):
    """The kinds of array the flood sends, as bytes: {kind: bytes}."""
    rng = np.random.default_rng(7)
    ids = np.arange(robots)
    full = cdr.twists(np.full(robots, 0.2), rng.uniform(-3, 3, robots))
    good = cdr.TWIST_ARRAY.build(frame_id="arena", token="f" * 32, ids=ids, twists=full)
    return {
        "foreign": good,
        "no_token": cdr.TWIST_ARRAY.build(frame_id="arena", ids=ids, twists=full),
        "bad_encapsulation": b"\x00\x07\x00\x00" + good[4:],
        "truncated": good[:14],
        "huge": cdr.TWIST_ARRAY.build(frame_id="arena", token="f" * 32, ids=np.arange(HUGE) % robots,
                                      twists=cdr.twists(np.full(HUGE, 0.2), np.zeros(HUGE))),
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--namespace", default="/robotarium")
    parser.add_argument("--rate", type=float, default=1000.0, help="arrays per second on each topic")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--robots", type=int, default=8)
    parser.add_argument("--huge-every", type=int, default=500)
    parser.add_argument("--poses", metavar="RUN_ID", help="also publish fake poses of this run")
    args = parser.parse_args(argv)

    rclpy.init()
    node = Node("flood")
    ns = args.namespace.rstrip("/")
    topics = ["%s/cmd_requested" % ns, "%s/cmd_safe" % ns]
    publishers = {topic: node.create_publisher(TwistArray, topic, QOS) for topic in topics}
    # (poses as the simulator offers them: the safety node's poses reader is transient-local)
    poses_pub = node.create_publisher(RobotPoses, ns + "/poses", TESTBED_QOS) if args.poses else None
    # The safety node listens on cmd_requested, the simulator on cmd_safe (a recorder on both):
    # wait until every reader is matched, so that every array sent reaches each.
    listeners = [(publishers[topics[0]], "safety"), (publishers[topics[1]], "simulator")]
    if poses_pub is not None:
        listeners.append((poses_pub, "safety"))
    deadline = time.monotonic() + 30
    while not all(readers_matched(node, publisher, name) for publisher, name in listeners):
        if time.monotonic() > deadline:
            raise SystemExit("flood: nobody listens on %s" % topics)
        time.sleep(0.05)
    kinds = arrays(args.robots)
    turn = ["foreign", "no_token", "bad_encapsulation", "truncated"]
    far = np.arange(args.robots, dtype=float)
    fake = RobotPoses(run_id=args.poses or "", ids=list(range(args.robots)), x=list(-1.5 + far * 0.4),
                      y=[0.0] * args.robots, theta=[0.0] * args.robots)
    sent = {topic: dict.fromkeys(turn + ["huge"], 0) for topic in topics}
    sent["poses"] = 0
    period = 1.0 / args.rate
    print("flooding", flush=True)
    start = time.monotonic()
    k = 0
    while time.monotonic() - start < args.seconds:
        kind = "huge" if args.huge_every and k % args.huge_every == args.huge_every - 1 else turn[k % len(turn)]
        for topic, publisher in publishers.items():
            publisher.publish(kinds[kind])
            sent[topic][kind] += 1
        if poses_pub is not None and k % 10 == 0:   # 100 Hz of fake poses, ahead of the real ones
            fake.step = 10 ** 6 + k
            poses_pub.publish(fake)
            sent["poses"] += 1
        k += 1
        time.sleep(max(0.0, start + k * period - time.monotonic()))
    for publisher in publishers.values():
        publisher.wait_for_all_acked()
    print(json.dumps(sent), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
