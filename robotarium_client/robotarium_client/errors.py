"""What a Robotarium client raises when its experiment cannot go on for a reason that is not the
script's: the testbed lost, busy, incomplete, or ending the run itself; and the time limit.

In a module of their own (robotarium_client.robotarium re-exports them), so that the session and
the runner, which name a run's outcome after them, need not import the client.
"""
from robotarium_core import outcomes

EXIT_TIME_LIMIT = 5   # exit code of a script stopped at the time limit (README: exit codes)


class TestbedLost(RuntimeError):
    """The testbed stopped answering in the middle of an experiment (a node gone, no poses)."""
    __test__ = False  # not a pytest class


class NodeRestarted(TestbedLost):
    """A node of the testbed that the experiment needs (the simulator, the safety node) was restarted mid-run (by
    ./robotarium up, or in place after its DDS stalled): the run's state on it is gone. Its message is the run's
    cause, "testbed node restarted at step k: ..." (robotarium_core.restarts.ended_run); or "the testbed stopped at
    step k: ..." where a node kept exiting and up gave up on it."""


class TestbedBusy(RuntimeError):
    """The testbed is busy with another experiment and this client would not wait (--no-wait)."""


class TestbedIncomplete(RuntimeError):
    """The testbed answers but lacks a node an experiment needs (no safety node: nothing could move)."""


class EndedByTestbed(RuntimeError):
    """The testbed ended the experiment (an operator's ./robotarium end --force, a stopped testbed)."""


class EndedByUnsentRequest(EndedByTestbed):
    """An end request with this run's token that this script did not send ended the experiment: a
    process that copied the token off the wire (without SROS2 it is no secret). Never "completed"."""

    def __init__(self, step):
        super().__init__(
            "%s. Stop the process that sends it (./robotarium status lists what runs on the domain), or run the "
            "testbed with DDS Security (sros2/README.md) so that no other process learns the token; then run the "
            "script again." % ("T" + outcomes.unsent_end(step)[1:]))
        self.step = step


class TimeLimitReached(SystemExit):
    """Raised by step() once the experiment reached its time limit (testbed configuration
    `time_limit`, or ./robotarium run --time-limit): the experiment has been ended and its report
    printed; the rest of the script does not run. A SystemExit, so that `except Exception` in a
    script's loop does not keep it going; the process exits with EXIT_TIME_LIMIT."""

    def __init__(self, message):
        super().__init__(EXIT_TIME_LIMIT)
        self.message = message
