"""robotarium report: recompute the results of a recorded run (report, plot, video, page).

Its arguments are robotarium_recording's (shared with `ros2 run`), which parses them itself."""
import robotarium_recording as recording
from robotarium_cli.running import finish_unfinished

HELP = "recompute the results of a recorded run (report, plot, video, page)"


def add_arguments(parser):
    recording.report_arguments(parser)


def main_argv(argv):
    if "-h" not in argv and "--help" not in argv:
        finish_unfinished()
    return recording.report_main(argv)


def main(args):
    """ros2 robotarium report: the arguments parsed already."""
    finish_unfinished()
    return recording.report(args)
