"""What every testbed node does the same way: checked parameters, and a main() that spins.

Kept apart from model.py (no ROS there); the nodes themselves stay thin shells.
"""
import sys

import rclpy


def declare_checked_parameters(node, table):
    """Declare each parameter of `table` {name: (default, valid, meaning)} and check its value.

    Lists become lists of floats, numbers floats. Raises ValueError naming the parameter and
    what a valid value is, so that main() can stop the node with a clear message.
    """
    values = {}
    for name, (default, valid, meaning) in table.items():
        value = node.declare_parameter(name, default).value
        value = [float(v) for v in value] if isinstance(value, (list, tuple)) or hasattr(value, "tolist") \
            else float(value)
        if not valid(value):
            raise ValueError("parameter %s=%r is invalid: it must be %s." % (name, value, meaning))
        values[name] = value
    return values


def run_node(make_node, name, args=None, before_destroy=None):
    """rclpy.init, make the node (a bad parameter exits with code 2 and its message), spin until
    Ctrl-C or shutdown, then clean up. Returns the process exit code."""
    rclpy.init(args=args)
    try:
        node = make_node()
    except (ValueError, AssertionError) as error:
        print("%s: %s" % (name, error), file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        if before_destroy is not None:
            before_destroy(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
