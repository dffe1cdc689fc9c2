"""Replay a recorded run: republish its topics with the original timing, so any subscriber sees it again.

    ./robotarium replay BAG [--rate R] [--loop] [--figure] [--namespace NS]
    ros2 run robotarium_recording replay BAG ...

Every recorded topic except /rosout (the log lines stay in the bag: republishing them would mix
them with live logs) is published again, serialized bytes as recorded, at the recorded receive
times scaled by 1/rate. QoS follows what the recorded publishers offered (reliable unless one of
them was best effort; transient local only if all of them were). Pause and resume: the space bar
(or p) when started from a terminal, q quits; or the service <ns>/replay/pause
(std_srvs/SetBool: true pauses, false resumes). --figure draws the poses in the arena
(robots to scale, with headings); with no display (Agg) the last frame is saved to
--figure-file (default <bag>/replay.png).
"""
import argparse
import os
import select
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args
from std_srvs.srv import SetBool

from robotarium_recording.bag import Bag
from robotarium_recording.recorder_node import message_class

SKIPPED_TOPICS = {"/rosout"}
FIGURE_HZ = 15


class ReplayClock:
    """Maps recorded times (ns) to wall-clock deadlines (time.monotonic), with pause and rate."""

    def __init__(self, rate=1.0):
        if not rate > 0:
            raise ValueError("rate must be > 0; received %r" % rate)
        self.rate = rate
        self.origin = None
        self.first_ns = 0
        self.paused_at = None

    def start(self, first_ns, now):
        self.first_ns, self.origin = first_ns, now
        if self.paused_at is not None:
            self.paused_at = now

    def deadline(self, log_ns):
        return self.origin + (log_ns - self.first_ns) * 1e-9 / self.rate

    @property
    def paused(self):
        return self.paused_at is not None

    def pause(self, now):
        if self.paused_at is None:
            self.paused_at = now

    def resume(self, now):
        if self.paused_at is not None:
            self.origin += now - self.paused_at   # the paused time does not count
            self.paused_at = None


def publisher_qos(offers):
    """The QoS to publish a recorded topic with, from its recorded offers (rosbag2's rule)."""
    reliable = all(o.get("reliability") != "best_effort" for o in offers)
    latched = bool(offers) and all(o.get("durability") == "transient_local" for o in offers)
    return QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class ReplayNode(Node):
    def __init__(self, bag, rate=1.0, loop=False, namespace=None):
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
        self.messages = [(m.log_time, m.topic, m.data, m.type) for m in bag.messages(self.publishers_by_topic)]
        self.create_service(SetBool, "replay/pause", self.on_pause)

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


class Keyboard:
    """Single keys from a terminal without Enter (no-op when stdin is not a terminal)."""

    def __init__(self):
        self.enabled = sys.stdin.isatty()
        self.saved = None
        if self.enabled:
            import termios
            import tty
            self.saved = termios.tcgetattr(sys.stdin)
            tty.setcbreak(sys.stdin.fileno())

    def key(self):
        if self.enabled and select.select([sys.stdin], [], [], 0)[0]:
            return sys.stdin.read(1)
        return None

    def close(self):
        if self.saved is not None:
            import termios
            termios.tcsetattr(sys.stdin, termios.TCSADRAIN, self.saved)


class Figure:
    """The arena with the replayed poses. update() only moves the artists (cheap); draw() renders,
    and play() calls it only when the next message is far enough away not to be delayed."""

    def __init__(self, bag, path):
        import matplotlib
        if not os.environ.get("DISPLAY") and not os.environ.get("MPLBACKEND"):
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        self.plt, self.bag, self.path = plt, bag, path
        self.interactive = matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "ps", "cairo", "template")
        self.view = None
        self.dirty = False
        self.last_draw = 0.0
        if self.interactive:
            plt.ion()

    def update(self, data, type_name):
        msg = self.bag.typestore.deserialize_cdr(data, type_name)
        if self.view is None:
            from robotarium_recording.results import ArenaView
            self.view = ArenaView(len(msg.x), "replay of %s" % self.bag.name, plt=self.plt)
            if self.interactive:
                self.view.fig.show()
        self.view.update(msg.x, msg.y, msg.theta, "t = %6.2f s  step %d" % (msg.sim_time, msg.step))
        self.dirty = True

    def draw(self):
        """Render on screen, at most FIGURE_HZ times a second (headless: only at the end)."""
        if not (self.dirty and self.interactive) or time.monotonic() - self.last_draw < 1.0 / FIGURE_HZ:
            return False
        self.view.fig.canvas.draw_idle()
        self.view.fig.canvas.flush_events()
        self.last_draw, self.dirty = time.monotonic(), False
        return True

    def close(self):
        if self.view is not None and not self.interactive:
            self.view.fig.savefig(self.path)
            print("[replay] last frame saved to %s" % self.path, file=sys.stderr)


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
        if not node.loop:
            break
    executor.spin_once(timeout_sec=0.2)
    executor.remove_node(node)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(prog="robotarium replay", description=(
        "Republish a recorded run with its original timing. Keys: space/p pause and resume, q quits; "
        "service <ns>/replay/pause (std_srvs/SetBool) does the same."))
    parser.add_argument("bag", help="run folder (bags/<run_id>), its metadata.yaml or its .mcap file")
    parser.add_argument("--rate", type=float, default=1.0, help="speed factor (2 = twice as fast)")
    parser.add_argument("--loop", action="store_true", help="start again at the end, until stopped")
    parser.add_argument("--figure", action="store_true", help="draw the poses in the arena")
    parser.add_argument("--figure-file", help="where the last frame goes without a display (default <bag>/replay.png)")
    parser.add_argument("--namespace", help="republish the recorded namespace's topics under this one instead")
    parser.add_argument("--delay", type=float, default=0.5, help=(
        "seconds to wait before the first message, so that subscribers discover the new publishers (default 0.5)"))
    args = parser.parse_args(remove_ros_args(["replay"] + argv)[1:])
    if not args.rate > 0:
        parser.error("--rate must be > 0")
    try:
        bag = Bag(args.bag)
    except FileNotFoundError as error:
        print("replay: %s" % error, file=sys.stderr)
        return 2
    rclpy.init(args=["replay"] + argv)
    node = keyboard = figure = None
    try:
        node = ReplayNode(bag, rate=args.rate, loop=args.loop, namespace=args.namespace)
        poses_topic = bag.topic("poses", required=False)
        if args.figure and poses_topic in node.publishers_by_topic:
            figure = Figure(bag, args.figure_file or os.path.join(bag.path, "replay.png"))
        keyboard = Keyboard()
        print("[replay] %s: %d messages on %d topics, %.1f s at rate %g%s%s" % (
            bag.path, len(node.messages), len(node.publishers_by_topic), bag.duration_ns * 1e-9, args.rate,
            ", looping" if args.loop else "", "; space pauses, q quits" if keyboard.enabled else ""), file=sys.stderr)
        play(node, keyboard, figure, poses_topic, max(0.0, args.delay))
        print("[replay] done", file=sys.stderr)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        if keyboard is not None:
            keyboard.close()
        if figure is not None:
            figure.close()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
