"""The live view in Foxglove: a Foxglove WebSocket server (the foxglove-sdk package) streaming a
testbed's namespace, live or replayed.

    ./robotarium view [--host H] [--port P] [--namespace NS]      (default ws://127.0.0.1:8765)
    ./robotarium view --layout FILE [--namespace NS]              (write the Foxglove layout, exit)
    ros2 run robotarium_recording view ...

A thin shell: it forwards the testbed's messages as their CDR bytes with their ros2msg schemas,
keeps the newest poses, the trails and the drawing, and builds `<ns>/scene` and
`<ns>/scene/drawing` on a timer (plain numpy in foxglove_scene.py). It subscribes like any viewer,
so a replay (`./robotarium replay BAG --view`) streams through it too. What it serves and how to
open it: docs/ros-interface.md#a-live-view-in-foxglove.
"""
import argparse
import json
import os
import signal
import subprocess
import sys
import threading
import time

import foxglove.websocket
from foxglove.channels import GridChannel, SceneUpdateChannel
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.utilities import remove_ros_args
from std_msgs.msg import String
from visualization_msgs.msg import Marker

import foxglove
from robotarium_core import cdr, lifeline, scene
from robotarium_core.config import DEFAULT, ConfigError, TestbedConfig
from robotarium_core.dds_health import fast_dds_watchdogs
from robotarium_core.node_main import run_node
from robotarium_core.topics import (
    CMD_REQUESTED,
    CMD_SAFE,
    CONFIG,
    DEFAULT_NAMESPACE,
    DRAWING,
    LATCHED,
    OBSTACLES,
    POSES,
    SAFETY_REPORT,
    STATUS,
    namespace_from_environment,
)
from robotarium_msgs.msg import RobotPoses, SafetyReport, TestbedStatus, TwistArray
from robotarium_recording import drawing, foxglove_scene
from robotarium_recording.schema import message_definition

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
SCENE = "scene"                  # foxglove.SceneUpdate, under the namespace
SCENE_DRAWING = "scene/drawing"  # foxglove.Grid, under the namespace
LAYOUT_FILE = os.path.join("foxglove", "robotarium_layout.json")   # in the repository

# A viewer's subscription: reliable and volatile, so it matches every publisher (transient-local or
# not: a replay's, `ros2 topic pub`); late, it waits for the next message. A short queue: a viewer
# that falls behind a lockstep run drops the oldest poses, never the testbed's.
_LIVE = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
# The drawing's whole history of the run (DRAWING_QOS keeps 1000 changes), so a view started
# mid-run draws what the script drew before.
_HISTORY = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)

# The testbed's topics forwarded as they are: (topic, message class, QoS of the view's subscription).
FORWARDED = (
    (POSES, RobotPoses, _LIVE),
    (STATUS, TestbedStatus, _LIVE),
    (CMD_REQUESTED, TwistArray, _LIVE),
    (CMD_SAFE, TwistArray, _LIVE),
    (SAFETY_REPORT, SafetyReport, _LIVE),
    (DRAWING, String, _HISTORY),
    (CONFIG, String, LATCHED),
    (OBSTACLES, Marker, LATCHED),
)


def type_name(cls):
    """robotarium_msgs.msg.RobotPoses -> robotarium_msgs/msg/RobotPoses."""
    return "%s/msg/%s" % (cls.__module__.split(".")[0], cls.__name__)


def topic_in(namespace, topic):
    return "%s/%s" % (namespace.rstrip("/"), topic)


class ViewNode(Node):
    def __init__(self, namespace, server):
        super().__init__("view", namespace=namespace)
        self.server = server
        self.config = DEFAULT
        self.trails = scene.Trails(self.config.trail_length, self.config.time_step)
        self.poses = self.ids = self.run_id = None
        self.drawing = drawing.DrawingState()
        self.drawn_version = 0
        self.raster = None
        ns = self.get_namespace()
        self.hooks = {POSES: self.on_poses, DRAWING: self.on_drawing, CONFIG: self.on_config}
        for topic, cls, qos in FORWARDED:
            name = topic_in(ns, topic)
            channel = foxglove.Channel(name, message_encoding="cdr", schema=foxglove.Schema(
                name=type_name(cls), encoding="ros2msg", data=message_definition(type_name(cls)).encode()))
            self.create_subscription(cls, name, self._forward(topic, channel), qos, raw=True)
        self.scene_channel = SceneUpdateChannel(topic_in(ns, SCENE))
        self.drawing_channel = GridChannel(topic_in(ns, SCENE_DRAWING))
        self.timer = self.create_timer(1.0 / self.config.viewer_rate, self.publish_scene)

    def _forward(self, topic, channel):
        hook = self.hooks.get(topic)

        def on_message(data):
            channel.log(data)
            if hook is not None:
                hook(data)
        return on_message

    def on_poses(self, data):
        try:
            msg = cdr.ROBOT_POSES.parse(data, max_elements=self.config.max_robots)
        except cdr.CdrError:
            return   # not ours to judge: forwarded as it came, left out of the scene
        if msg.run_id != self.run_id:   # a new run: its own trails and drawing
            self.run_id = msg.run_id
            self.trails.reset()
            self.drawing = drawing.DrawingState()
        self.poses = (msg.x.copy(), msg.y.copy(), msg.theta.copy())
        self.ids = msg.ids.copy()
        self.trails.add(msg.step, self.poses)

    def on_drawing(self, data):
        try:
            self.drawing.apply(drawing.decode(deserialize_message(data, String).data))
        except (ValueError, AttributeError, TypeError) as error:
            self.get_logger().warning("a drawing message could not be read (%s); left out" % error,
                                      throttle_duration_sec=10.0)

    def on_config(self, data):
        try:
            config = TestbedConfig.from_yaml(deserialize_message(data, String).data)
        except (ConfigError, ValueError, TypeError) as error:
            self.get_logger().warning("the testbed's configuration could not be read (%s); drawing with the "
                                      "default one" % error)
            return
        if (config.trail_length, config.time_step) != (self.config.trail_length, self.config.time_step):
            self.trails = scene.Trails(config.trail_length, config.time_step)
        if config.viewer_rate != self.config.viewer_rate:
            self.timer.cancel()
            self.destroy_timer(self.timer)
            self.timer = self.create_timer(1.0 / config.viewer_rate, self.publish_scene)
        if config.arena != self.config.arena:
            self.raster = None
        self.config = config

    def publish_scene(self):
        """The scene (and the drawing, where it changed) for whoever is connected."""
        now = time.time_ns()
        if self.scene_channel.has_sinks():
            self.scene_channel.log(foxglove_scene.scene_update(
                self.config, now, self.poses, self.ids, self.trails.paths() if self.poses is not None else ()),
                log_time=now)
        if self.drawing.version != self.drawn_version and self.drawing_channel.has_sinks():
            if self.raster is None:
                self.raster = foxglove_scene.DrawingRaster(self.config.arena)
            self.drawn_version = self.drawing.version
            self.drawing_channel.log(self.raster.grid(self.drawing, now), log_time=now)


# -- the layout -------------------------------------------------------------------------------------

def layout(namespace=None):
    """The Foxglove layout of this view (as Foxglove exports one: configById + layout): a 3D panel
    on the scene and the drawing in the arena frame, seen from above; the status as raw messages;
    a plot of the status's counters."""
    ns = namespace or "/" + DEFAULT_NAMESPACE
    status = topic_in(ns, STATUS)
    three_d = {
        "cameraState": {"perspective": False, "distance": 4.0, "phi": 0.0, "thetaOffset": 0.0,
                        "target": [0, 0, 0], "targetOffset": [0, 0, 0], "targetOrientation": [0, 0, 0, 1],
                        "fovy": 45, "near": 0.01, "far": 100},
        "followMode": "follow-pose",
        "followTf": foxglove_scene.FRAME,
        "scene": {"enableStats": False},
        "transforms": {},
        "topics": {topic_in(ns, SCENE): {"visible": True},
                   topic_in(ns, SCENE_DRAWING): {"visible": True, "colorMode": "rgba-fields"},
                   topic_in(ns, OBSTACLES): {"visible": True}},
        "layers": {},
        "publish": {"type": "point"},
        "imageMode": {},
    }
    raw = {"topicPath": status, "diffEnabled": False, "diffMethod": "custom", "diffTopicPath": "",
           "showFullMessageForDiff": False}
    plot = {"paths": [{"value": "%s.%s" % (status, field), "enabled": True, "timestampMethod": "receiveTime"}
                      for field in ("step", "collisions", "boundary_violations", "safety_interventions",
                                    "command_timeouts")],
            "showLegend": True, "legendDisplay": "floating", "showXAxisLabels": True, "showYAxisLabels": True,
            "isSynced": True, "xAxisVal": "timestamp"}
    return {
        "configById": {"3D!robotarium": three_d, "RawMessages!status": raw, "Plot!status": plot},
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1},
        "layout": {"first": "3D!robotarium", "second": {"first": "RawMessages!status", "second": "Plot!status",
                                                         "direction": "column", "splitPercentage": 55},
                   "direction": "row", "splitPercentage": 65},
    }


def layout_text(namespace=None):
    return json.dumps(layout(namespace), indent=2) + "\n"


# -- the view in a process of its own (up --view, replay --view) ----------------------------------------

def add_view_arguments(parser, prefix=""):
    """--[prefix]host and --[prefix]port, for the commands that start a view (up, replay)."""
    parser.add_argument("--%shost" % prefix, default=DEFAULT_HOST,
                        help="address the Foxglove WebSocket server listens on (default %s; 0.0.0.0: every "
                             "interface, reachable from other machines)" % DEFAULT_HOST)
    parser.add_argument("--%sport" % prefix, type=int, default=DEFAULT_PORT,
                        help="its port (default %d; 0: any free one, printed)" % DEFAULT_PORT)


class ViewProcess:
    """`python -m robotarium_recording.view_node` for another command (up --view, replay --view):
    it holds that command's lifeline (it stops when the command is gone), its output goes to the
    command's stderr, and wait_ready() waits until it serves (or says why it cannot)."""

    def __init__(self, namespace, host=DEFAULT_HOST, port=DEFAULT_PORT):
        env, pass_fds = lifeline.for_child(dict(os.environ, PYTHONUNBUFFERED="1"))
        self.process = subprocess.Popen(
            [sys.executable, "-m", "robotarium_recording.view_node", "--namespace", namespace, "--host", host,
             "--port", str(port)], env=env, pass_fds=pass_fds, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        self.lines = []
        self._ready = threading.Event()
        self._viewer = threading.Event()
        threading.Thread(target=self._echo, daemon=True).start()

    def _echo(self):
        for raw in iter(self.process.stdout.readline, b""):
            line = raw.decode(errors="replace").rstrip("\n")
            self.lines.append(line)
            print(line, file=sys.stderr, flush=True)
            if READY in line:
                self._ready.set()
            if VIEWER in line:
                self._viewer.set()
        self._ready.set()   # it ended
        self._viewer.set()

    def wait_viewer(self, timeout):
        """True once a viewer subscribed; False after `timeout` s, or when the view ended first."""
        return self._viewer.wait(timeout) and self.process.poll() is None

    def url(self):
        """The ws:// address it serves (the port it chose for port 0), or ''."""
        for line in self.lines:
            if READY in line:
                return "ws://" + line.split(READY, 1)[1].split()[0]
        return ""

    def wait_ready(self, timeout=30.0):
        """True once it serves; False when it ended first or did not say so within `timeout`."""
        self._ready.wait(timeout)
        return self.process.poll() is None and any(READY in line for line in self.lines)

    def failed(self):
        return self.process.poll() is not None

    def stop(self, grace=5.0):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)   # it stops its server and its node
            try:
                self.process.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                self.process.kill()
        self.process.wait()


READY = "Foxglove WebSocket server on ws://"
VIEWER = "a viewer subscribed"   # said once per client: replay --view waits for it


class ViewerWatch(foxglove.websocket.ServerListener):
    """Says when a viewer (a Foxglove client) subscribes to its first channel: connected and watching."""

    def __init__(self):
        self.seen = set()

    def on_subscribe(self, client, channel):
        if client.id not in self.seen:
            self.seen.add(client.id)
            print("[view] %s (client %d, first to %s)" % (VIEWER, client.id, channel.topic), flush=True)


DESCRIPTION = ("Serve a testbed's namespace to Foxglove, live: the scene (arena, robots with heading and id, trails, "
               "what the script drew) in the arena frame at the testbed's viewer_rate, and the poses, status, commands "
               "and safety reports as they are published. In Foxglove: Open connection > Foxglove WebSocket > "
               "ws://HOST:PORT, then import the layout %s (see --layout). Runs until Ctrl-C." % LAYOUT_FILE)


def build_parser():
    parser = argparse.ArgumentParser(prog="robotarium view", description=DESCRIPTION)
    add_arguments(parser)
    return parser


def add_arguments(parser):
    """view's arguments (robotarium view, ros2 run, ros2 robotarium view)."""
    add_view_arguments(parser)
    parser.add_argument("--namespace", default=None,
                        help="the testbed's namespace (default: $ROBOTARIUM_NAMESPACE, else /%s)" % DEFAULT_NAMESPACE)
    parser.add_argument("--layout", metavar="FILE", help=(
        "write the Foxglove layout of this view (for --namespace) to FILE and exit; the one for /%s is "
        "committed as %s" % (DEFAULT_NAMESPACE, LAYOUT_FILE)))


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    return view(parser.parse_args(remove_ros_args(["view"] + argv)[1:]), parser.error, ros_args=argv)


def view(args, error, ros_args=()):
    """Serve the view as `args` (add_arguments) say; error(message) reports a bad argument and exits;
    ros_args: the command line's --ros-args, if any."""
    namespace = "/" + (args.namespace or namespace_from_environment()).strip("/")
    if args.layout:
        with open(args.layout, "w") as f:
            f.write(layout_text(namespace))
        print("[view] wrote the Foxglove layout for %s to %s" % (namespace, args.layout), file=sys.stderr)
        return 0
    if not 0 <= args.port < 65536:
        error("--port must be between 0 and 65535; received %d" % args.port)
    try:
        server = foxglove.start_server(name="robotarium %s" % namespace, host=args.host, port=args.port,
                                       server_listener=ViewerWatch())
    except RuntimeError as problem:
        print("view: cannot serve on %s port %d: %s. Is another view running there (./robotarium view, up --view, "
              "replay --view)? Stop it, or choose another port (--port N, or --view-port N; 0 picks a free one)."
              % (args.host, args.port, problem), file=sys.stderr)
        return 1

    def make_node():
        node = ViewNode(namespace, server)
        print("[view] %s%s:%d serves %s (on ROS_DOMAIN_ID %s). In Foxglove: Open connection > Foxglove "
              "WebSocket, and import the layout %s. Ctrl-C stops." % (
                  READY, args.host, server.port, namespace, os.environ.get("ROS_DOMAIN_ID", "0"), LAYOUT_FILE),
              flush=True)
        return node

    return run_node(make_node, "view", ["view"] + list(ros_args), before_destroy=lambda node: server.stop(),
                    watchdogs=fast_dds_watchdogs())


if __name__ == "__main__":
    sys.exit(main())
