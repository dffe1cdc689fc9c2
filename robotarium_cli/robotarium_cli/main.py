"""The robotarium command: up, run, verify, demo, status, stop, end, replay, report, view.

    robotarium VERB [ARGS]      (./robotarium VERB makes the environment, then hands over to it)
    ros2 robotarium VERB [ARGS] (where ros2cli is installed: robotarium_cli.command.robotarium)

One module per verb (robotarium_cli.verb). Signals: SIGINT, SIGTERM and SIGHUP (Ctrl-C, `kill`,
`timeout`, a closed terminal) to `run`, `demo` or `up` stop the script if it still runs
(console.Interruption), end its experiment, stop the testbed nodes the command started and close
the recording. SIGKILL cannot be caught: then the script and the nodes notice through their
lifeline (robotarium_core.lifeline) that the command is gone and do the same by themselves.
"""
import argparse
import os
import sys

from robotarium_cli import verb as verbs


def add_verb_parser(subparsers, name):
    """The parser of verb `name` among `subparsers`, with its arguments and its module."""
    module = verbs.load(name)
    parser = subparsers.add_parser(name, help=module.HELP, description=getattr(module, "DESCRIPTION", None),
                                   epilog=getattr(module, "EPILOG", None),
                                   formatter_class=getattr(module, "FORMATTER", argparse.HelpFormatter))
    module.add_arguments(parser)
    return parser, module


def run_verb(module, args, error):
    """Run a parsed verb (here and for ros2 robotarium): its own flags given after a script taken
    back first (`robotarium run script.py --lockstep`); error(message) reports a bad one and exits."""
    if hasattr(module, "take_own_arguments"):
        module.take_own_arguments(args, error)
    return module.main(args) or 0


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in verbs.VERBS and hasattr(verbs.load(argv[0]), "main_argv"):
        return verbs.load(argv[0]).main_argv(argv[1:]) or 0   # it parses its arguments, --help included
    parser = argparse.ArgumentParser(prog="./robotarium", description="The Robotarium testbed on ROS 2.")
    subparsers = parser.add_subparsers(dest="command", required=True)
    # A verb named: its parser only (the others' modules and what they import, ~0.1 s, are not needed);
    # none, or an unknown one: every verb's, for the list of them.
    named = [argv[0]] if argv and argv[0] in verbs.VERBS else verbs.VERBS
    parsers = {name: add_verb_parser(subparsers, name) for name in named}
    args = parser.parse_args(argv)
    verb_parser, module = parsers[args.command]
    return run_verb(module, args, verb_parser.error)


def console_main():
    """The `robotarium` console script."""
    code = main()
    # Leave without tearing down the DDS participant the probes kept (testbed._probe_context): Fast DDS
    # can deadlock destroying one while discovery callbacks run. Everything of ours is closed by now.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code if isinstance(code, int) else 0 if code is None else 1)


if __name__ == "__main__":
    console_main()
