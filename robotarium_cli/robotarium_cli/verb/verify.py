"""robotarium verify: judge a script as the Robotarium's verification does (robotarium_cli.verification)."""
import argparse
import os

from robotarium_cli import verification
from robotarium_cli.console import positive_int, say, seconds
from robotarium_cli.running import verify_script
from robotarium_client import session

HELP = "judge a script as the Robotarium's verification does: accept or reject"
DESCRIPTION = ("Run SCRIPT in lockstep on a testbed of its own (or on a warm one: ./robotarium up --verification) with "
               "the safety node auditing, and accept or reject it by the Robotarium's rules (their limits: testbed.yaml, "
               "verify_*).")
FORMATTER = argparse.RawDescriptionHelpFormatter

EPILOG = """\
before anything runs the script must compile and import only modules the Robotarium provides
(verify_allowed_modules in testbed.yaml, and modules beside the script). It then runs in lockstep on a
testbed of its own with the safety node auditing (or on the warm verification testbed, where
./robotarium up --verification runs one on this machine and ROS_DOMAIN_ID with the same --config,
--no-record and --bags-dir, and it is free): it lets the script's own commands through, so
collisions and robots leaving the arena happen and are counted as on the Robotarium. Rejected when
it has more than verify_max_collision_iterations (100) collision iterations or verify_max_boundary_iterations
(100) iterations with robots outside the arena, uses another robot count than --robots, runs longer than
verify_duration_factor (1.5) x --duration, raises, or never calls call_at_scripts_end().
Exit codes: 0 accepted; 6 rejected (each broken rule is printed, and listed in --json); 2 a bad command
line; 4 the testbed failed (no verdict); 128 + N interrupted by signal N. No video unless --video."""


def add_arguments(parser):
    parser.add_argument("script")
    parser.add_argument("script_args", nargs=argparse.REMAINDER, help="arguments passed to the script")
    parser.add_argument("--robots", type=positive_int, metavar="N",
                        help="the number of robots declared for the experiment (omitted: not checked)")
    parser.add_argument("--duration", type=seconds, metavar="S",
                        help="the experiment's declared duration in seconds (omitted: not checked)")
    parser.add_argument("--json", metavar="FILE", help="also write the verdict as JSON to FILE (exit codes 0 and 6)")
    parser.add_argument("--rps", choices=session.RPS_APIS + ("1",), default=None,
                        help="the Robotarium API the script is written against, as for run (1: the guide's)")
    parser.add_argument("--config", help="the testbed configuration file (default: robotarium_core's testbed.yaml)")
    parser.add_argument("--no-record", action="store_true", help="do not record the run")
    parser.add_argument("--video", action="store_true",
                        help="also make the recorded run's video (run.mp4; default: none, as the verdict needs none)")
    parser.add_argument("--bags-dir", help="where the run is recorded (default: bags/)")
    parser.add_argument("--results-dir", help="where a run not recorded keeps its results (default: results/)")


# Our own options that may follow the script too (argparse passes them on to it).
OWN_OPTIONS = {"--robots": positive_int, "--duration": seconds, "--json": str, "--rps": str, "--config": str,
               "--bags-dir": str, "--results-dir": str}


def take_own_arguments(args, error):
    rest, given = [], iter(args.script_args)
    for arg in given:
        name, _, value = arg.partition("=")
        if name in OWN_OPTIONS:
            value = value or next(given, "")
            try:
                value = OWN_OPTIONS[name](value)
            except argparse.ArgumentTypeError as problem:
                error("argument %s: %s" % (name, problem))
            if name == "--rps" and value not in session.RPS_APIS + ("1",):
                error("argument --rps: invalid choice %r" % value)
            setattr(args, name[2:].replace("-", "_"), value)
        elif arg == "--no-record":
            args.no_record = True
        else:
            rest.append(arg)
    args.script_args = rest


def main(args):
    """./robotarium verify: see robotarium_cli.verification."""
    from robotarium_core import outcomes
    from robotarium_core.config import ConfigError, TestbedConfig
    try:
        if args.config:
            TestbedConfig.load(args.config)
    except (OSError, ConfigError) as error:
        say("cannot read the testbed configuration: %s" % error)
        return outcomes.USAGE_ERROR
    if args.video and args.no_record:
        say("--video makes the video from the recording: not with --no-record")
        return outcomes.USAGE_ERROR
    script = os.path.abspath(args.script)
    if not os.path.isfile(script):
        say("no such script: %s" % script)
        return outcomes.USAGE_ERROR
    try:
        judged = verify_script(
            script, args.script_args, args.config, args.robots, args.duration,
            rps_api={"1": "guide"}.get(args.rps, args.rps), record=not args.no_record, bags_dir=args.bags_dir,
            results_dir=args.results_dir, video=args.video)
    except verification.NoVerdict as error:
        say("no verdict: %s" % error)
        return error.code
    if args.json:
        verification.write_json(args.json, judged.document())
    print(judged.text(), end="")
    return outcomes.VERIFY_ACCEPTED if judged.accepted else outcomes.VERIFY_REJECTED
