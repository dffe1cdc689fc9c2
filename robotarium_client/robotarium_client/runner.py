"""Runs an experiment script for `./robotarium run`, in the script's own process.

    python -m robotarium_client.runner OPTIONS_JSON RUN_INFO_JSON SCRIPT [ARGS...]

It sets robotarium_client.session.options (the run's choices, explicitly: no environment
variables), runs SCRIPT as `python SCRIPT ARGS` would (as __main__, its folder first on
sys.path), and afterwards writes what the script's last Robotarium reported when it ended (run
id, recording, report, counters) to RUN_INFO_JSON, for the command line to collect the results.
"""
import json
import os
import runpy
import sys

from robotarium_client import session


def main(argv):
    options_json, run_info_path, script, *script_args = argv
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
