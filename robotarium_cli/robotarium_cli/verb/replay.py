"""robotarium replay: republish a recorded run (in experiment time; --figure draws it).

Its arguments are robotarium_recording's (shared with `ros2 run`), which parses them itself."""
import robotarium_recording as recording
from robotarium_cli.console import error

HELP = "republish a recorded run (in experiment time; --figure draws it)"


def add_arguments(parser):
    recording.replay_arguments(parser)


def main_argv(argv):
    return recording.replay_main(argv)


def main(args):
    """ros2 robotarium replay: the arguments parsed already."""
    return recording.replay(args, error)
