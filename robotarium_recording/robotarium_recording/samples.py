"""Which readers the recorder needs on a topic, and dropping the second copy of a sample. Plain Python.

A DDS reader hears only the writers whose QoS offer meets its request: a transient-local reader
no volatile writer (`ros2 topic pub`, plain rclpy: reliable + volatile), a reliable one no
best-effort writer. A single reader per topic therefore missed some publishers the testbed accepts
(its command inputs are volatile: any reliable writer drives it). The recorder keeps one reader
per kind of writer it sees on a topic (`reader_kinds`): the transient-local one still gets a
latched writer's history on matching, the volatile one every volatile writer. A writer that more
than one of them matches delivers each sample to each: `SeenSamples` drops the later copies by the
sample's identity (a hash of its writer's source timestamp and sequence number, and its length), remembering
the last `window` identities per topic (the configuration's recorder_dedup_window).
"""
from collections import deque

# (reliable, transient_local) of a reader
RELIABLE_LATCHED, RELIABLE_VOLATILE, BEST_EFFORT = (True, True), (True, False), (False, False)


def reader_kinds(offers):
    """The readers that together hear every writer offering `offers` ((reliable, transient_local)
    pairs): a best-effort writer needs a best-effort reader, a reliable volatile one a reliable
    volatile reader, a reliable transient-local one a reliable transient-local reader (which also
    hands over its history)."""
    kinds = set()
    for reliable, latched in offers:
        kinds.add(BEST_EFFORT if not reliable else (RELIABLE_LATCHED if latched else RELIABLE_VOLATILE))
    return kinds


class SeenSamples:
    """The identities of the last `window` samples of each topic: first(topic, identity) is True
    the first time a sample arrives, False for its copies through another reader."""

    def __init__(self, window):
        if window < 1:
            raise ValueError("the window must hold at least one sample (got %r)" % window)
        self.window = int(window)
        self.topics = {}   # topic -> (deque of identities, set of them)
        self.copies = 0    # copies dropped, over the recorder's life

    def first(self, topic, identity):
        order, seen = self.topics.setdefault(topic, (deque(), set()))
        if identity in seen:
            self.copies += 1
            return False
        order.append(identity)
        seen.add(identity)
        if len(order) > self.window:
            seen.discard(order.popleft())
        return True


def identity(info, data):
    """A sample's identity from rclpy's message info (dict) and its bytes: one 64-bit hash of its
    writer's source timestamp, sequence number and its length (half the memory of keeping the three:
    10,000 of them for each of a 2.x run's ~36 topics; two samples of a topic share it once in 2**64
    draws). None when the middleware gives neither a stamp nor a sequence number (nothing is dropped)."""
    stamp = info.get("source_timestamp") if info else None
    sequence = info.get("publication_sequence_number") if info else None
    if not stamp and sequence is None:
        return None
    return hash((stamp, sequence, len(data)))
