"""Taking every message waiting in a subscription's queue at once, for the readers that act on the
present (the client's and the safety node's poses) and the command inputs under a flood (rclpy's
executor hands a callback one message per turn of its wait loop).
"""


def take_waiting(subscription, limit=10_000, with_info=False):
    """The messages waiting in `subscription`'s queue, taken now (raw bytes for a raw=True one; with
    with_info, (message, its message info) as rclpy hands a callback that takes both).

    rclpy's executor hands a callback one message per turn of its wait loop, a few hundred
    microseconds each on a loaded machine; under a flood of 1000 arrays a second a node then falls
    behind until its queue is full and the oldest array, perhaps the client's, is pushed out. A
    callback that takes the rest of the queue at once (a few microseconds an array) keeps up."""
    with subscription.handle:
        for _ in range(limit):
            taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
            if taken is None:
                return
            yield taken if with_info else taken[0]
