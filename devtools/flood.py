"""A careless or hostile neighbour on the testbed's DDS domain: floods both command topics.

    python -m devtools.flood [--namespace /robotarium] [--rate 1000] [--seconds 3] [--robots 8]
                             [--huge-every 500] [--poses RUN_ID] [--forge [--burst 1]]

It publishes, on cmd_requested and on cmd_safe each, `rate` arrays a second for `seconds`,
taking turns: a well-formed array of `robots` twists at full speed with a token that is not the
experiment's, the same with no token, and bytes that are no TwistArray (a wrong encapsulation,
cut short inside the header); every `huge_every`-th array is 100,000 twists (2.4 MB). With
--poses it also publishes poses claiming RUN_ID with every robot 1 m from any other. Publishers
are reliable, keep-all and wait until the testbed's nodes have matched them, so that every array
sent reaches them: it prints "flooding" when it begins, and at the end one JSON line
{topic: {kind: count}} of what it sent. --rate 0: as fast as it can.

With --forge it first copies the running experiment's token off the wire (the client's arrays on
cmd_requested: without SROS2 the token is no secret) and then also sends, on cmd_requested,
arrays with that token driving every robot straight ahead at full speed: "forged_next" (step 0,
unnumbered) and "forged_step" (from the client's newest step seen, -2 to +1, on: re-sends, the
next step, steps ahead), --burst of them back to back each time (forged_step: consecutive steps),
and in place of each huge array a "forged_huge" (100,000 twists with the token).
"""
import argparse
import json
import os
import time

import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.impl.implementation_singleton import rclpy_implementation
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


def publish(publisher, data, counts, kind):
    """Publish and count; at the highest rate the readers' acknowledgements may not keep up and
    DDS refuses the array after blocking a while: counted as "refused" (never sent)."""
    try:
        publisher.publish(data)
        counts[kind] += 1
    except rclpy_implementation.RCLError:
        counts["refused"] = counts.get("refused", 0) + 1


class Forger:
    """Arrays with the experiment's token, copied from the client's arrays on cmd_requested."""

    def __init__(self, node, topic, robots):
        self.node = node
        self.token, self.step = None, 0
        self.robots = robots
        self.full_ahead = cdr.twists(np.full(robots, 0.2), np.zeros(robots))
        self.rng = np.random.default_rng(11)
        # (a short history: the flood's own arrays come back here too, and a keep-all reader would slow it)
        node.create_subscription(TwistArray, topic, self.on_array, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE),
                                 raw=True)

    def on_array(self, data):
        try:
            msg = cdr.TWIST_ARRAY.parse(data, max_elements=1000)
        except cdr.CdrError:
            return
        if msg.token and msg.token != "f" * 32 and msg.frame_id != "forged":   # not our own arrays
            self.token = msg.token
            self.step = max(self.step, msg.step)

    def wait_for_token(self, deadline):
        while self.token is None:
            if time.monotonic() > deadline:
                raise SystemExit("flood: no array with a token seen on cmd_requested (is a client running?)")
            rclpy.spin_once(self.node, timeout_sec=0.05)

    def array(self, kind, offset=0):
        if kind == "forged_huge":
            return cdr.TWIST_ARRAY.build(frame_id="forged", token=self.token, step=self.step + 1,
                                         ids=np.arange(HUGE) % self.robots,
                                         twists=cdr.twists(np.full(HUGE, 0.2), np.zeros(HUGE)))
        step = 0 if kind == "forged_next" else max(0, self.step + offset)
        return cdr.TWIST_ARRAY.build(frame_id="forged", token=self.token, step=step, ids=np.arange(self.robots),
                                     twists=self.full_ahead)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--namespace", default="/robotarium")
    parser.add_argument("--rate", type=float, default=1000.0, help="arrays per second on each topic")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--robots", type=int, default=8)
    parser.add_argument("--huge-every", type=int, default=500)
    parser.add_argument("--poses", metavar="RUN_ID", help="also publish fake poses of this run")
    parser.add_argument("--forge", action="store_true",
                        help="copy the experiment's token from cmd_requested and send arrays with it too")
    parser.add_argument("--burst", type=int, default=1, help="forged arrays sent back to back each time (with --forge)")
    parser.add_argument("--nice", type=int, default=0,
                        help="run at this lower priority (os.nice): the rate is still the highest the CPU left over allows")
    args = parser.parse_args(argv)
    if args.nice:
        os.nice(args.nice)

    rclpy.init()
    node = Node("flood")
    ns = args.namespace.rstrip("/")
    topics = ["%s/cmd_requested" % ns, "%s/cmd_safe" % ns]
    publishers = {topic: node.create_publisher(TwistArray, topic, QOS) for topic in topics}
    # (poses as the simulator offers them: reliable and volatile, as the safety node reads them)
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
    forged = Forger(node, topics[0], args.robots) if args.forge else None
    if forged is not None:
        forged.wait_for_token(deadline + 30)
    far = np.arange(args.robots, dtype=float)
    fake = RobotPoses(run_id=args.poses or "", ids=list(range(args.robots)), x=list(-1.5 + far * 0.4),
                      y=[0.0] * args.robots, theta=[0.0] * args.robots)
    sent = {topic: dict.fromkeys(turn + ["huge"], 0) for topic in topics}
    if forged is not None:
        sent[topics[0]].update(forged_next=0, forged_step=0, forged_huge=0)
    sent["poses"] = 0
    period = 1.0 / args.rate if args.rate > 0 else 0.0
    print("flooding", flush=True)
    start = time.monotonic()
    k = 0
    while time.monotonic() - start < args.seconds:
        kind = "huge" if args.huge_every and k % args.huge_every == args.huge_every - 1 else turn[k % len(turn)]
        for topic, publisher in publishers.items():
            publish(publisher, kinds[kind], sent[topic], kind)
        if forged is not None:
            rclpy.spin_once(node, timeout_sec=0)   # the client's newest step
            forge = "forged_huge" if kind == "huge" else ("forged_next", "forged_step")[k % 2]
            offset = int(forged.rng.integers(-2, 2))   # a run of steps from just behind the client's to ahead
            for i in range(1 if forge == "forged_huge" else args.burst):
                publish(publishers[topics[0]], forged.array(forge, offset + i), sent[topics[0]], forge)
        if poses_pub is not None and k % 10 == 0:   # 100 Hz of fake poses, ahead of the real ones
            fake.step = 10 ** 6 + k
            poses_pub.publish(fake)
            sent["poses"] += 1
        k += 1
        if period:
            time.sleep(max(0.0, start + k * period - time.monotonic()))
    for publisher in publishers.values():   # what is still in flight reaches the nodes (a slow recorder may never ack it all)
        publisher.wait_for_all_acked(Duration(seconds=5))
    print(json.dumps(sent), flush=True)
    node.destroy_node()   # (a clean end: the nodes drop what they hold of our writers at once, not after a lease)
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
