"""robotarium run: run a Robotarium script against the testbed."""
import argparse

from robotarium_cli.console import seconds, seed_type
from robotarium_cli.running import RunRequest, finish_unfinished, run_script
from robotarium_client import session

HELP = "run a Robotarium script against the testbed"
FORMATTER = argparse.RawDescriptionHelpFormatter

EPILOG = """\
whatever happens, the run folder (the last line printed names it) gets log.txt, report.txt (its first
line says how the run ended), run.json, index.html, and from a recording made here trajectories.png and
run.mp4 (a script killed outright included; should run itself be killed outright, the next run, status or
report finishes the folder). Exit codes: 0 the run completed (call_at_scripts_end); 1 the script raised an exception or
could not be compiled or imported (then no testbed is started); 2 a bad command line; 3 the script
ended without call_at_scripts_end(); 4 no testbed, it was busy and --no-wait said not to wait, or it was lost
or ended the experiment; 5 the time limit;
128 + N interrupted by signal N (130: Ctrl-C, 143: SIGTERM, 129: SIGHUP)."""


def add_arguments(parser):
    parser.add_argument("script")
    parser.add_argument("script_args", nargs=argparse.REMAINDER, help="arguments passed to the script")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--lockstep", dest="mode", action="store_const", const="lockstep",
                      help="one step per step() call, as fast as possible (overrides sim_in_real_time)")
    mode.add_argument("--real-time", dest="mode", action="store_const", const="real-time",
                      help="30 Hz like the real testbed (overrides sim_in_real_time)")
    parser.add_argument("--time-limit", type=seconds, metavar="S",
                        help="end the experiment after S seconds of testbed time, in real time and lockstep alike "
                             "(default: the testbed's time_limit, 900 s: the real Robotarium's 15-minute slot; 0: none)")
    parser.add_argument("--hardware", action="store_true",
                        help="hardware-like: the real testbed's tracking and command latency, pose noise, wheel "
                             "dynamics (the numbers: hardware section of testbed.yaml)")
    parser.add_argument("--seed", type=seed_type, default=0,
                        help="seed of the hardware-like model (default: the testbed draws one; the report names it)")
    parser.add_argument("--no-record", action="store_true", help="(local testbed only) do not record the run")
    parser.add_argument("--no-video", action="store_true", help="skip rendering the video of the run")
    parser.add_argument("--no-verdict", action="store_true",
                        help="where the safety layer changed the script's commands, do not judge the script as "
                             "./robotarium verify does (by default run does, and prints the Robotarium's verdict)")
    parser.add_argument("--bags-dir", help="(local testbed only) where runs are recorded (default: bags/)")
    parser.add_argument("--config", help="(local testbed only) the testbed configuration file "
                                         "(default: robotarium_core's testbed.yaml)")
    parser.add_argument("--results-dir", help="where runs not recorded here keep their results "
                                              "(default: results/)")
    parser.add_argument("--no-wait", action="store_true",
                        help="when the testbed is busy with another experiment, exit at once (code 4) instead of "
                             "waiting in line for it (first come, first served)")
    parser.add_argument("--no-local-testbed", action="store_true",
                        help="never start a testbed here: wait up to 60 s for one to answer (./robotarium up)")
    parser.add_argument("--rps", choices=session.RPS_APIS, default=None,
                        help="the Robotarium API the script is written against: guide (rps 0.0.0, the user's guide), "
                             "2 (the Robotarium simulator 2.x: sensors, obstacles, the drive-on phase, debug()) or "
                             "auto (default, or ROBOTARIUM_RPS: 2 when the script uses something only 2.x has)")


# `./robotarium run script.py --lockstep` works too: our own flags may follow the script.
OWN_FLAGS = {"--lockstep": ("mode", "lockstep"), "--real-time": ("mode", "real-time"),
             "--no-record": ("no_record", True), "--no-video": ("no_video", True),
             "--no-local-testbed": ("no_local_testbed", True), "--hardware": ("hardware", True),
             "--no-wait": ("no_wait", True), "--no-verdict": ("no_verdict", True)}


def take_own_arguments(args, error):
    """Our own flags given after the script (argparse passes them on to it) taken back."""
    rest, given = [], iter(args.script_args)
    for arg in given:
        if arg in OWN_FLAGS:
            setattr(args, *OWN_FLAGS[arg])
        elif arg == "--time-limit" or arg.startswith("--time-limit="):
            value = arg.partition("=")[2] or next(given, "")
            try:
                args.time_limit = seconds(value)
            except argparse.ArgumentTypeError as problem:
                error("argument --time-limit: %s" % problem)
        else:
            rest.append(arg)
    args.script_args = rest


def main(args):
    finish_unfinished(args.results_dir)
    options = session.RunOptions(real_time={"lockstep": False, "real-time": True}.get(args.mode),
                                 config_file=args.config, time_limit=args.time_limit, hardware=args.hardware,
                                 seed=args.seed, rps_api=args.rps or session.rps_api_from_environment(),
                                 wait=not args.no_wait)
    code, _, _ = run_script(RunRequest(args.script, args.script_args, options, record=not args.no_record,
                                       bags_dir=args.bags_dir, video=not args.no_video,
                                       local_testbed=not args.no_local_testbed, results_dir=args.results_dir,
                                       judge=not args.no_verdict))
    return code
