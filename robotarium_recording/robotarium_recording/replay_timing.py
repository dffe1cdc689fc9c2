"""A replay's time, without ROS: when each recorded message is due (ReplayClock: rate, pause and
resume) and a lockstep run's messages moved to experiment time (experiment_times)."""
import numpy as np


class ReplayClock:
    """Maps recorded times (ns) to wall-clock deadlines (time.monotonic), with pause and rate."""

    def __init__(self, rate=1.0):
        if not rate > 0:
            raise ValueError("rate must be > 0; received %r" % rate)
        self.rate = rate
        self.origin = None
        self.first_ns = 0
        self.paused_at = None

    def start(self, first_ns, now):
        self.first_ns, self.origin = first_ns, now
        if self.paused_at is not None:
            self.paused_at = now

    def deadline(self, log_ns):
        return self.origin + (log_ns - self.first_ns) * 1e-9 / self.rate

    @property
    def paused(self):
        return self.paused_at is not None

    def pause(self, now):
        if self.paused_at is None:
            self.paused_at = now

    def resume(self, now):
        if self.paused_at is not None:
            self.origin += now - self.paused_at   # the paused time does not count
            self.paused_at = None


def experiment_times(bag, log_times):
    """The messages' recorded times (ns) moved to experiment time: each poses message at its step
    times the time step, the others in between by linear interpolation. A lockstep run is recorded
    as fast as it ran; replayed this way it plays as its video does, step by step in real time."""
    track = bag.poses()
    if len(track.steps) < 2:
        return list(log_times)
    order = np.argsort(track.log_ns, kind="stable")
    recorded = track.log_ns[order].astype(float)
    experiment = track.log_ns[order][0] + track.steps[order] * bag.config().time_step * 1e9
    keep = np.concatenate(([True], np.diff(recorded) > 0))   # np.interp needs increasing abscissae
    return np.interp(np.asarray(log_times, dtype=float), recorded[keep], experiment[keep]).astype(np.int64).tolist()
