"""Progress lines for long runs: `[robotarium] step 1500: 49.5 s of testbed time in 12 s (125 steps/s, lockstep)`."""
import sys
import time

LINE_START = "[robotarium] step "   # how every progress line begins: ./robotarium run keeps them out of log.txt


class StepProgress:
    """Prints a line to stderr at most every `interval` seconds of wall time (0: never)."""

    def __init__(self, interval, time_step, mode):
        self.interval, self.time_step, self.mode = interval, time_step, mode
        self._started = self._next = None

    def __call__(self, steps):
        if not self.interval:
            return
        now = time.monotonic()
        if self._started is None:
            self._started, self._next = now, now + self.interval
        elif now >= self._next:
            self._next = now + self.interval
            elapsed = now - self._started
            print(LINE_START + "%d: %.1f s of testbed time in %.0f s (%.0f steps/s, %s)" % (
                steps, steps * self.time_step, elapsed, (steps - 1) / elapsed, self.mode), file=sys.stderr, flush=True)
