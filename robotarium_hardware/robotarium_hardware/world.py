"""The simulated fleet's world: where each robot's body really is, in one small shared-memory file.

Each robot process writes its own body's true pose and speed there (its row, nobody else's) as its
wheel model advances; the motion-capture and camera stand-ins look at the bodies through it, as a
real tracking system looks at the floor, and tests and benchmarks read the truth to measure what the
arena did. A robot whose process was killed leaves its body where it stood, as a real one would.
Everything the robots, the stand-ins and the arena tell each other goes over DDS, as between machines.

Row i: [stamp (s, time.time()), x, y, theta, v, omega, sequence]; a writer makes the sequence odd while it
writes and even after (a seqlock), so a reader never takes half of an update. Plain numpy, no ROS.
"""
import os
import time

import numpy as np

FIELDS = ("stamp", "x", "y", "theta", "v", "omega", "sequence")
STAMP, X, Y, THETA, V, OMEGA, SEQUENCE = range(len(FIELDS))


class World:
    """The world file of `size` robots at `path` (created with create=True: all rows unset)."""

    def __init__(self, path, size=None, create=False):
        self.path = path
        if create:
            rows = np.zeros((size, len(FIELDS)))
            rows[:, STAMP] = np.nan
            rows.tofile(path)
        count = os.path.getsize(path) // (8 * len(FIELDS))
        self.rows = np.memmap(path, dtype=np.float64, mode="r+", shape=(count, len(FIELDS)))
        self.size = count

    def write(self, i, x, y, theta, v, omega, stamp=None):
        row = self.rows[i]
        sequence = row[SEQUENCE] + 1
        row[SEQUENCE] = sequence          # odd: writing
        row[STAMP:SEQUENCE] = (time.time() if stamp is None else stamp, x, y, theta, v, omega)
        row[SEQUENCE] = sequence + 1      # even: done

    def read(self):
        """size x 6 (stamp, x, y, theta, v, omega), each row whole (NaN stamp: not placed yet)."""
        for _ in range(100):
            before = self.rows[:, SEQUENCE].copy()
            values = np.array(self.rows[:, :SEQUENCE])
            if np.all(before == self.rows[:, SEQUENCE]) and not np.any(before % 2):
                return values
        return values   # a writer kept writing: the values of the last try (each field whole)

    def poses_at(self, when=None):
        """3 x size poses extrapolated to `when` (time.time(); default now) along each body's arc
        since its last update (a robot writes every 10 ms; a tracker samples in between)."""
        rows = self.read()
        when = time.time() if when is None else when
        dt = np.clip(when - rows[:, STAMP], 0.0, 0.05)
        dt = np.where(np.isfinite(dt), dt, 0.0)
        theta = rows[:, THETA] + rows[:, OMEGA] * dt
        middle = rows[:, THETA] + rows[:, OMEGA] * dt / 2
        return np.array([rows[:, X] + rows[:, V] * dt * np.cos(middle), rows[:, Y] + rows[:, V] * dt * np.sin(middle),
                         np.arctan2(np.sin(theta), np.cos(theta))])

    def placed(self):
        return np.isfinite(self.read()[:, STAMP])
