"""Topic names and the QoS every testbed topic uses (shared by the nodes and the client).

DDS discovery is asymmetric: a reader may know a writer well before the writer knows the
reader, and a reliable writer delivers nothing to readers it does not know yet. With slow
discovery (a loaded 2-core machine takes seconds) the first commands of a run would be lost.
So every testbed topic is reliable and transient-local with a history of 50: a writer keeps its
last 50 samples and hands them to a reader as soon as it matches. Nothing a client sends before
the safety node or the simulator matched it is lost, and a late viewer or recorder still gets
the current poses. Subscribers ask for the same QoS to receive that history.

The two command inputs (the safety node's cmd_requested, the simulator's cmd_safe) subscribe
with COMMAND_QOS instead: reliable but volatile, so that any publisher matches them, a plain
`rclpy` script or `ros2 topic pub` with default QoS included (a transient-local reader would
refuse volatile writers). The senders on our side wait until their writer has matched a reader
before they send.
"""
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

DEFAULT_NAMESPACE = "robotarium"

TESTBED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)

COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)

CMD_REQUESTED = "cmd_requested"   # TwistArray: client -> safety node
CMD_SAFE = "cmd_safe"             # TwistArray: safety node -> simulator
POSES = "poses"                   # RobotPoses: simulator -> everyone
POSE_ARRAY = "pose_array"         # geometry_msgs/PoseArray for viewers
STATUS = "status"                 # TestbedStatus
SAFETY_REPORT = "safety_report"   # SafetyReport
RECORDING = "recording"           # std_msgs/String: recorder -> simulator, where the run is recorded
START_EXPERIMENT = "start_experiment"
END_EXPERIMENT = "end_experiment"
