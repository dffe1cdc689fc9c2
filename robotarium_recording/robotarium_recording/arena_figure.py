"""The arena as the Robotarium draws it: the one drawer of the live figure (r.figure, r.axes), the
video of a run, the trajectory plot and the replay figure.

A robot is drawn as rps draws it (robotarium_abc.py): a gold square chassis of the robot's
diameter turned to its heading, two black wheels at the ends of the axle, a little behind the
centre, and two LEDs at the front. Here they are three matplotlib collections for all robots
instead of five patches per robot, so a frame of 50 robots costs a few draw calls. Sizes come
from the run's configuration (arena, robot diameter), scaled from rps's numbers for its 11 cm
robot. Ids (the video and the replay show them) are labels on the chassis.

Two layouts: `live()` is rps's figure (pyplot's default window, the arena filling it, no axes),
which scripts draw on; `offscreen()` is an Agg figure of a given pixel size for the video and
pictures, the same view of the arena with the axes filling a 16:10 frame.
"""
# matplotlib is imported inside the functions that draw: the modules that import this one (the
# client's drawing watcher, the drawing's reader) must not pay matplotlib's import for nothing.
import os

import numpy as np

CHASSIS_COLOUR = "#FFD700"
RPS_ROBOT_RADIUS = 0.055   # rps's wheel and LED offsets below are in metres for this robot
MARGIN = 0.1               # m of floor shown around the arena, as rps's figure does
ID_HEIGHT = 0.05           # m, height of a robot's id on its chassis
ROBOTS_ZORDER = 1          # the robots' zorder: patches', as rps's robots have


def pyplot():
    """matplotlib.pyplot, on the Agg backend when there is no display (and MPLBACKEND says nothing)."""
    import matplotlib
    if not os.environ.get("MPLBACKEND") and not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def is_interactive(plt):
    """True when pyplot draws on a screen (not Agg or a file backend)."""
    return plt.get_backend().lower() not in ("agg", "pdf", "svg", "ps", "cairo", "template")


def robot_colours(n):
    """n RGBA colours, distinct for up to 60 robots (tab10, tab20, then tab20 + tab20b + tab20c)."""
    import matplotlib
    if n <= 10:
        names = ["tab10"]
    elif n <= 20:
        names = ["tab20"]
    else:
        names = ["tab20", "tab20b", "tab20c"]
    palette = np.vstack([matplotlib.colormaps[name].colors for name in names])
    if len(names) > 1:   # interleave so that neighbouring ids differ in hue, not only in shade
        palette = palette.reshape(len(names), 20, 3).transpose(1, 0, 2).reshape(-1, 3)
    rgb = palette[np.arange(n) % len(palette)]
    return np.column_stack((rgb, np.ones(n)))


def points_per_metre(axes):
    """How many typographic points one metre of the arena spans on `axes` now (marker and font
    sizes of a script are in points, computed for its own figure's scale)."""
    return float(axes.transData.get_matrix()[0, 0]) * 72.0 / axes.figure.dpi


def robot_geometry(poses, robot_radius):
    """Chassis corners (N, 4, 2), wheel centres (2N, 2) and LED centres (2N, 2) at `poses` (3 x N),
    with rps's offsets scaled to this robot radius."""
    x, y, theta = (np.asarray(row, dtype=float) for row in poses)
    k = robot_radius / RPS_ROBOT_RADIUS
    centre = np.column_stack((x, y))
    forward = np.column_stack((np.cos(theta), np.sin(theta)))
    side = np.column_stack((-forward[:, 1], forward[:, 0]))   # to the robot's left
    r = robot_radius
    corners = np.stack([centre + r * (a * forward + b * side) for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1))],
                       axis=1)
    back = centre - 0.04 * k * forward
    wheels = np.vstack((back + r * side, back - r * side))
    front = centre + 0.75 * r * forward
    leds = np.vstack((front - 0.04 * k * side, front - 0.015 * k * side))
    return corners, wheels, leds


class ArenaFigure:
    """The arena with N robots on `figure`/`axes`; update(poses) moves them (cheap: no redraw)."""

    def __init__(self, figure, axes, arena, robot_radius, poses, ids=False):
        from matplotlib.collections import EllipseCollection, PolyCollection
        from matplotlib.patches import Rectangle

        self.figure, self.axes = figure, axes
        self.arena = tuple(float(v) for v in arena)
        self.robot_radius = float(robot_radius)
        poses = np.asarray(poses, dtype=float)
        self.number_of_robots = n = poses.shape[1]
        x0, x1, y0, y1 = self.arena
        axes.set_axis_off()
        axes.set_xlim(x0 - MARGIN, x1 + MARGIN)
        axes.set_ylim(y0 - MARGIN, y1 + MARGIN)
        k = self.robot_radius / RPS_ROBOT_RADIUS
        wheel = np.full(2 * n, 2 * 0.02 * k)
        led = np.full(2 * n, 2 * self.robot_radius / 5)
        self.wheels = EllipseCollection(wheel, wheel, np.zeros(2 * n), units="xy", offsets=np.zeros((2 * n, 2)),
                                        offset_transform=axes.transData, facecolors="k", edgecolors="k",
                                        linewidths=1.0)
        self.chassis = PolyCollection(np.zeros((n, 4, 2)), facecolors=CHASSIS_COLOUR, edgecolors="k", linewidths=1.0)
        self.leds = EllipseCollection(led, led, np.zeros(2 * n), units="xy", offsets=np.zeros((2 * n, 2)),
                                      offset_transform=axes.transData, facecolors="none", edgecolors="k",
                                      linewidths=1.0)
        for collection in (self.wheels, self.chassis, self.leds):
            collection.set_zorder(ROBOTS_ZORDER)
            axes.add_collection(collection, autolim=False)
        self.boundary = axes.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False))
        self.own_artists = {self.wheels, self.chassis, self.leds, self.boundary}
        self.ids = None
        if ids:
            # The ids as glyph outlines in one collection (a text artist per robot would cost
            # half a millisecond each per frame): paths in points, placed at the robots' centres.
            from matplotlib.collections import PathCollection
            from matplotlib.textpath import TextPath
            from matplotlib.transforms import Affine2D
            paths = []
            for i in range(n):
                path = TextPath((0, 0), str(i), size=1.0)
                (a, b), (c, d) = path.get_extents().get_points()
                paths.append(path.transformed(Affine2D().translate(-(a + c) / 2, -(b + d) / 2)))
            self.ids = PathCollection(paths, offsets=np.zeros((n, 2)), offset_transform=axes.transData,
                                      facecolors="k", edgecolors="none", zorder=ROBOTS_ZORDER + 0.01)
            axes.add_collection(self.ids, autolim=False)
            self.own_artists.add(self.ids)
        self.label = None
        self.interactive = False   # set by whoever shows it on a screen
        self.poses = poses
        self.update(poses)

    # -- the two layouts -----------------------------------------------------------------------------

    @classmethod
    def live(cls, arena, robot_radius, poses, plt=None, ids=False):
        """rps's figure: pyplot's default window with the arena filling it (r.figure, r.axes)."""
        if plt is None:
            import matplotlib.pyplot as plt
        figure, axes = plt.subplots()
        self = cls(figure, axes, arena, robot_radius, poses, ids=ids)
        axes.set_aspect("equal")
        plt.subplots_adjust(left=-0.03, right=1.03, bottom=-0.03, top=1.03, wspace=0, hspace=0)
        self.size_ids()
        return self

    @classmethod
    def offscreen(cls, arena, robot_radius, poses, width=1280, height=800, dpi=200, ids=True):
        """An Agg figure of width x height pixels (no pyplot: nothing to close, no window)."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        figure = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        FigureCanvasAgg(figure)
        return cls._framed(figure, arena, robot_radius, poses, ids)

    @classmethod
    def window(cls, arena, robot_radius, poses, plt, ids=True, title=""):
        """A pyplot window in the video's layout (the replay figure)."""
        figure = plt.figure(figsize=(9.6, 6.0), num=title or None)
        return cls._framed(figure, arena, robot_radius, poses, ids)

    @classmethod
    def _framed(cls, figure, arena, robot_radius, poses, ids):
        """The arena and its margin centred in the whole figure, the view widened along one
        axis to the figure's shape."""
        axes = figure.add_axes((0, 0, 1, 1))
        self = cls(figure, axes, arena, robot_radius, poses, ids=ids)
        width, height = figure.get_size_inches()
        x0, x1, y0, y1 = self.arena
        w, h = x1 - x0 + 2 * MARGIN, y1 - y0 + 2 * MARGIN
        w, h = max(w, h * width / height), max(h, w * height / width)
        axes.set_xlim((x0 + x1 - w) / 2, (x0 + x1 + w) / 2)
        axes.set_ylim((y0 + y1 - h) / 2, (y0 + y1 + h) / 2)
        axes.set_aspect("equal")
        self.size_ids()
        return self

    # -- drawing -------------------------------------------------------------------------------------

    def draw_obstacles(self, obstacles):
        """A 2.x experiment's line-segment walls (M x 2 x 2), as 2.x draws them: thick grey lines
        below the robots."""
        from matplotlib.collections import LineCollection
        segments = np.asarray(obstacles, dtype=float).reshape(-1, 2, 2)
        if len(segments):
            walls = LineCollection(segments, colors="0.5", linewidths=4, zorder=ROBOTS_ZORDER - 0.5)
            self.axes.add_collection(walls, autolim=False)
            self.own_artists.add(walls)

    def size_ids(self):
        """Ids ID_HEIGHT tall at the figure's present scale (digits are about 0.73 em tall)."""
        if self.ids is not None:
            from matplotlib.transforms import Affine2D
            self.axes.apply_aspect()
            em = ID_HEIGHT / 0.73 * points_per_metre(self.axes)
            self.ids.set_transform(Affine2D().scale(em * self.figure.dpi / 72.0))

    def update(self, poses):
        """Move every robot to `poses` (3 x N)."""
        self.poses = poses = np.asarray(poses, dtype=float)
        corners, wheels, leds = robot_geometry(poses, self.robot_radius)
        self.chassis.set_verts(corners)
        self.wheels.set_offsets(wheels)
        self.leds.set_offsets(leds)
        if self.ids is not None:
            self.ids.set_offsets(poses[:2].T)

    def set_label(self, text):
        """A line of text in the frame's lower left corner (time and step of a video frame)."""
        if self.label is None:
            self.label = self.figure.text(0.005, 0.005, "", ha="left", va="bottom", family="monospace",
                                          fontsize=6, color="0.25")
        self.label.set_text(text)

    def frame(self):
        """Render (Agg) and return the RGBA pixels."""
        canvas = self.figure.canvas
        canvas.draw()
        return canvas.buffer_rgba()

    def show(self):
        """Redraw an on-screen figure now (no-op headless)."""
        canvas = self.figure.canvas
        canvas.draw_idle()
        canvas.flush_events()
