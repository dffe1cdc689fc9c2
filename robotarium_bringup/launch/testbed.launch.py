"""The Robotarium testbed under `ros2 launch`: the nodes `./robotarium up` starts, on a ROS install.

    ros2 launch robotarium_bringup testbed.launch.py [namespace:=robotarium] [config:=FILE]
                                                   [bags_dir:=DIR] [record:=true] [fleet:=FILE]

`--show-args` lists the arguments. Real time or lockstep is no launch argument: each experiment
chooses it when it starts. Ctrl-C stops the nodes as ./robotarium up does (the simulator ends a
running experiment, the recorder closes its bag). Where a testbed runs already in the namespace and
domain, each node refuses with exit code 4 (robotarium_core/claim.py) and the launch ends with an
error. The arguments and their defaults: docs/ros-interface.md#launch.
"""
import json
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, RegisterEventHandler
from launch.conditions import IfCondition
from launch.event_handlers import OnProcessExit
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    config = os.path.join(get_package_share_directory("robotarium_core"), "config", "testbed.yaml")
    arguments = [
        DeclareLaunchArgument("namespace", default_value="robotarium",
                              description="namespace of the testbed's topics and services (clients: "
                                          "ROBOTARIUM_NAMESPACE=/<namespace>)"),
        DeclareLaunchArgument("config", default_value=config,
                              description="testbed configuration file of the simulator and the safety node"),
        DeclareLaunchArgument("bags_dir", default_value="",
                              description="where runs are recorded (empty: $ROBOTARIUM_ROOT/bags, else ./bags)"),
        DeclareLaunchArgument("record", default_value="true", choices=["true", "false"],
                              description="start the recorder"),
        DeclareLaunchArgument("fleet", default_value="",
                              description="a fleet file (your own robots): the hardware arena moves them in the "
                                          "simulator's place"),
    ]
    return LaunchDescription(arguments + [OpaqueFunction(function=_nodes),
                                          RegisterEventHandler(OnProcessExit(on_exit=_refused))])


def _nodes(context):
    """The testbed's nodes: the simulator, or a fleet's hardware arena (with its tag tracker where a camera
    tracks it), the safety node, the recorder. Chosen here, as the launch starts: the fleet file says."""
    namespace = LaunchConfiguration("namespace")
    parameters = [LaunchConfiguration("config")]
    record = LaunchConfiguration("record").perform(context)
    fleet_file = LaunchConfiguration("fleet").perform(context)
    # with a recorder, a run's first steps wait for its readers (the streams are volatile)
    world = _overrides(wait_for_recorder=record == "true")
    if fleet_file:
        from robotarium_hardware import fleet as fleets  # (only a launch of robots needs it)
        fleet_file = os.path.abspath(fleet_file)
        fleet = _overrides(fleet_file=fleet_file)
        nodes = [Node(package="robotarium_hardware", executable="arena", namespace=namespace,
                      parameters=parameters, ros_arguments=world + fleet, output="screen", emulate_tty=True)]
        if fleets.load(fleet_file).tracking == "camera":
            nodes.append(Node(package="robotarium_hardware", executable="tag_tracker", namespace=namespace,
                              ros_arguments=fleet, output="screen", emulate_tty=True))
    else:
        nodes = [Node(package="robotarium_sim", executable="simulator", namespace=namespace,
                      parameters=parameters, ros_arguments=world, output="screen", emulate_tty=True)]
    return nodes + [
        Node(package="robotarium_safety", executable="safety", namespace=namespace, parameters=parameters,
             output="screen", emulate_tty=True),
        Node(package="robotarium_recording", executable="recorder", namespace=namespace,
             ros_arguments=_overrides(bags_dir=LaunchConfiguration("bags_dir").perform(context)), output="screen",
             emulate_tty=True, condition=IfCondition(LaunchConfiguration("record"))),
    ]


def _overrides(**values):
    """Parameters as `--ros-args -p NAME:=VALUE` (VALUE as JSON, which the YAML that rcl reads it as takes
    whole: a path stays a string). launch_ros writes a dict of parameters to a file in /tmp of its own and
    never removes it: one per node at every launch."""
    return [arg for name, value in values.items() for arg in ("-p", "%s:=%s" % (name, json.dumps(value)))]


REFUSED = 4   # robotarium_core.claim.REFUSED: an older node of this kind runs in the namespace and domain


def _refused(event, context):
    """A node that refused to be a second one ends the launch with an error (its line names the one
    that runs): a testbed without its simulator, safety node or recorder is no testbed."""
    if event.returncode == REFUSED:
        raise RuntimeError("not starting a second testbed: %s refused (exit code 4), an older one runs in this "
                           "namespace and domain (its line above names it)" % event.action.name)
