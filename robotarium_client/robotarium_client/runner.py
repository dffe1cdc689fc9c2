"""Runs an experiment script for `./robotarium run`, in the script's own process.

    python -m robotarium_client.runner OPTIONS_JSON RUN_INFO_JSON SCRIPT [ARGS...]

It sets robotarium_client.session.options (the run's choices, explicitly: no environment
variables), runs SCRIPT as `python SCRIPT ARGS` would (as __main__, its folder first on
sys.path), and afterwards writes what the script's last Robotarium reported when it ended (run
id, recording, report, counters) to RUN_INFO_JSON, for the command line to collect the results.

Stopping: SIGINT, SIGTERM and SIGHUP raise KeyboardInterrupt in the script (its Robotarium's exit
handler then ends the experiment). `./robotarium run` starts this process in a process group of
its own and forwards the signals it gets, once; and it hands this process its lifeline
(robotarium_core.lifeline): if `./robotarium run` is killed outright, the script is interrupted the
same way (its Robotarium ends the experiment on a testbed that outlives `run`; one that `run`
started ends it itself), and this process exits at the latest ORPHAN_EXIT seconds later.
"""
import _thread
import json
import os
import runpy
import signal
import sys
import threading

from robotarium_client import session
from robotarium_core import lifeline

ORPHAN_EXIT = 1.5


def _orphaned():
    # (nothing printed: the output went to the process that is gone)
    timer = threading.Timer(ORPHAN_EXIT, os._exit, (128 + signal.SIGKILL,))
    timer.daemon = True   # it still fires while exit handlers run
    timer.start()
    _thread.interrupt_main(signal.SIGINT)


def main(argv):
    options_json, run_info_path, script, *script_args = argv
    for name in ("SIGTERM", "SIGHUP"):
        signal.signal(getattr(signal, name), signal.default_int_handler)
    lifeline.watch(_orphaned)
    session.options = session.RunOptions.from_json(options_json)
    sys.argv = [script, *script_args]
    sys.path.insert(0, os.path.dirname(os.path.abspath(script)))
    try:
        runpy.run_path(script, run_name="__main__")
    finally:
        ended = [r.run_info for r in session.robotaria if r.run_info is not None]
        if ended:
            with open(run_info_path, "w") as f:
                json.dump(ended[-1], f, indent=2)


if __name__ == "__main__":
    main(sys.argv[1:])
