"""A simulator and a recorder on a private domain, driven by a probe that plays the experiment's
client and the safety node (Stack), and reading a bag back with rosbags alone: what the recorder
and sensor tests share."""
import os

import yaml
from geometry_msgs.msg import Twist
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from std_msgs.msg import String

from devtools.rosutil import NodeProcess, RosProbe, SafetyStandIn, unique_domain_id
from robotarium_core.topics import LATCHED
from robotarium_msgs.msg import RobotPoses, TwistArray
from robotarium_msgs.srv import EndExperiment, StartExperiment

NS = "/robotarium"


class Stack:
    """Simulator + recorder on a private domain, and a probe that drives them (as the experiment's
    client and in the safety node's place: it publishes on cmd_safe with the safety key)."""

    def __init__(self, tmp_path, recorder=True, config_file=None):
        self.domain = unique_domain_id()
        self.tmp_path = tmp_path
        self.bags_dir = tmp_path / "bags"
        self.sim = NodeProcess("robotarium_sim.simulator_node", self.domain, log_path=tmp_path / "simulator.log",
                               ros_args=["--params-file", str(config_file)] if config_file else ())
        self.recorder = None
        self.probe = RosProbe(self.domain)
        self.poses = self.probe.collect(RobotPoses, NS + "/poses")
        self.recording = self.probe.collect(String, NS + "/recording", LATCHED)
        self.safety = SafetyStandIn(self.probe)
        self.cmd = self.safety.publisher
        assert self.probe.spin_until(lambda: self.cmd.get_subscription_count() >= 1, 30), self.sim.output()
        if recorder:
            self.start_recorder()

    def start_recorder(self):
        self.recorder = NodeProcess("robotarium_recording.recorder_node", self.domain, log_path=self.tmp_path / "recorder.log",
                                    ros_args=["-p", "bags_dir:=%s" % self.bags_dir])
        node = self.probe.node
        ready = lambda: (self.cmd.get_subscription_count() >= 2 and node.count_subscribers(NS + "/pose_array") >= 1  # noqa: E731
                         and node.count_subscribers(NS + "/_status/stream") >= 1)
        assert self.probe.spin_until(ready, 30), "recorder did not come up:\n%s" % self.recorder.output()
        self.probe.spin_for(0.5)   # let the simulator see the recorder's pose_array subscription too

    def start(self, n, poses=None, real_time=False, name="test", seed=1):
        request = StartExperiment.Request(name=name, number_of_robots=n, real_time=real_time, seed=seed)
        if poses is not None:
            request.x, request.y, request.theta = (list(map(float, row)) for row in poses)
        response = self.probe.start_experiment(request, NS)
        assert response.success, response.message
        self.run_id = response.run_id
        self.token = response.token
        assert self.probe.spin_until(lambda: any(p.step == 0 for p in self.poses), 10)
        return response

    def step(self, k, v, w):
        """One lockstep step: publish commands for every robot, wait for the poses of step k."""
        self.command(k, v, w)
        assert self.probe.spin_until(lambda: self.poses and self.poses[-1].step >= k, 10), "lockstep stalled at %d" % k

    def command(self, k, v, w):
        """Publish commands for every robot with step number k (0: unnumbered, real time)."""
        msg = TwistArray(step=k, ids=list(range(len(v))))
        msg.header.stamp = self.probe.node.get_clock().now().to_msg()
        msg.header.frame_id = "arena"
        for vi, wi in zip(v, w):
            t = Twist()
            t.linear.x, t.angular.z = float(vi), float(wi)
            msg.twists.append(t)
        self.safety.publish(msg)

    def end(self):
        if self.recorder is not None and self.recorder.alive():
            # The recorder announces the bag when the run starts; give the simulator time to hear
            # it (a lockstep run of a few steps is over in milliseconds).
            announced = lambda: self.recording and self.recording[-1].data.endswith(self.run_id)  # noqa: E731
            assert self.probe.spin_until(announced, 10), self.recorder.output()
            self.probe.spin_for(0.2)
        response = self.probe.call(EndExperiment, NS + "/end_experiment", EndExperiment.Request(token=self.token))
        assert response.success, response.message
        return response

    def wait_closed(self, path, timeout=15):
        """Until the recorder has finished the bag (final metadata.yaml says complete)."""
        def closed():
            try:
                with open(os.path.join(path, "metadata.yaml")) as f:
                    return yaml.safe_load(f)["rosbag2_bagfile_information"]["custom_data"]["complete"] == "true"
            except (OSError, KeyError, TypeError):
                return False
        assert self.probe.spin_until(closed, timeout), self.recorder.output()

    def close(self):
        self.probe.close()
        if self.recorder is not None:
            self.recorder.close()
        self.sim.close()


def rosbags_messages(path):
    """{topic: [decoded messages]} read with rosbags alone (types from the bag's own definitions)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    out = {}
    with Reader(path) as reader:
        for conn in reader.connections:
            if conn.msgtype not in store.fielddefs or conn.msgtype.startswith("robotarium_msgs/"):
                store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        for conn, _, raw in reader.messages():
            out.setdefault(conn.topic, []).append(store.deserialize_cdr(raw, conn.msgtype))
        counts = {c.topic: c.msgcount for c in reader.connections}
        total = reader.message_count
    return out, counts, total
