"""Topic names and the QoS of the testbed's topics (shared by the nodes and the client).

Streams (poses, commands, safety reports, sensors, the status stream) are reliable and volatile
(`OUTPUT_QOS`, `TESTBED_QOS`): a late joiner never gets a sample of an earlier run, and a writer
sends a run's first sample only once the readers that need all of it matched (`readers_matched`,
`listeners`). The status is a state (`STATUS_QOS`, depth 1) with a hidden stream beside it for the
recorder; the drawing is kept for its run by the client's writer (`DRAWING_QOS`). The command
inputs (`command_input_qos`) are volatile, so any reliable publisher drives the testbed.
Why each choice: docs/ros-interface.md#topics.
"""
import os

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from robotarium_core.config import DEFAULT

DEFAULT_NAMESPACE = "robotarium"


def namespace_from_environment():
    """The testbed's namespace for a client or a command: ROBOTARIUM_NAMESPACE with one leading slash,
    /robotarium by default (nodes take theirs from ROS: `__ns`)."""
    return "/" + os.environ.get("ROBOTARIUM_NAMESPACE", DEFAULT_NAMESPACE).strip("/")

# What a reader of the testbed's streams asks for: reliable, volatile (nothing from before it joined),
# a queue of 50 samples.
TESTBED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
# What the streams' writers (the testbed's and the client's) offer: the same, with a history a matched
# reader may trail by.
OUTPUT_HISTORY = 1000   # samples: 5 s of a lockstep run at 200 steps/s, 33 s in real time
OUTPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=OUTPUT_HISTORY,
                        reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
# How long a writer waits for the readers that need a run's first sample (`listeners`) before it
# publishes anyway (and says whose reader was missing): matching takes milliseconds on a quiet
# machine, a recorder subscribes to a new topic within its discovery period (0.5 s).
LISTENERS_WAIT = 5.0



def command_input_qos(depth):
    """The testbed's command inputs (cmd_requested at the safety node, cmd_safe at the simulator)
    read serialized arrays and drop foreign ones in microseconds (robotarium_core.cdr), so their
    queue only has to outlast a moment's stall of the node: `depth` is the configuration's
    command_queue_depth (1000: a second of a 1 kHz flood before a client's array could be pushed
    out). Keep-last, so a flood never grows it. Volatile: any reliable publisher matches (ros2
    topic pub's default, rclpy's, rclcpp's)."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


COMMAND_INPUT_QOS = command_input_qos(DEFAULT.command_queue_depth)
# One SafetyReport per array the safety node sends, each counted by the simulator (the report's
# interventions and what the safety layer prevented): a lost packet holds back every later report
# until it is repaired, and with a history of 50 (0.4 s of a lockstep run) the simulator counted 172
# of 243 interventions while another process flooded the machine's loopback. The outputs' depth, for
# the simulator's reader too.
SAFETY_REPORT_QOS = OUTPUT_QOS
# What the script drew on r.axes, change by change (robotarium_recording.drawing), kept for the run by
# the client's writer: a viewer or recorder matching late still gets the whole figure.
DRAWING_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=OUTPUT_HISTORY,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# pose_array for viewers: a stream like the others.
POSE_ARRAY_QOS = OUTPUT_QOS

# A topic that keeps only its last message for late subscribers (announcements, the run's configuration).
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# The testbed's state (status): a late joiner gets only the newest; every status also goes on the stream.
STATUS_QOS = LATCHED
STATUS_STREAM_QOS = OUTPUT_QOS
# The recent runs' folders (recorder -> ./robotarium run): `recording` keeps only the newest, which is ""
# once a run closed, so a command that asks late still finds the folder of a run it knows the id of.
RECORDED_RUNS_QOS = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE,
                               durability=DurabilityPolicy.TRANSIENT_LOCAL)

# What viewers get (RViz, Foxglove): reliable + volatile, the ROS default.
VIEWER_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)

CMD_REQUESTED = "cmd_requested"   # TwistArray: client -> safety node
CMD_SAFE = "cmd_safe"             # TwistArray: safety node -> simulator
POSES = "poses"                   # RobotPoses: simulator -> everyone
POSE_ARRAY = "pose_array"         # geometry_msgs/PoseArray for viewers
MARKERS = "markers"               # visualization_msgs/MarkerArray for viewers: arena, robots, trails
STATUS = "status"                 # TestbedStatus, latched (STATUS_QOS): the testbed's state now
STATUS_STREAM = "_status/stream"  # TestbedStatus: every status (STATUS_STREAM_QOS), hidden; recorded as <ns>/status
SAFETY_REPORT = "safety_report"   # SafetyReport
RECORDING = "recording"           # std_msgs/String: recorder -> simulator, where the run is recorded
RECORDED_RUNS = "_recording/runs"   # std_msgs/String (JSON: run_id, path), RECORDED_RUNS_QOS, hidden: each run's
                                    # folder as its recording opened
RECORDING_ERROR = "recording_error"   # std_msgs/String (JSON, latched): recorder -> clients, a run whose recording
                                      # stopped: {"run_id", "path", "why", "write_errors"}
CONFIG = "config"                 # std_msgs/String, latched: the running experiment's TestbedConfig as YAML
SAFETY_ARM = "safety/arm"         # ArmSafety: simulator -> safety node, the experiment to guard and its secrets
DRAWING = "drawing"               # std_msgs/String, JSON: client -> recorder, what the script drew on r.axes
EXPERIMENT = "experiment"         # std_msgs/String, latched: the running experiment's settings as YAML (api, obstacles, ...)
OBSTACLES = "obstacles"           # visualization_msgs/Marker, latched: the experiment's obstacles (LINE_LIST) for viewers
SENSORS = "sensors"               # SensorReadings: simulator -> client, every step of a 2.x experiment
START_EXPERIMENT = "start_experiment"
END_EXPERIMENT = "end_experiment"


def offer_meets_request(offered, requested):
    """DDS's request/offer rule for the two policies the testbed uses: a reliable reader needs a
    reliable writer, a transient-local reader a transient-local writer. (rclpy's qos_check_compatible
    reads a graph profile's infinite deadline and lease as set, so it cannot judge graph entries.)"""
    return not ((requested.reliability == ReliabilityPolicy.RELIABLE and offered.reliability != ReliabilityPolicy.RELIABLE)
                or (requested.durability == DurabilityPolicy.TRANSIENT_LOCAL
                    and offered.durability != DurabilityPolicy.TRANSIENT_LOCAL))


def readers_matched(node, publisher, required_node=None):
    """True when `publisher` has matched every reader of its topic that the graph shows and that
    can match it (same type, compatible QoS), and, if `required_node` is given, the graph shows a
    reader of that node (a name in the topic's namespace: "safety" for /robotarium/cmd_requested,
    "recorder" for /robotarium/_status/stream; or a fully qualified one: "/robotarium/safety").

    The graph learns of a reader in the same discovery step in which our writer matches it, so
    "matched at least as many as the graph shows" means that each of them, the required one
    included, is matched: whatever we publish from now on reaches it (reliable)."""
    return not _unmatched(node, publisher, [required_node])


def _unmatched(node, publisher, required_nodes):
    """Of `required_nodes` (names as readers_matched takes them, None for "every reader the graph
    shows"), those whose reader `publisher` has not matched yet; one look at the graph for all."""
    topic = publisher.topic_name
    readers = node.get_subscriptions_info_by_topic(topic)
    our_type = "%s/msg/%s" % (publisher.msg_type.__module__.split(".")[0], publisher.msg_type.__name__)
    can_match = [r for r in readers if r.topic_type == our_type and offer_meets_request(publisher.qos_profile, r.qos_profile)]

    def shown(required):
        return any("%s/%s" % (r.node_namespace.rstrip("/"), r.node_name) == required if required.startswith("/")
                   # a node of the namespace the topic is in, or one above it (/robotarium/_status/stream)
                   else r.node_name == required and topic.startswith(r.node_namespace.rstrip("/") + "/")
                   for r in can_match)
    all_matched = publisher.get_subscription_count() >= len(can_match)
    return [who for who in required_nodes if not all_matched or (who is not None and not shown(who))]


def node_names(node):
    """The names of the nodes the graph shows in `node`'s namespace."""
    ns = node.get_namespace()
    return {name for name, namespace in node.get_node_names_and_namespaces() if namespace == ns}


def listeners(node, publishers_and_readers):
    """The (publisher, node name) pairs whose reader the publisher has not matched yet, of
    `publishers_and_readers`: (publisher, node name or None) pairs, None for "every reader the graph
    shows". A writer of a stream publishes a run's first sample once this is empty (above). The graph
    is looked at once per publisher (a 2.x start of 50 robots waits on some 150 writers)."""
    by_publisher = {}
    for publisher, who in publishers_and_readers:
        by_publisher.setdefault(publisher, []).append(who)
    return [(publisher, who) for publisher, wanted in by_publisher.items()
            for who in _unmatched(node, publisher, wanted)]


def warn_on_incompatible_qos(node, topic):
    """Subscription event callbacks that say, once, what to do when a publisher cannot match."""
    warned = []

    def on_incompatible(info):
        if not warned:
            warned.append(True)
            node.get_logger().warning(
                "a publisher on %s offers a QoS this testbed cannot accept (last policy: %s); publish "
                "reliable (the ROS default; ros2 topic pub does)" % (topic, info.last_policy_kind))
    return SubscriptionEventCallbacks(incompatible_qos=on_incompatible)
