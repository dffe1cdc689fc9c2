"""What every testbed node does the same way: the testbed configuration as ROS parameters, and a
main() that spins.

Kept apart from model.py and config.py (no ROS there); the nodes themselves stay thin shells.
"""
import math
import sys

import rclpy
from rclpy.exceptions import ParameterException
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType

from robotarium_core.config import DEFAULT, FIELDS, TestbedConfig


def _descriptor(description, value, low=-math.inf, high=math.inf, integer=False, read_only=True):
    """A ParameterDescriptor that `ros2 param describe` explains and that refuses values out of
    range, or any change at all where the node reads the value only at start-up (read_only)."""
    if isinstance(value, (list, tuple)):
        kind = ParameterType.PARAMETER_DOUBLE_ARRAY
    elif isinstance(value, str):
        kind = ParameterType.PARAMETER_STRING
    elif integer:
        kind = ParameterType.PARAMETER_INTEGER
    else:
        kind = ParameterType.PARAMETER_DOUBLE
    descriptor = ParameterDescriptor(description=description, type=kind, read_only=read_only)
    # ROS ranges are closed; an open lower bound (> 0) is checked by the config, not here.
    if kind == ParameterType.PARAMETER_INTEGER and (math.isfinite(low) or math.isfinite(high)):
        descriptor.integer_range = [IntegerRange(from_value=int(max(low, -2**31)), to_value=int(min(high, 2**31)))]
    elif kind == ParameterType.PARAMETER_DOUBLE and math.isfinite(low) and math.isfinite(high):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high))]
    return descriptor


def declare_parameter(node, name, default, description, **range_and_mode):
    """Declare one parameter with its descriptor and return its value; a value given out of its
    range or of the wrong type raises ValueError saying which parameter and what a valid one is."""
    descriptor = _descriptor(description, default, **range_and_mode)
    try:
        return node.declare_parameter(name, default, descriptor).value
    except (ParameterException, rclpy.exceptions.InvalidParameterTypeException) as error:
        low, high = range_and_mode.get("low", -math.inf), range_and_mode.get("high", math.inf)
        valid = "" if not (math.isfinite(low) or math.isfinite(high)) else " in [%g, %g]" % (low, high)
        raise ValueError("parameter %s must be a %s%s (%s); %s" % (
            name, type(default).__name__, valid, description, error)) from None


def declare_config(node, role=None):
    """Declare the testbed configuration's values that `role` ("simulator" or "safety") reads, or
    all of them (role None: the simulator, which publishes the whole configuration of a run), as
    read-only parameters with their meaning and range, defaults from the packaged testbed.yaml
    (a params file given with --params-file overrides them). Returns the checked TestbedConfig;
    a bad value raises ConfigError naming it, which run_node turns into a clear exit."""
    values = {}
    for name, field in FIELDS.items():
        if role is not None and role not in field.used_by:
            continue
        default = getattr(DEFAULT, name)
        default = list(default) if isinstance(default, tuple) else default
        values[name] = declare_parameter(
            node, name, default, "%s (testbed configuration)" % field.description,
            low=field.low, high=field.high, integer=field.integer)
    return TestbedConfig.from_dict(values, base=DEFAULT)


def run_node(make_node, name, args=None, before_destroy=None):
    """rclpy.init, make the node (a bad parameter exits with code 2 and its message), spin until
    Ctrl-C or shutdown, then clean up. Returns the process exit code."""
    rclpy.init(args=args)
    try:
        node = make_node()
    except (ValueError, AssertionError, ParameterException) as error:
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
