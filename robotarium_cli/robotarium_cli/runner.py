"""Runs an experiment script for `./robotarium run`, in the script's own process.

    python -m robotarium_cli.runner OPTIONS_JSON RUN_INFO_JSON SCRIPT [ARGS...]
    python -m robotarium_cli.runner --gated NAMESPACE   (the same arguments, as JSON, through its start gate)

Gated, it is a warm interpreter: started while `run` still looks for the testbed (or starts one), it
imports what every script needs (rclpy, numpy, the client; not `rps`, whose API waits for the run's
options) and then waits at its start gate (robotarium_core.lifeline.StartGate) for the run's
arguments; a gate closed without them (no testbed, or `run` gone) ends it without running anything.

It sets robotarium_client.session.options (the run's choices, explicitly: no environment
variables) and runs SCRIPT as `python SCRIPT ARGS` would. However the script ends (its end, an
exception, a signal: SIGINT as KeyboardInterrupt, SIGTERM and SIGHUP as session.Interrupted, a
lost testbed, the lifeline of a killed `run`), it ends every experiment still running, saying how,
and keeps the run in RUN_INFO_JSON (a run_record.RunRecord); started.json beside it names the run
from its start, for a script killed outright. Exit code: outcomes.EXIT_CODES (128 + a signal).
What each end leaves, and its bound: docs/faults.md#a-run-and-its-processes.
"""
import _thread
import json
import os
import runpy
import signal
import sys
import threading
import traceback

from robotarium_client import session, testbed_link
from robotarium_client.errors import EndedByTestbed, EndedByUnsentRequest, TestbedBusy, TestbedIncomplete
from robotarium_client.figure import skip_headless_idle_draws
from robotarium_core import lifeline, outcomes, run_record

ORPHAN_EXIT = 1.5
RESERVE, RESERVE_BYTES = ".reserve", 256 * 1024   # room kept for run.json (main)
STARTED = "started.json"   # beside RUN_INFO_JSON: session.note_started's record of the running experiment
orphaned = []   # set when ./robotarium run is gone: the interruption is said to be that


def _orphaned():
    # The output went to the process that is gone: what is printed from now on (the traceback,
    # the report) goes to the run's log instead, where the one finishing the run folder reads it
    # (a write to the closed pipe would raise in the script and cut its end short).
    orphaned.append(True)
    _output_to(session.run_files and session.run_files.get("log"))
    timer = threading.Timer(ORPHAN_EXIT, os._exit, (128 + signal.SIGKILL,))
    timer.daemon = True   # it still fires while exit handlers run
    timer.start()
    _thread.interrupt_main(signal.SIGINT)

def _output_to(path):
    """Send this process's stdout and stderr to the end of file `path` (nowhere if it cannot be opened)."""
    try:
        fd = os.open(path or os.devnull, os.O_WRONLY | os.O_APPEND)
    except OSError:   # a job box's script cannot write the command's log
        fd = os.open(os.devnull, os.O_WRONLY)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)


SIGNAL_EXIT = {signal.SIGINT: 128 + signal.SIGINT, signal.SIGTERM: 128 + signal.SIGTERM,
               signal.SIGHUP: 128 + signal.SIGHUP}


def _raise_interrupted(signum, frame):
    raise session.Interrupted(signal.Signals(signum).name)


SIGINT_RECEIVED = []   # [True] once SIGINT came


def _raise_keyboard_interrupt(signum, frame):
    # As Python's own handler, remembered: raised inside a C call, pybind11 turns the KeyboardInterrupt into a
    # RuntimeError ("Unable to convert call argument"), and the run said "the script raised RuntimeError" (a soak).
    SIGINT_RECEIVED.append(True)
    raise KeyboardInterrupt


def print_traceback(exc, script):
    """The traceback as `python SCRIPT` prints it: frames from the script on, not the runner's."""
    tb = exc.__traceback__
    while tb is not None and os.path.abspath(tb.tb_frame.f_code.co_filename) != script:
        tb = tb.tb_next
    traceback.print_exception(type(exc), exc, tb or exc.__traceback__, file=sys.stderr)
    sys.stderr.flush()


def where_in_script(exc, script):
    """'line 57 of go.py': the script's last line in the traceback ('' if none)."""
    line = None
    for frame, lineno in traceback.walk_tb(exc.__traceback__):
        if os.path.abspath(frame.f_code.co_filename) == script:
            line = lineno
    return "" if line is None else "line %d of %s" % (line, os.path.basename(script))


def run(script, script_args):
    """Run the script; returns (outcome, detail, exit code)."""
    sys.argv = [script, *script_args]
    sys.path.insert(0, os.path.dirname(script))
    for signum in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, _raise_interrupted)
    signal.signal(signal.SIGINT, _raise_keyboard_interrupt)
    testbed_link.HANG_WATCH = True   # a step stuck in its own Fast DDS for good ends the process (run names it)
    if os.environ.get("MPLBACKEND", "").lower() == "agg":   # headless (./robotarium run chose it)
        skip_headless_idle_draws()
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit as exit_:
        code = exit_.code
        if code is not None and not isinstance(code, int):
            print(code, file=sys.stderr)   # sys.exit("message") prints it, as python does
            code = 1
        return None, "", code or 0
    except BaseException as exc:   # noqa: BLE001 - every way a script can end is reported
        if isinstance(exc, EndedByTestbed) and not isinstance(exc, EndedByUnsentRequest):
            pass   # the testbed's doing, not the script's: ./robotarium run's closing line says it, once
        elif isinstance(exc, (TestbedBusy, TestbedIncomplete)):   # the testbed's doing: one line
            print("[robotarium] %s" % exc, file=sys.stderr, flush=True)
        else:
            print_traceback(exc, script)
        step = session.robotaria[-1]._iterations if session.robotaria else 0
        if SIGINT_RECEIVED and not isinstance(exc, (KeyboardInterrupt, session.Interrupted, EndedByTestbed)):
            exc = KeyboardInterrupt().with_traceback(exc.__traceback__)   # what the SIGINT became in a C call
        if orphaned and isinstance(exc, KeyboardInterrupt):
            exc = session.Interrupted("the loss of ./robotarium run (its lifeline closed)")
        outcome, detail = session.failure_of(exc, step, where_in_script(exc, script))
        if isinstance(exc, (EndedByTestbed, TestbedBusy, TestbedIncomplete)):   # not a signal here: the testbed's doing
            code = outcomes.EXIT_CODES[outcomes.TESTBED_LOST]
        elif outcome == outcomes.INTERRUPTED:   # 128 + the signal, as a shell reports it
            code = 128 + getattr(signal, getattr(exc, "signal_name", "SIGINT"), signal.SIGKILL)
        else:
            code = outcomes.EXIT_CODES[outcome]
        return outcome, detail, code
    return None, "", 0


def finish(outcome, detail, code):
    """End every experiment still running, saying how; returns (outcome, detail, code, experiments)."""
    step = session.robotaria[-1]._iterations if session.robotaria else 0
    if outcome is None:   # the script's code ran to its end (or sys.exit)
        if not session.robotaria:
            outcome, detail = outcomes.NO_END, "the script never started an experiment (it made no Robotarium)"
        elif all(r.run_info is not None for r in session.robotaria):
            # ended by call_at_scripts_end() (completed), or at the time limit (TimeLimitReached)
            last = session.robotaria[-1].run_info
            outcome = {name: value for value, name in outcomes.NAMES.items()}.get(last.outcome, outcomes.COMPLETED)
            detail = last.detail
        elif code:
            outcome, detail = outcomes.SCRIPT_ERROR, "the script exited with status %s at step %d" % (code, step)
        else:
            outcome, detail = outcomes.NO_END, ("the script ended without calling r.call_at_scripts_end() "
                                                "(step %d)" % step)
        if outcome != outcomes.COMPLETED and not code:
            code = outcomes.EXIT_CODES[outcome]
    elif session.robotaria and all(r.run_info is not None and r.run_info.outcome == "completed"
                                   for r in session.robotaria):
        # Its experiments had completed (call_at_scripts_end) when the script failed or was stopped.
        outcome, detail = outcomes.COMPLETED, "then %s" % detail
    runs = []
    for robotarium in session.robotaria:
        if robotarium.run_info is None:
            try:
                robotarium._finish(outcome, detail)
            except EndedByUnsentRequest:
                pass   # ended already, by the request it names (the script's exception said so)
            except BaseException as error:   # noqa: BLE001 - a lost testbed cannot be told
                print("[robotarium] could not end the experiment on the testbed (%s)"
                      % session.describe_exception(error), file=sys.stderr)
        runs.append(robotarium.run_info or robotarium.partial_run_info())
    return outcome, detail, code, runs


def warm_up(namespace):
    """Import what every script's run needs: what `import rps.robotarium` brings but `rps` itself (its API is
    decided from the run's options, on its import); not pyplot, which only a script that plots needs (0.3 CPU-s
    more for every other one: bench wall_to_prompt, 2026-12-01), nor the 2.x API's modules."""
    import robotarium_client.robotarium  # noqa: F401 (numpy, rclpy, the client's session and link with it)
    # and DDS joined: the testbed's participants are found while `run` looks for the testbed, not in the
    # script's constructor (bench wall_to_prompt)
    testbed_link.join_dds_early(namespace)


def gated_arguments(namespace):
    """The run's arguments, once `run` opens the gate; None when it closed it without them. `namespace`: the
    testbed's, where its client joins DDS meanwhile."""
    warm_up(namespace)
    data = lifeline.read_start_gate()
    return None if data is None else json.loads(data)


def main(argv):
    if argv[:1] == ["--gated"] and len(argv) == 2:
        argv = gated_arguments(argv[1])
        if argv is None:
            testbed_link.leave_dds_early()
            return 0   # not wanted after all: nothing was run
    options_json, run_info_path, script, *script_args = argv
    folder = os.path.dirname(os.path.abspath(run_info_path))
    # Beside RUN_INFO_JSON: the log ./robotarium run keeps, and what is known of the experiment as soon
    # as it started (a script killed outright never writes RUN_INFO_JSON).
    session.run_files = {"log": os.path.join(folder, "log.txt"), "started": os.path.join(folder, STARTED)}
    lifeline.watch(_orphaned)
    # Room kept for run.json: a script that fills its disk (a job box's quota holds this folder) still has its
    # run recorded. Its own to give up: only its own record would suffer.
    reserve = os.path.join(folder, RESERVE)
    try:
        with open(reserve, "wb") as f:
            f.write(bytes(RESERVE_BYTES))
    except OSError:
        pass
    session.options = session.RunOptions.from_json(options_json)
    script = os.path.abspath(script)
    pid = os.getpid()
    outcome, detail, code = run(script, script_args)
    if os.getpid() != pid:
        # A process the script forked, whose copy of the script ended: the run and its experiment are the
        # script's own process's to end and record, not each fork's (a fork bomb's hundreds raced on run.json).
        os._exit(code)
    # Ending the experiment must not be cut short by a second Ctrl-C or signal.
    for signum in SIGNAL_EXIT:
        signal.signal(signum, signal.SIG_IGN)
    outcome, detail, code, runs = finish(outcome, detail, code)
    testbed_link.leave_dds_early()   # (a script that made no Robotarium)
    try:
        os.remove(reserve)   # its room is run.json's now
    except OSError:
        pass
    run_record.write(run_record.RunRecord(
        outcome=outcomes.NAMES[outcome], detail=detail, exit_code=code, experiments=runs,
        step_calls=session.robotaria[-1]._iterations if session.robotaria else 0), run_info_path)
    if testbed_link.DDS_STUCK:   # Python's exit would wait for the stuck Fast DDS for ever: the record is kept
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
