"""`ros2 robotarium <verb>`: the robotarium command as a ros2cli command, laid out as ros2bag lays out
`ros2 bag` (a CommandExtension whose verbs are entry points of the group robotarium_cli.verb).

Only this module imports ros2cli: each verb's class here wraps its module in robotarium_cli.verb
(HELP, add_arguments, main), so `robotarium <verb>` works where ros2cli is not installed."""
from ros2cli.command import CommandExtension, add_subparsers_on_demand
from ros2cli.verb import VerbExtension

from robotarium_cli import verb as verbs
from robotarium_cli.console import error
from robotarium_cli.main import run_verb


class RobotariumCommand(CommandExtension):
    """The Robotarium testbed: start one, run and verify scripts on it, its status, replay and report runs."""

    def add_arguments(self, parser, cli_name):
        self._subparser = parser
        add_subparsers_on_demand(parser, cli_name, "_verb", "robotarium_cli.verb", required=False)

    def main(self, *, parser, args):
        if not hasattr(args, "_verb"):
            self._subparser.print_help()
            return 0
        return args._verb.main(args=args)


def _verb_class(name):
    module = verbs.load(name)

    def add_arguments(self, parser, cli_name):
        if hasattr(module, "EPILOG"):
            parser.epilog = module.EPILOG
        module.add_arguments(parser)

    def main(self, *, args):
        return run_verb(module, args, error)
    return type(name.capitalize() + "Verb", (VerbExtension,), {
        "__doc__": module.HELP[0].upper() + module.HELP[1:] + ".", "__module__": __name__,
        "add_arguments": add_arguments, "main": main})


# The entry points of robotarium_cli.verb (setup.py) name these: one class per verb of VERBS.
for _name in verbs.VERBS:
    globals()[_name.capitalize() + "Verb"] = _verb_class(_name)
