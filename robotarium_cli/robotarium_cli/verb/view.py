"""robotarium view: serve the testbed live to Foxglove: the scene, status, commands and poses.

Its arguments are robotarium_recording's (shared with `ros2 run`), which parses them itself."""
import robotarium_recording as recording
from robotarium_cli.console import error

HELP = "serve the testbed live to Foxglove: the scene, status, commands and poses"


def add_arguments(parser):
    recording.view_arguments(parser)


def main_argv(argv):
    return recording.view_main(argv)


def main(args):
    """ros2 robotarium view: the arguments parsed already."""
    return recording.view(args, error)
