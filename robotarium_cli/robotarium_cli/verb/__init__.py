"""The robotarium command's verbs, one module each, laid out as ros2bag lays out its own: each has
HELP (one line), add_arguments(parser) and main(args), so that `robotarium <verb>` (robotarium_cli.main)
and `ros2 robotarium <verb>` (robotarium_cli.command.robotarium, where ros2cli is installed) are the same command.
A verb whose arguments its own package parses (replay, report, view: shared with `ros2 run`) has
main_argv(argv) instead of main(args), and add_arguments for `ros2 robotarium`.

A verb imports what its main needs (bringup, the client, messages) inside main: `robotarium --help`
and `ros2 robotarium` import every verb module to list them."""
import importlib

# In the order `robotarium --help` lists them.
VERBS = ("up", "fleet", "run", "verify", "status", "stop", "end", "demo", "replay", "report", "view")


def load(name):
    """The module of verb `name` (robotarium_cli.verb.<name>)."""
    return importlib.import_module("robotarium_cli.verb." + name)
