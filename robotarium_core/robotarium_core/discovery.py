"""Waiting on what DDS discovery tells a participant, in steps of 10 ms: a service becoming ready
(rclpy's own wait sleeps 0.25 s between looks), and discovery settling before a participant is
destroyed (Fast DDS can hang destroying one while a discovery callback runs).
"""
import time

SERVICE_POLL = 0.01   # s between looks at the DDS graph while waiting for a service


def wait_for_service(client, timeout, stop=None):
    """Client.wait_for_service without its 0.25 s steps (rclpy sleeps that long between looks at
    the graph): True as soon as the service is there, False after `timeout` seconds, or as soon as
    stop() is true (a Ctrl-C while a command waits)."""
    deadline = time.monotonic() + timeout
    while client.context.ok():
        if client.service_is_ready():
            return True
        if time.monotonic() >= deadline or (stop is not None and stop()):
            return False
        time.sleep(SERVICE_POLL)
    return False


# Discovery counts as settled after this long without news (s), waited for at most QUIET_DISCOVERY_WAIT.
QUIET_DISCOVERY = 0.1
QUIET_DISCOVERY_WAIT = 1.0


def discovery_graph(node):
    """What discovery has told `node`'s participant: nodes, and each topic's publisher and subscriber
    counts."""
    return (tuple(sorted(node.get_node_names_and_namespaces())),
            tuple((name, node.count_publishers(name), node.count_subscribers(name))
                  for name, _ in sorted(node.get_topic_names_and_types())))


def wait_for_quiet_discovery(node, still=QUIET_DISCOVERY, timeout=QUIET_DISCOVERY_WAIT):
    """Wait (at most `timeout`) until discovery has told `node` nothing new for `still` seconds. Before
    a participant is destroyed: Fast DDS can hang for good destroying one while one of its discovery
    callbacks runs (DomainParticipant::set_listener spins holding the lock the callback needs to
    end), and an experiment's end makes the simulator drop that run's endpoints just then (a test
    worker hung in destroy_node that way)."""
    last, since, end = discovery_graph(node), time.monotonic(), time.monotonic() + timeout
    while time.monotonic() - since < still and time.monotonic() < end:
        time.sleep(0.01)
        now = discovery_graph(node)
        if now != last:
            last, since = now, time.monotonic()
