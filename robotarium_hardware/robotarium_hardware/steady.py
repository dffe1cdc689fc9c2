"""Keeping a real-time node's Python from pausing it: the nodes that stop or are real robots (the arena, the
tag tracker, and the simulated fleet's robots and stand-ins) answer within tens of milliseconds, and a full
garbage collection walks every object the imports made (rclpy, numpy, OpenCV: about 40 000, 10 ms here, several
times that on a loaded machine)."""
import gc


def steady():
    """Once set up: what exists now is never collected (gc.freeze), so a collection walks only what the node
    makes while it runs."""
    gc.collect()
    gc.freeze()
