"""What every robotarium command shares: its messages, the signals it stops on, argument types."""
import argparse
import os
import signal
import sys
import threading

# Seconds a script has, after the first signal, to end its experiment before it is killed.
SCRIPT_GRACE = 5.0
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def say(text):
    print("[robotarium] %s" % text, file=sys.stderr, flush=True)


def shown(path):
    """A path as short as it is clear: relative when it lies below the working folder."""
    relative = os.path.relpath(path)
    return path if relative.startswith("..") else relative


def signal_group(process, sig):
    """Signal the process group of a child started with process_group=0, unless it was reaped."""
    if process.poll() is None:
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            pass


class Interruption:
    """SIGINT, SIGTERM and SIGHUP, caught while installed: the first is remembered and forwarded
    to the script (watch()), once (the runner then ends its experiment saying how); a script
    still running SCRIPT_GRACE seconds later, or at a second signal, is killed. The command then
    stops what it started as after any run."""

    def __init__(self):
        self.signum = None
        self.count = 0
        self.script = None
        self._timer = None
        self._previous = {sig: signal.signal(sig, self._on_signal) for sig in STOP_SIGNALS}

    @property
    def name(self):
        return signal.Signals(self.signum).name if self.signum else ""

    @property
    def exit_code(self):
        """128 + the signal's number, as a shell reports a command a signal stopped (130: Ctrl-C)."""
        return 128 + self.signum

    def _on_signal(self, signum, frame):
        self.count += 1
        if self.signum is None:
            self.signum = signum
        self._forward()

    def watch(self, process):
        """Forward signals to this script (started with process_group=0)."""
        self.script = process
        if self.signum is not None:
            self._forward()

    def _forward(self):
        process = self.script
        if process is None or process.poll() is not None:
            return
        if self.count > 1:
            signal_group(process, signal.SIGKILL)
        elif self._timer is None:
            signal_group(process, self.signum)   # the runner names it in the report (SIGINT: Ctrl-C)
            self._timer = threading.Timer(SCRIPT_GRACE, signal_group, (process, signal.SIGKILL))
            self._timer.daemon = True
            self._timer.start()

    def restore(self):
        if self._timer is not None:
            self._timer.cancel()
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)


def seed_type(text):
    """--seed: a whole number 0 .. 2**32 - 1 (the StartExperiment request's uint32)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError("must be a whole number; received %r" % text) from None
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError("must be between 0 and %d; received %d" % (2**32 - 1, value))
    return value


def positive_int(text):
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError("expected a whole number >= 1, got %r" % text)
    return value


def seconds(text):
    """A command-line number of seconds: finite and not negative."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError("expected a number of seconds >= 0, got %r" % text)
    return value


def error(message):
    """A bad argument found after parsing (ros2 robotarium parsed them): said, exit code 2."""
    say("error: " + message)
    raise SystemExit(2)
