"""How a run ended. Plain Python.

The numbers are TestbedStatus.OUTCOME_* (robotarium_msgs; robotarium_core/test/test_outcomes.py checks that they
agree): the simulator keeps the outcome an end_experiment request gives in the IDLE status that
closes the run, so the recording itself says how the run ended. One more has no message value,
because only the report can tell it: a recording that ends while its experiment was still running.
"""
import errno
import re

NONE, COMPLETED, SCRIPT_ERROR, INTERRUPTED, NO_END, TIME_LIMIT, CLIENT_LOST, TESTBED_LOST = range(8)
UNFINISHED = 100     # the recording ends while the experiment was still running
TESTBED_BUSY = 101   # the experiment never started: the testbed was busy and the client would not wait (--no-wait)
TESTBED_INCOMPLETE = 102   # the experiment never started: the testbed has no safety node (nothing could move)
# An end request with the run's token that its script did not send (a process that copied the token
# off the wire: without SROS2 it is no secret). Only the client can tell: to the testbed it is its client's.
ENDED_BY_UNSENT_REQUEST = 103

# Short names (run.json's "outcome") and what each means, for people.
NAMES = {COMPLETED: "completed", SCRIPT_ERROR: "script_error", INTERRUPTED: "interrupted", NO_END: "no_end",
         TIME_LIMIT: "time_limit", CLIENT_LOST: "client_lost", TESTBED_LOST: "testbed_lost",
         UNFINISHED: "unfinished", TESTBED_BUSY: "testbed_busy",
         TESTBED_INCOMPLETE: "testbed_incomplete", ENDED_BY_UNSENT_REQUEST: "ended_by_unsent_request"}
PHRASES = {
    COMPLETED: "completed: the script called call_at_scripts_end()",
    SCRIPT_ERROR: "the script raised an exception",
    INTERRUPTED: "interrupted",
    NO_END: "the script ended without calling call_at_scripts_end()",
    TIME_LIMIT: "stopped at the time limit",
    CLIENT_LOST: "the testbed ended it: its client went away",
    TESTBED_LOST: "the testbed was lost",
    UNFINISHED: "the recording ends while the experiment was still running (its client or the testbed went away)",
    TESTBED_BUSY: "the testbed was busy with another experiment",
    TESTBED_INCOMPLETE: "the testbed is incomplete: no safety node answers",
    ENDED_BY_UNSENT_REQUEST: "the experiment was ended by an end request this script did not send (a process holding "
                             "its token)",
}

# Exit codes of `./robotarium run` (README): 0 only for a completed run. An interrupted run exits
# with 128 + the signal's number, as a shell reports it (130 for Ctrl-C); EXIT_CODES has SIGINT's.
EXIT_CODES = {COMPLETED: 0, SCRIPT_ERROR: 1, NO_END: 3, TESTBED_LOST: 4, CLIENT_LOST: 4, UNFINISHED: 4,
              TESTBED_BUSY: 4, TESTBED_INCOMPLETE: 4, ENDED_BY_UNSENT_REQUEST: 4, TIME_LIMIT: 5, INTERRUPTED: 130}
USAGE_ERROR = 2   # the command line itself was wrong (no such script, a bad option)
# Exit codes of `./robotarium verify` (README): 0 the script is accepted, VERIFY_REJECTED it is
# rejected (a rule is broken: --json names each), USAGE_ERROR a bad command line, TESTBED_PROBLEM
# the testbed failed so there is no verdict, 128 + N interrupted by signal N.
VERIFY_ACCEPTED = 0
VERIFY_REJECTED = 6
TESTBED_PROBLEM = 4   # = EXIT_CODES[TESTBED_LOST]


def of_request(outcome):
    """The outcome an end_experiment request means (an empty request: the script completed)."""
    return COMPLETED if outcome == NONE else int(outcome)


def first_line(outcome, detail=""):
    """The report's first line: how the run ended."""
    if outcome == COMPLETED:
        return "Run completed%s." % (": " + detail if detail else "")
    if outcome == TIME_LIMIT and detail:   # the client's note says it all: "Stopped at the time limit: ..."
        return detail
    return "Run did not complete: %s." % (detail or PHRASES.get(outcome, "unknown outcome %s" % outcome)).rstrip(".")


def unsent_end(step):
    """What ended a run whose experiment an end request with its token ended at `step`, that its
    script did not send (ENDED_BY_UNSENT_REQUEST)."""
    return ("the experiment was ended at step %d by an end request this script did not send (a process holding "
            "its token)" % step)


def step_of_end_reason(end_reason, default=0):
    """The step in the simulator's end_reason ("ended by its client at step 115"), else `default`."""
    found = re.search(r"at step (\d+)", end_reason or "")
    return int(found.group(1)) if found else default


ENDED_BY_ITS_CLIENT = "ended by its client"   # the simulator's end_reason for an end request with the token


ENDED_BY_TESTBED = "The experiment was ended by the testbed: "   # the client's words for a run the testbed ended
ENDED_BY_ITS_USER = "ended by its user"   # ./robotarium end by the user who runs the experiment (end_reason)
RECORDER_GONE = "the recorder is gone"   # why a recording stopped, when its recorder is lost
NO_TESTBED_ANSWERS = "No Robotarium testbed answers"   # how the client's error begins when none answered it
RECORDER_RESTARTED = "the recorder was restarted"   # ... when it was restarted mid-run (robotarium_core.restarts)
# how ./robotarium run names the end of a script whose step() stayed stuck in a call into its own Fast DDS until
# the kernel's timer ended its process (robotarium_client.testbed_link.HUNG_STEP)
OWN_DDS_HUNG = ("This script's own Fast DDS stopped: its step() stayed stuck in a call into Fast DDS that never came "
                "back (a deadlock inside Fast DDS, docs/faults.md; nothing of Python can run then), and its process "
                "was ended")
DISK_FULL = "disk full"   # ... when its disk took no more (the recorder's write, or the results beside the bag)


def disk_full(error):
    """Whether `error` (an exception) is a write refused for want of room: no space, or over a disk quota."""
    return isinstance(error, OSError) and error.errno in (errno.ENOSPC, errno.EDQUOT)


def recorder_lost(because):
    """Whether a recording stopped because its recorder went (gone, or restarted: the bag it wrote is left
    as it was, closed by nobody), rather than for an error the recorder named (a full disk)."""
    return because == RECORDER_GONE or str(because or "").startswith(RECORDER_RESTARTED)


def recording_stopped(run):
    """"recording stopped at step k: why" when the recording of a run (a run_record.RunRecord) ended
    before the run (the recorder gone, a full disk), else ""."""
    step = getattr(run, "recording_stopped_at_step", None)
    if step is None:
        return ""
    return "recording stopped at step %d: %s" % (step, run.recording_stopped_because or RECORDER_GONE)


def with_recording_stopped(first_line, stopped):
    """A report's first line with how its recording stopped early (`stopped`: recording_stopped's words) after it."""
    return "%s %s%s: the recording is incomplete." % (first_line, stopped[0].upper(), stopped[1:])


def lost_poses(count, first_step):
    """What a report says of a recording missing the poses of `count` steps (a gap in the bag's step
    sequence), the first of them `first_step`."""
    return ("the recording is incomplete: poses of %d step(s) are missing from the bag (first: step %d)"
            % (count, first_step))


def run_notes(run):
    """What the report adds about a run beyond its recording (a run_record.RunRecord, or None): a
    recording that stopped early, a safety node restarted mid-run, data files left out of the run folder."""
    notes = []
    if recording_stopped(run):
        notes.append("%s. The recording is incomplete, so there is no acceptance estimate." % recording_stopped(run))
    for restart in getattr(run, "safety_restarts", None) or ():
        notes.append("%s (the robots stood still meanwhile%s)." % (
            restart, "" if getattr(run, "real_time", True) else "; in lockstep the run waited, so its steps are "
            "those of an uninterrupted run"))
    for name, why in sorted((getattr(run, "data_not_saved", None) or {}).items()):
        notes.append("data file %s not saved in the run folder: %s" % (name, why))
    return notes
