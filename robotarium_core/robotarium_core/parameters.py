"""A node's ROS parameters, declared with what `ros2 param describe` shows: a description, a type
and a range, read-only where the node reads the value only at start-up; a value out of range
fails with a message that names the parameter and a valid value. `declare_config` declares the
testbed configuration's values (robotarium_core/testbed.yaml) that a node reads.
"""
import math

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.exceptions import InvalidParameterTypeException, ParameterException

from robotarium_core.config import DEFAULT, FIELDS, TestbedConfig


def _descriptor(description, value, low=-math.inf, high=math.inf, integer=False, read_only=True):
    """A ParameterDescriptor that `ros2 param describe` explains and that refuses values out of
    range, or any change at all where the node reads the value only at start-up (read_only)."""
    if isinstance(value, bool):
        kind = ParameterType.PARAMETER_BOOL
    elif isinstance(value, (list, tuple)) and value and all(isinstance(v, str) for v in value):
        kind = ParameterType.PARAMETER_STRING_ARRAY
    elif isinstance(value, (list, tuple)):
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
    except (ParameterException, InvalidParameterTypeException) as error:
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
        if isinstance(default, tuple):
            default = list(default) if field.names else [float(v) for v in default]
        values[name] = declare_parameter(
            node, name, default, "%s (testbed configuration)" % field.description,
            low=field.low, high=field.high, integer=field.integer)
    return TestbedConfig.from_dict(values, base=DEFAULT)
