"""The one testbed configuration: loaded once, checked, declared as read-only ROS parameters, and
carried with each run so its report is computed with the numbers the run was made with."""
import dataclasses
import math
import os
import re

import numpy as np
import pytest
import yaml
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, SetParameters
from test_recorder import NS, Stack

from robotarium_core import config, model
from robotarium_core.config import DEFAULT, ConfigError, TestbedConfig
from robotarium_recording import results
from robotarium_recording.bag import Bag

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def write_config(path, **changes):
    values = dict(DEFAULT.to_dict(), **changes)
    path.write_text(yaml.safe_dump({"/**": {"ros__parameters": values}}))
    return path


def test_the_packaged_configuration_holds_the_robotariums_numbers():
    assert DEFAULT.arena == (-1.6, 1.6, -1.0, 1.0) and DEFAULT.boundaries == [-1.6, -1.0, 3.2, 2.0]
    assert (DEFAULT.time_step, DEFAULT.rate, DEFAULT.command_timeout) == (0.033, 30.0, 0.5)
    assert (DEFAULT.robot_diameter, DEFAULT.wheel_radius, DEFAULT.base_length) == (0.11, 0.016, 0.105)
    assert DEFAULT.max_wheel_velocity == DEFAULT.max_linear_velocity / DEFAULT.wheel_radius == 12.5
    # rps's formula for the turn-rate limit
    assert math.isclose(DEFAULT.max_angular_velocity,
                        2 * (DEFAULT.wheel_radius / DEFAULT.robot_diameter) * DEFAULT.max_wheel_velocity)
    # the model's constants are the configuration's (written once, in testbed.yaml)
    assert (model.TIME_STEP, model.COMMAND_TIMEOUT, model.ARENA, model.MAX_ROBOTS) == (
        DEFAULT.time_step, DEFAULT.command_timeout, DEFAULT.arena, DEFAULT.max_robots)
    assert list(dataclasses.asdict(DEFAULT)) == list(config.FIELDS)


@pytest.mark.parametrize("change, words", [
    (dict(rate=-5.0), "rate must be in (0, 1000]"),
    (dict(arena=[1.0, -1.0, -1.0, 1.0]), "arena must be [x_min, x_max, y_min, y_max] with min < max"),
    (dict(command_timeout="soon"), "command_timeout must be a finite number"),
    (dict(max_robots=2.5), "max_robots must be a whole number"),
    (dict(boundary_margin=float("nan")), "boundary_margin must be a finite number"),
])
def test_a_bad_value_is_refused_naming_it(tmp_path, change, words):
    with pytest.raises(ConfigError) as error:
        TestbedConfig.load(write_config(tmp_path / "bad.yaml", **change))
    assert words in str(error.value) and "bad.yaml" in str(error.value)


def test_unknown_and_missing_values_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="unknown configuration values \\['rates'\\]"):
        TestbedConfig.from_dict(dict(DEFAULT.to_dict(), rates=30.0))
    partial = DEFAULT.to_dict()
    del partial["rate"]
    with pytest.raises(ConfigError, match="lacks rate"):
        TestbedConfig.from_dict(partial)


def test_the_configuration_travels_as_yaml():
    custom = dataclasses.replace(DEFAULT, command_timeout=0.2, arena=(-2.0, 2.0, -1.2, 1.2))
    assert TestbedConfig.from_yaml(custom.to_yaml()) == custom
    # a run recorded before a value existed gets the default for it
    assert TestbedConfig.from_yaml("command_timeout: 0.25\n").command_timeout == 0.25
    # a foreign or damaged config message: a ConfigError saying what it is, never an AttributeError
    for text in ("- 1\n- 2\n", "just words", "{unclosed"):
        with pytest.raises(ConfigError, match="a run's configuration"):
            TestbedConfig.from_yaml(text)


# -- the nodes ---------------------------------------------------------------------------------------

@pytest.mark.node
def test_parameters_explain_themselves_and_refuse_changes_they_would_ignore(tmp_path):
    stack = Stack(tmp_path, recorder=False)
    try:
        probe = stack.probe
        described = probe.call(DescribeParameters, NS + "/simulator/describe_parameters",
                               DescribeParameters.Request(names=["rate", "arena", "command_timeout"]))
        rate, arena, timeout = described.descriptors
        assert "real-time loop" in rate.description and rate.read_only
        assert rate.floating_point_range[0].to_value == 1000.0
        assert "x_min, x_max, y_min, y_max" in arena.description and arena.read_only
        assert "command" in timeout.description
        # `ros2 param set /robotarium/simulator rate 10.0` used to answer "successful" and change nothing
        request = SetParameters.Request(parameters=[Parameter(name="rate", value=ParameterValue(
            type=ParameterType.PARAMETER_DOUBLE, double_value=10.0))])
        answer = probe.call(SetParameters, NS + "/simulator/set_parameters", request)
        assert not answer.results[0].successful and "read-only" in answer.results[0].reason
    finally:
        stack.close()


@pytest.mark.node
def test_a_run_is_reported_with_the_configuration_it_was_made_with(tmp_path):
    """A testbed with a wider arena and a 0.2 s command timeout: the recorded run carries both, and
    the report recomputed from the bag uses them (the packaged defaults would count a robot at
    x = 1.8 outside the arena every step, and 0.5 s of over-limit commands instead of 0.2 s)."""
    custom = write_config(tmp_path / "wide.yaml", arena=[-2.0, 2.0, -1.2, 1.2], command_timeout=0.2)
    stack = Stack(tmp_path, config_file=custom)
    try:
        stack.start(1, poses=np.array([[1.8], [0.0], [np.pi / 2]]), real_time=True, name="custom")
        stack.probe.spin_for(0.3)
        stack.command(0, [0.19], [0.6])   # 13.8 rad/s on a wheel: over the limit, then no more commands
        stack.probe.spin_for(1.0)
        ended = stack.end()
        stack.wait_closed(ended.recording)
    finally:
        stack.close()

    bag = Bag(ended.recording)
    assert bag.config() == TestbedConfig.load(custom)
    numbers = results.recompute(bag)
    assert numbers["mismatches"] == [], numbers["mismatches"]
    assert numbers["boundary_violations"] == ended.boundary_violations == 0
    # over the limit while the command was in force: 0.2 s at 30 Hz, not 0.5 s
    assert numbers["actuator_limit_iterations"] == ended.actuator_limit_iterations
    assert 3 <= ended.actuator_limit_iterations <= 9
    assert "command timeout 0.2 s" in results.report_text(bag, numbers)
    # the packaged defaults would have got this run wrong
    track = bag.poses()
    assert model.outside_arena(np.array([track.x[-1], track.y[-1], track.theta[-1]]), DEFAULT.arena).all()


def fields_read(source):
    """The configuration fields a node's source reads (`config.X`, `c.X`), with those behind the
    derived properties (`c.limits` reads the wheel numbers) expanded."""
    import inspect
    derived = {name: set(re.findall(r"self\.(\w+)", inspect.getsource(value.fget))) & set(config.FIELDS)
               for name, value in vars(TestbedConfig).items() if isinstance(value, property)}
    read = set()
    for name in re.findall(r"\b(?:config|c)\.(\w+)", source):
        read |= derived.get(name, {name} & set(config.FIELDS))
    return read


@pytest.mark.parametrize("role, module", [("safety", "robotarium_safety/robotarium_safety/safety_node.py")])
def test_a_node_declares_every_field_it_reads(role, module):
    # A field a node reads but does not declare keeps the packaged value whatever its params file
    # says (drive_on_position_error was read by the safety node and declared for the simulator only).
    with open(os.path.join(REPO, module)) as source:
        read = fields_read(source.read())
    undeclared = sorted(name for name in read if role not in config.FIELDS[name].used_by)
    assert read and not undeclared, "%s reads %s but declares it not (add %r to its used_by)" % (
        module, undeclared, role)
