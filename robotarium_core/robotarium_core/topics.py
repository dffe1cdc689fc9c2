"""Topic names and the QoS every testbed topic uses (shared by the nodes and the client).

DDS discovery is asymmetric: a reader may know a writer well before the writer knows the
reader, and a reliable writer delivers nothing to readers it does not know yet. With slow
discovery (a loaded 2-core machine takes seconds) the first commands of a run would be lost.
So every testbed topic is reliable and transient-local with a history of 50: a writer keeps its
last 50 samples and hands them to a reader as soon as it matches. Nothing a client sends before
the safety node or the simulator matched it is lost, and a late viewer or recorder still gets
the current poses. Subscribers ask for the same QoS to receive that history.

Publishers to the testbed must offer this durability too: a transient-local reader does not
match a volatile writer (DDS's request/offer rule). A plain rclpy script publishes with
`TESTBED_QOS`; the nodes log a warning naming the topic when an incompatible publisher appears
(`warn_on_incompatible_qos`).
"""
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

DEFAULT_NAMESPACE = "robotarium"

TESTBED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)

# The testbed's command inputs (cmd_requested at the safety node, cmd_safe at the simulator) read
# serialized arrays and drop foreign ones in microseconds (robotarium_core.cdr), so their queue
# only has to outlast a moment's stall of the node: 1000 arrays are one second of a 1 kHz flood
# before a client's array could be pushed out.
COMMAND_INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                               durability=DurabilityPolicy.TRANSIENT_LOCAL)

# A topic that keeps only its last message for late subscribers (announcements, the run's configuration).
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)

CMD_REQUESTED = "cmd_requested"   # TwistArray: client -> safety node
CMD_SAFE = "cmd_safe"             # TwistArray: safety node -> simulator
POSES = "poses"                   # RobotPoses: simulator -> everyone
POSE_ARRAY = "pose_array"         # geometry_msgs/PoseArray for viewers
STATUS = "status"                 # TestbedStatus
SAFETY_REPORT = "safety_report"   # SafetyReport
RECORDING = "recording"           # std_msgs/String: recorder -> simulator, where the run is recorded
CONFIG = "config"                 # std_msgs/String, latched: the running experiment's TestbedConfig as YAML
SAFETY_ARM = "safety/arm"        # ArmSafety: simulator -> safety node, the experiment to guard and its secrets
START_EXPERIMENT = "start_experiment"
END_EXPERIMENT = "end_experiment"


def warn_on_incompatible_qos(node, topic):
    """Subscription event callbacks that say, once, what to do when a publisher cannot match."""
    warned = []

    def on_incompatible(info):
        if not warned:
            warned.append(True)
            node.get_logger().warning(
                "a publisher on %s offers a QoS this testbed cannot accept (last policy: %s); publish "
                "reliable + transient-local, e.g. robotarium_core.topics.TESTBED_QOS" % (topic, info.last_policy_kind))
    return SubscriptionEventCallbacks(incompatible_qos=on_incompatible)
