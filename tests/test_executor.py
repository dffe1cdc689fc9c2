"""robotarium_core.executor.LeanExecutor serves what rclpy's executors serve, the way they do:
messages (typed and raw), timers, a coroutine service that awaits, guard conditions woken from
another thread, liveliness events, entities made and destroyed in callbacks, and exceptions."""
import os
import threading
import time

import pytest
import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.context import Context
from rclpy.node import Node
from rclpy.task import Future
from std_msgs.msg import Float64, String
from std_srvs.srv import Trigger

from devtools.rosutil import unique_domain_id
from robotarium_core import cdr, presence
from robotarium_core.dds_settings import init_context
from robotarium_core.executor import LeanExecutor
from robotarium_core.topics import TESTBED_QOS


@pytest.fixture
def node():
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    context = Context()
    init_context(context=context, domain_id=unique_domain_id(), node=False)
    node = Node("lean", context=context)
    executor = LeanExecutor(context=context)
    executor.add_node(node)
    node.spin_until = lambda predicate, timeout=10.0: spin_until(executor, predicate, timeout)
    node.lean = executor
    try:
        yield node
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def spin_until(executor, predicate, timeout):
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        executor.spin_once(timeout_sec=0.1)
    return True


def test_messages_typed_and_raw_and_timers(node):
    typed, raw, ticks = [], [], []
    node.create_subscription(String, "chatter", typed.append, TESTBED_QOS)
    node.create_subscription(String, "chatter", raw.append, TESTBED_QOS, raw=True)
    node.create_timer(0.01, lambda: ticks.append(time.monotonic()))
    publisher = node.create_publisher(String, "chatter", TESTBED_QOS)
    for k in range(5):
        publisher.publish(String(data="hello %d" % k))
    assert node.spin_until(lambda: len(typed) == 5 and len(raw) == 5 and len(ticks) >= 10)
    assert [m.data for m in typed] == ["hello %d" % k for k in range(5)]
    assert all(isinstance(b, bytes) and b"hello" in b for b in raw)
    assert 0.005 < (ticks[-1] - ticks[0]) / (len(ticks) - 1) < 0.05


def test_a_coroutine_service_awaits_while_other_callbacks_run(node):
    """As the simulator's start: the service's answer waits for something only other callbacks
    (a timer here) provide; its own group takes no second request meanwhile."""
    ticks = []
    node.create_timer(0.01, lambda: ticks.append(1))

    async def slow(request, response):
        done = Future()
        timer = node.create_timer(0.2, lambda: done.done() or done.set_result(None))
        await done
        node.destroy_timer(timer)
        response.success, response.message = True, "after %d ticks" % len(ticks)
        return response
    node.create_service(Trigger, "slow", slow, callback_group=MutuallyExclusiveCallbackGroup())
    client = node.create_client(Trigger, "slow")
    assert node.spin_until(client.service_is_ready)
    futures = [client.call_async(Trigger.Request()) for _ in range(2)]
    assert node.spin_until(lambda: all(f.done() for f in futures), timeout=10)
    answers = [f.result().message for f in futures]
    assert all(a.startswith("after ") for a in answers)
    assert int(answers[0].split()[1]) >= 5   # the timer kept running while the first one waited
    assert int(answers[1].split()[1]) >= int(answers[0].split()[1]) + 5   # one after the other


def test_a_guard_condition_from_another_thread_wakes_it_at_once(node):
    woken = []
    guard = node.create_guard_condition(lambda: woken.append(time.monotonic()))
    node.lean.spin_once(timeout_sec=0)
    triggered = []
    threading.Timer(0.2, lambda: (triggered.append(time.monotonic()), guard.trigger())).start()
    started = time.monotonic()
    node.lean.spin_once(timeout_sec=5.0)
    assert woken and woken[0] - triggered[0] < 0.05 and time.monotonic() - started < 1.0


def test_liveliness_events_are_served(node):
    """A presence's loss is an event (a waitable), not a message: it must still reach the watch.
    (The holder is another participant: DDS does not report liveliness within one.)"""
    lost = []
    watch = presence.Watch(node, "_alive/thing", 0.6, on_lost=lambda: lost.append(True))
    other = Context()
    init_context(context=other, domain_id=node.context.get_domain_id(), node=False)
    try:
        holder = presence.Presence(Node("holder", context=other), "_alive/thing", 0.6)
        assert node.spin_until(lambda: watch.alive, timeout=30)
        holder.destroy()
        assert node.spin_until(lambda: lost, timeout=10)
    finally:
        rclpy.try_shutdown(context=other)


def test_entities_made_and_destroyed_in_callbacks(node):
    """A callback that destroys a subscription (even one ready in the same wait) and makes
    another: nothing breaks, the new one is served."""
    got, subscriptions = [], {}
    publisher = node.create_publisher(Float64, "numbers", TESTBED_QOS)

    def first(msg):
        got.append(("first", msg.data))
        node.destroy_subscription(subscriptions.pop("first"))
        node.destroy_subscription(subscriptions.pop("doomed"))
        subscriptions["second"] = node.create_subscription(Float64, "numbers", lambda m: got.append(("second", m.data)),
                                                           TESTBED_QOS)
    subscriptions["first"] = node.create_subscription(Float64, "numbers", first, TESTBED_QOS)
    subscriptions["doomed"] = node.create_subscription(Float64, "numbers", lambda m: got.append(("doomed", m.data)),
                                                       TESTBED_QOS)
    publisher.publish(Float64(data=1.0))
    assert node.spin_until(lambda: ("first", 1.0) in got)
    publisher.publish(Float64(data=2.0))
    assert node.spin_until(lambda: ("second", 2.0) in got)
    assert ("first", 2.0) not in got and ("doomed", 2.0) not in got


def test_an_exception_in_a_callback_comes_out_of_spin_once(node):
    def broken(msg):
        raise ValueError("broken callback")
    node.create_subscription(String, "broken", broken, TESTBED_QOS)
    node.create_publisher(String, "broken", TESTBED_QOS).publish(String(data="x"))
    with pytest.raises(ValueError, match="broken callback"):
        node.spin_until(lambda: False, timeout=5)


def test_raw_cdr_round_trip_through_dds(node):
    """Bytes built by robotarium_core.cdr go through DDS and come out as rclpy messages."""
    from robotarium_msgs.msg import RobotPoses
    got = []
    node.create_subscription(RobotPoses, "poses", got.append, TESTBED_QOS)
    publisher = node.create_publisher(RobotPoses, "poses", TESTBED_QOS)
    publisher.publish(cdr.ROBOT_POSES.build(frame_id="arena", run_id="r", step=7, ids=[0, 1], x=[0.5, -0.5],
                                            y=[0.1, 0.2], theta=[0.0, 3.0]))
    assert node.spin_until(lambda: got)
    assert (got[0].step, list(got[0].x), list(got[0].theta)) == (7, [0.5, -0.5], [0.0, 3.0])
