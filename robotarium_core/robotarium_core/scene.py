"""What a viewer draws of the testbed: the arena, each robot (footprint, heading, id) and its recent
trail. Plain numpy: the simulator's `markers` topic (robotarium_core.markers) and the Foxglove view
of a live or recorded run (robotarium_recording.foxglove_scene) draw the same geometry from it.

Everything is in the `arena` frame (metres, the poses' frame); z is up, the arena floor at z = 0.
"""
import numpy as np

# One colour per robot (RGB, 0..1), repeating after ten: matplotlib's tab10, as the trajectory plot.
PALETTE = np.array([
    (0.122, 0.467, 0.706), (1.000, 0.498, 0.055), (0.173, 0.627, 0.173), (0.839, 0.153, 0.157),
    (0.580, 0.404, 0.741), (0.549, 0.337, 0.294), (0.890, 0.467, 0.761), (0.498, 0.498, 0.498),
    (0.737, 0.741, 0.133), (0.090, 0.745, 0.812)])

TRAIL_POINTS = 60   # points kept per robot trail, however long it is


def robot_colours(n):
    """n x 3 RGB colours, robot i in PALETTE[i % 10]."""
    return PALETTE[np.arange(n) % len(PALETTE)]


def arena_outline(arena):
    """The arena's border as a closed polyline: 5 x 2 corner points, the first repeated."""
    x_min, x_max, y_min, y_max = arena
    return np.array([[x_min, y_min], [x_max, y_min], [x_max, y_max], [x_min, y_max], [x_min, y_min]], dtype=float)


def headings(poses, length):
    """Segments from each robot's centre `length` ahead along its heading: N x 2 x 2 (robot, end, xy)."""
    poses = np.asarray(poses, dtype=float)
    centres = poses[:2].T
    tips = centres + length * np.stack((np.cos(poses[2]), np.sin(poses[2])), axis=1)
    return np.stack((centres, tips), axis=1)


class Trails:
    """The recent path of every robot: the last `seconds` of testbed time, at most TRAIL_POINTS
    points each (one every `every` steps), always ending at the newest pose. A run with another
    number of robots, or a step number that goes back (a new run), starts them afresh."""

    def __init__(self, seconds, time_step, points=TRAIL_POINTS):
        steps = max(1, int(round(seconds / time_step)))
        self.every = max(1, -(-steps // points))   # ceil: at most `points` kept points
        self.points = max(1, steps // self.every)
        self._kept = None       # points x 2 x N ring of kept positions
        self._count = 0         # kept positions so far (<= points used)
        self._next = 0          # ring index of the next kept position
        self._newest = None     # 2 x N, the latest pose, kept or not
        self._step = None

    def reset(self):
        self._kept, self._count, self._next, self._newest, self._step = None, 0, 0, None, None

    def add(self, step, poses):
        """The poses (3 x N, or 2 x N) of testbed step `step`."""
        xy = np.asarray(poses, dtype=float)[:2]
        if self._kept is None or self._kept.shape[2] != xy.shape[1] or (self._step is not None and step < self._step):
            self._kept = np.empty((self.points, 2, xy.shape[1]))
            self._count = self._next = 0
        if step % self.every == 0 or self._count == 0:
            self._kept[self._next] = xy
            self._next = (self._next + 1) % self.points
            self._count = min(self._count + 1, self.points)
        self._newest, self._step = xy.copy(), step

    def paths(self):
        """Each robot's trail, oldest first: a list of k x 2 arrays (k >= 1), or [] before any pose."""
        if self._newest is None:
            return []
        order = (np.arange(self._count) + (self._next - self._count)) % self.points
        kept = self._kept[order]                           # k x 2 x N
        if not np.array_equal(kept[-1], self._newest):
            kept = np.concatenate((kept, self._newest[None]), axis=0)
        return [kept[:, :, i] for i in range(kept.shape[2])]
