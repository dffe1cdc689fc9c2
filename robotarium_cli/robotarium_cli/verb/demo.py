"""robotarium demo: a bundled multi-robot example, headless and recorded."""
import os

from robotarium_bringup.testbed import repository_root
from robotarium_cli.console import say
from robotarium_cli.running import RunRequest, run_script
from robotarium_client import session

HELP = "run a bundled multi-robot example headless, recorded"


def add_arguments(parser):
    parser.add_argument("--no-video", action="store_true", help="skip rendering the video of the run")


DEMO_SCRIPT = os.path.join("examples", "barrier_certificates.py")  # 8 robots swap places through the middle


def main(args):
    script = os.path.join(repository_root(), DEMO_SCRIPT)
    say("demo: %s, headless, lockstep" % DEMO_SCRIPT)
    code, info, run_dir = run_script(RunRequest(script, options=session.RunOptions(real_time=False),
                                                video=not args.no_video, judge=True))
    if code == 0 and run_dir:
        say("demo done: the results page, the report, trajectories.png and the video of the run are in %s"
            % run_dir)
    return code
