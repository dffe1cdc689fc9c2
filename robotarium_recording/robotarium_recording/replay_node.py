"""Replay a recorded run: republish its topics with the original timing, so any subscriber sees it again.

    ./robotarium replay BAG [--rate R] [--loop] [--figure] [--view] [--namespace NS] [--timing T] [--into-live]
    ros2 run robotarium_recording replay BAG ...

Every recorded topic but /rosout goes out again as its recorded bytes, with the QoS its recorded
publishers offered, scaled by 1/rate: a lockstep run in experiment time, a real-time run at its
recorded times. A namespace where a live testbed answers is refused unless --into-live. --figure
draws it as its live figure was (or writes a video without a display); --view serves it to
Foxglove through the view node. What each option does: docs/user-guide.md (replay).
"""
import argparse
import os
import sys
import time

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rclpy.utilities import remove_ros_args
from std_srvs.srv import SetBool

from robotarium_core.dds_settings import init_context
from robotarium_core.topics import readers_matched
from robotarium_msgs.srv import StartExperiment
from robotarium_recording.bag import Bag
from robotarium_recording.recorder_node import message_class
from robotarium_recording.replay_display import Figure, Keyboard
from robotarium_recording.replay_timing import ReplayClock, experiment_times
from robotarium_recording.schema import message_definition
from robotarium_recording.view_node import ViewProcess, add_view_arguments

SKIPPED_TOPICS = {"/rosout"}
LIVE_CHECK = 3.0   # s to wait for a live testbed's start_experiment service before replaying
VIEW_MATCH = 15.0  # s to wait for --view's subscriptions to match the replay's publishers
SUBSCRIBER_WAIT = 60.0   # s --wait-for-subscriber waits for one, at most
VIEWER_SETTLE = 1.0   # s after a viewer's first subscription: it subscribes to its panels' channels one by one


def publisher_qos(offers):
    """The QoS to publish a recorded topic with, from its recorded offers (rosbag2's rule)."""
    reliable = all(o.get("reliability") != "best_effort" for o in offers)
    latched = bool(offers) and all(o.get("durability") == "transient_local" for o in offers)
    return QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class ReplayNode(Node):
    def __init__(self, bag, rate=1.0, loop=False, namespace=None, timing="recorded"):
        self.bag = bag
        self.namespace = (namespace or bag.namespace).rstrip("/") or "/"
        super().__init__("replay", namespace=self.namespace)
        self.loop = loop
        self.clock = ReplayClock(rate)
        self.quit = False
        self.publishers_by_topic = {}
        for topic, info in bag.topics.items():
            if topic in SKIPPED_TOPICS:
                continue
            try:
                cls = message_class(info.type)
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warning("skipping %s: message type %s is not installed" % (topic, info.type))
                continue
            self.publishers_by_topic[topic] = self.create_publisher(cls, self.rename(topic), publisher_qos(info.offered_qos))
        messages = list(bag.messages(self.publishers_by_topic))
        times = [m.log_time for m in messages]
        if timing == "experiment":
            times = experiment_times(bag, times)
        convert = self.layout_converters()
        self.messages = [(t, m.topic, convert[m.type](m) if m.type in convert else m.data, m.type)
                         for t, m in zip(times, messages)]
        self.drawing_topic = bag.topic("drawing", required=False)
        self.create_service(SetBool, "replay/pause", self.on_pause)

    def layout_converters(self):
        """{type: bytes of a recorded message in today's layout} for the types this bag recorded with
        another definition than the one installed (a message gained fields since): republishing the
        recorded bytes as they are would reach no subscriber (they fail to deserialize). Fields that are
        gone are dropped, new ones keep their defaults."""
        converters = {}
        for type_name in {self.bag.topics[t].type for t in self.publishers_by_topic}:
            recorded = self.bag.schemas.get(type_name)
            try:
                installed = message_definition(type_name)
            except (OSError, ValueError):
                continue   # no .msg text to compare with (not one of ours): trust the recording
            if recorded is None or _layout(recorded) == _layout(installed):
                continue
            cls = message_class(type_name)
            self.get_logger().warning(
                "%s was recorded with an older definition: converting it to today's (new fields keep "
                "their defaults)" % type_name)
            converters[type_name] = lambda m, cls=cls: serialize_message(to_installed(self.bag.decode(m), cls()))
        return converters

    def rename(self, topic):
        """A topic of the recorded namespace, moved to this replay's namespace."""
        old = self.bag.namespace.rstrip("/")
        if self.namespace != old and topic.startswith(old + "/"):
            return self.namespace.rstrip("/") + topic[len(old):]
        return topic

    def on_pause(self, request, response):
        now = time.monotonic()
        (self.clock.pause if request.data else self.clock.resume)(now)
        response.success = True
        response.message = "paused" if self.clock.paused else "playing"
        self.get_logger().info("replay %s" % response.message)
        return response

    def toggle_pause(self):
        now = time.monotonic()
        (self.clock.resume if self.clock.paused else self.clock.pause)(now)
        print("[replay] %s" % ("paused (space to resume)" if self.clock.paused else "playing"), file=sys.stderr)


def _layout(definition):
    """A ros2msg definition without its comments and blank lines: what decides the bytes."""
    lines = (line.split("#", 1)[0].strip() for line in definition.splitlines())
    return [" ".join(line.split()) for line in lines if line]


def to_installed(decoded, msg):
    """Copy a message decoded with a recorded definition (rosbags) into an installed rclpy message,
    field by field by name; nested messages and arrays of them recursively."""
    for name in msg.get_fields_and_field_types():
        if not hasattr(decoded, name):
            continue
        value, current = getattr(decoded, name), getattr(msg, name)
        if hasattr(current, "get_fields_and_field_types"):
            to_installed(value, current)
        elif isinstance(current, list) and value is not None and len(value) and hasattr(
                value[0], "__dataclass_fields__"):
            cls = message_class(type(value[0]).__msgtype__) if hasattr(type(value[0]), "__msgtype__") else None
            if cls is None:
                continue
            setattr(msg, name, [to_installed(v, cls()) for v in value])
        else:
            setattr(msg, name, value.tolist() if isinstance(value, np.ndarray) and isinstance(current, list)
                    else value)
    return msg


def play(node, keyboard=None, figure=None, poses_topic=None, delay=0.0):
    """Publish every message at its deadline; spin in between so the pause service answers."""
    executor = rclpy.executors.SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    start = time.monotonic()
    while time.monotonic() - start < delay:
        executor.spin_once(timeout_sec=max(0.0, min(0.05, delay - (time.monotonic() - start))))
    while not node.quit:
        if not node.messages:
            break
        node.clock.start(node.messages[0][0], time.monotonic())
        for log_ns, topic, data, type_name in node.messages:
            while True:
                key = keyboard.key() if keyboard else None
                if key in (" ", "p"):
                    node.toggle_pause()
                elif key in ("q", "\x1b"):
                    node.quit = True
                if node.quit or not rclpy.ok(context=node.context):
                    return
                remaining = float("inf") if node.clock.paused else node.clock.deadline(log_ns) - time.monotonic()
                if remaining <= 0:
                    break
                if figure is not None and remaining > 0.03 and figure.draw():
                    continue
                if remaining > 0.004:
                    executor.spin_once(timeout_sec=min(remaining - 0.003, 0.05))
                else:
                    time.sleep(remaining)   # the last few ms without the executor, for accurate timing
            node.publishers_by_topic[topic].publish(data)
            if figure is not None and topic == poses_topic:
                figure.update(data, type_name)
            elif figure is not None and topic == node.drawing_topic:
                figure.drawing(data, type_name)
        if not node.loop:
            break
    executor.spin_once(timeout_sec=0.2)
    executor.remove_node(node)


DESCRIPTION = ("Republish a recorded run: every topic, in recorded order, in experiment time for a lockstep run "
               "(as its video plays) and with the original timing for a real-time one. Keys: space/p pause and "
               "resume, q quits; service <ns>/replay/pause (std_srvs/SetBool) does the same.")


def build_parser():
    parser = argparse.ArgumentParser(prog="robotarium replay", description=DESCRIPTION)
    add_arguments(parser)
    return parser


def add_arguments(parser):
    """replay's arguments (robotarium replay, ros2 run, ros2 robotarium replay)."""
    parser.add_argument("bag", help="run folder (bags/<run_id>), its metadata.yaml or its .mcap file")
    parser.add_argument("--rate", type=float, default=1.0, help="speed factor (2 = twice as fast)")
    parser.add_argument("--loop", action="store_true", help="start again at the end, until stopped")
    parser.add_argument("--timing", choices=("experiment", "recorded"), help=(
        "experiment: step k at k time steps (the default for lockstep runs, which were recorded as fast as "
        "they ran); recorded: the recorded receive times (the default for real-time runs)"))
    parser.add_argument("--figure", action="store_true", help=(
        "draw the run as its live figure (robots, ids, what the script drew); without a display, write "
        "the replay as a video instead (--figure-file)"))
    parser.add_argument("--figure-file", help="the video written without a display (default <bag>/replay.mp4)")
    parser.add_argument("--namespace", help="republish the recorded namespace's topics under this one instead")
    parser.add_argument("--into-live", action="store_true", help=(
        "publish even where a live testbed answers (its nodes, recorder and clients would take the replay "
        "for live traffic); without it such a replay is refused"))
    parser.add_argument("--view", action="store_true", help=(
        "also serve the replay to Foxglove, as ./robotarium view does for a live testbed (--view-host, --view-port): "
        "the view subscribes to the republished topics. Without --loop the replay waits for a viewer to "
        "subscribe, then plays once and stops with the view; with --loop it plays at once, until Ctrl-C"))
    add_view_arguments(parser, prefix="view-")
    parser.add_argument("--delay", type=float, default=0.5, help=(
        "seconds to wait before the first message, so that subscribers discover the new publishers (default 0.5)"))
    parser.add_argument("--wait-for-subscriber", action="store_true", help=(
        "before the first message, wait (up to %.0f s) until something subscribes to the poses and the replay's "
        "publisher has matched it: a subscriber started with the replay then gets every message, however long "
        "discovery takes on a loaded machine (--delay only guesses)" % SUBSCRIBER_WAIT))


def live_testbed_answers(node, namespace, timeout):
    """True when a simulator offers <namespace>/start_experiment on this domain (a live testbed)."""
    client = node.create_client(StartExperiment, "%s/start_experiment" % namespace.rstrip("/"))
    try:
        return client.wait_for_service(timeout_sec=timeout)
    finally:
        node.destroy_client(client)


def wait_for_view(node, poses_topic):
    """Until the view's subscriptions matched the replay's publishers (the poses' first: the scene is
    made of them), so that the view gets the replay from its first message."""
    publishers = list(node.publishers_by_topic.values())
    first = node.publishers_by_topic.get(poses_topic)
    deadline = time.monotonic() + VIEW_MATCH
    while time.monotonic() < deadline:
        if (first is None or readers_matched(node, first, required_node="view")) and all(
                readers_matched(node, publisher) for publisher in publishers):
            return True
        time.sleep(0.05)
    print("[replay] the view has not subscribed to every topic after %.0f s; replaying anyway" % VIEW_MATCH,
          file=sys.stderr)
    return False


def wait_for_subscriber(node, poses_topic, timeout=SUBSCRIBER_WAIT):
    """Until the poses publisher has matched at least one subscriber, and every publisher every
    reader the graph shows (a reliable writer sends only to the readers it has matched: what it
    published before is lost to the others)."""
    publisher = node.publishers_by_topic.get(poses_topic)
    if publisher is None:
        return True
    print("[replay] waiting for a subscriber to %s" % publisher.topic_name, file=sys.stderr, flush=True)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if publisher.get_subscription_count() > 0 and all(
                readers_matched(node, p) for p in node.publishers_by_topic.values()):
            return True
        time.sleep(0.05)
    print("[replay] nothing subscribed to %s after %.0f s; replaying anyway" % (publisher.topic_name, timeout),
          file=sys.stderr)
    return False


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    return replay(parser.parse_args(remove_ros_args(["replay"] + argv)[1:]), parser.error, ros_args=argv)


def replay(args, error, ros_args=()):
    """Replay as `args` (add_arguments) say; error(message) reports a bad argument and exits; ros_args:
    the command line's --ros-args, if any."""
    if not args.rate > 0:
        error("--rate must be > 0")
    try:
        bag = Bag(args.bag)
    except FileNotFoundError as error:
        print("replay: %s" % error, file=sys.stderr)
        return 2
    timing = args.timing or ("experiment" if any(s.mode == "lockstep" for s in bag.statuses()[:50]) else "recorded")
    init_context(args=["replay"] + list(ros_args))
    node = keyboard = figure = view = None
    try:
        node = ReplayNode(bag, rate=args.rate, loop=args.loop, namespace=args.namespace, timing=timing)
        # Discovery takes a moment (seconds on a loaded machine): the check waits up to as long as
        # ./robotarium run does for a testbed, and that wait counts towards --delay.
        checked = time.monotonic()
        if not args.into_live and live_testbed_answers(node, node.namespace, max(LIVE_CHECK, args.delay)):
            print("replay: a live testbed answers in %s on ROS_DOMAIN_ID %s: replayed poses, commands and statuses "
                  "would mix with its own. Replay into another namespace (--namespace /replay), on another "
                  "domain, or pass --into-live if that is what you want."
                  % (node.namespace, os.environ.get("ROS_DOMAIN_ID", "0")), file=sys.stderr)
            return 2
        poses_topic = bag.topic("poses", required=False)
        if args.view:
            view = ViewProcess(node.namespace, args.view_host, args.view_port)
            if not view.wait_ready():
                print("replay: the Foxglove view could not start (its message is above)", file=sys.stderr)
                return 1
            wait_for_view(node, poses_topic)
            if not args.loop:
                # Played once, the replay would be over before anyone opened Foxglove: wait for a viewer.
                print("[replay] waiting for a viewer: in Foxglove, Open connection > Foxglove WebSocket > %s; the "
                      "replay starts when it subscribes (Ctrl-C quits; --loop plays at once, again and again)"
                      % view.url(), file=sys.stderr, flush=True)
                while not view.wait_viewer(0.5):
                    if view.failed():
                        print("replay: the Foxglove view exited (its message is above)", file=sys.stderr)
                        return 1
                time.sleep(VIEWER_SETTLE)
        if args.wait_for_subscriber:
            wait_for_subscriber(node, poses_topic)
        if args.figure and poses_topic in node.publishers_by_topic:
            figure = Figure(bag, args.figure_file or os.path.join(bag.path, "replay.mp4"))
        keyboard = Keyboard()
        span = (node.messages[-1][0] - node.messages[0][0]) * 1e-9 if node.messages else 0.0
        print("[replay] %s: %d messages on %d topics, %.1f s (%s time) at rate %g%s%s" % (
            bag.path, len(node.messages), len(node.publishers_by_topic), span, timing, args.rate,
            ", looping" if args.loop else "", "; space pauses, q quits" if keyboard.enabled else ""), file=sys.stderr)
        play(node, keyboard, figure, poses_topic, max(0.0, args.delay - (time.monotonic() - checked)))
        print("[replay] done", file=sys.stderr)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        if keyboard is not None:
            keyboard.close()
        if figure is not None:
            figure.close()
        if view is not None:
            view.stop()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
