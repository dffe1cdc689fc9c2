"""Noticing within a bound that a process is gone: DDS liveliness on a hidden topic.

Each testbed node (and each client, for its experiment) holds a `Presence`: a publisher that never
publishes, on `<ns>/_alive/<who>`, with AUTOMATIC liveliness, which Fast DDS asserts from its own
threads however busy the process's Python is. A `Watch` on that topic requests a lease of `lease`
seconds and calls `on_lost` once no writer has been alive for that long (or one left cleanly):
0.6-0.75 s after a kill -9 with the nodes' 0.75 s lease. The topics are hidden, so the recorder
does not keep them and a replay never fakes a presence. The request/offer rule, the measurements:
docs/faults.md#how-a-node-winds-down.
"""
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import LivelinessPolicy, QoSProfile
from std_msgs.msg import Empty

SIMULATOR, SAFETY, RECORDER = "simulator", "safety", "recorder"


def alive_topic(who):
    """The presence topic of `who` (relative to the node's namespace)."""
    return "_alive/" + who


def _qos(lease):
    return QoSProfile(depth=1, liveliness=LivelinessPolicy.AUTOMATIC,
                      liveliness_lease_duration=Duration(nanoseconds=int(lease * 1e9)))


class Presence:
    """This process is there for as long as it holds this: a writer on `topic` (alive_topic(who),
    or a client's own topic) of any rclpy node of it, offering a third of `lease`."""

    def __init__(self, node, topic, lease):
        self.node = node
        self.publisher = node.create_publisher(Empty, topic, _qos(lease / 3),
                                               event_callbacks=PublisherEventCallbacks())

    def announce(self):
        """Say at once that this process is there: a sample asserts a writer's liveliness now, where
        the automatic assertions come only every 2/3 of the lease (a process that dies before the
        first one would otherwise never have been seen, and a Watch could not tell it is gone)."""
        self.publisher.publish(Empty())

    def destroy(self):
        self.node.destroy_publisher(self.publisher)


class Watch:
    """Tells when `who` is gone: `on_lost()` when, after a writer was alive, none has been alive for
    `lease` seconds; `on_seen()` whenever a writer becomes alive: the first, one back, or a new one beside
    an old one not yet known to be gone (a restarted node's, which can come before the old process's lease
    ran out on a loaded machine). `seen`, `alive` and `lost` say where it stands."""

    def __init__(self, node, topic, lease, on_lost=None, on_seen=None):
        self.node = node
        self.on_lost = on_lost
        self.on_seen = on_seen
        self.seen = False
        self.alive = False
        self.lost = False
        self.subscription = node.create_subscription(
            Empty, topic, lambda msg: None, _qos(lease),
            event_callbacks=SubscriptionEventCallbacks(liveliness=self._changed))

    def _changed(self, info):
        alive, was = info.alive_count > 0, self.alive
        self.alive = alive
        if alive and not was:
            self.seen, self.lost = True, False
        elif was and not alive:
            self.lost = True
            if self.on_lost is not None:
                self.on_lost()
        if info.alive_count_change > 0 and self.on_seen is not None:
            self.on_seen()

    def destroy(self):
        self.node.destroy_subscription(self.subscription)
