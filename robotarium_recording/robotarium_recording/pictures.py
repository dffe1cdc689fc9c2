"""The pictures of a recorded run: its video and its trajectory plot, from the bag alone.

The video is the Robotarium's video of a run: the arena as the live figure draws it
(arena_figure.ArenaFigure, robots with their ids) with everything the script drew on r.axes at
each step (drawing.py), one frame per step in experiment time (a frame every time step, played
at 1 / time_step frames a second), 1280 x 800, H.264 (ffmpeg of the imageio-ffmpeg wheel), or a
GIF with Pillow when no encoder is found. Frames are piped to ffmpeg as raw pixels, so rendering
and encoding run side by side; x264's "veryfast" preset (measured: a sixth of "ultrafast"'s file
for 10 % more time, since the encoder waits for frames anyway).

The trajectory plot shows every robot's path in its own colour (distinct for up to 60 robots),
where it started (an open circle with its id) and where it ended (the robot drawn with its id),
over what the script drew, faded.
"""
import fractions
import os
import subprocess
import sys

import numpy as np

from robotarium_recording.arena_figure import ROBOTS_ZORDER, ArenaFigure, robot_colours
from robotarium_recording.drawing import DrawingPainter, DrawingState

VIDEO_SIZE = (1280, 800)
VIDEO_DPI = 200
PLOT_SIZE = (1600, 1000)
PLOT_DPI = 160


def ffmpeg_path():
    """ffmpeg of the imageio-ffmpeg wheel, else one on PATH, else None."""
    try:
        import imageio_ffmpeg
        return imageio_ffmpeg.get_ffmpeg_exe()
    except Exception:   # no wheel, or no binary for this platform
        from shutil import which
        return which("ffmpeg")


def frame_rate(time_step):
    """Frames per second for one frame per step in experiment time, as ffmpeg's fraction ("1000/33")."""
    rate = fractions.Fraction(1 / time_step).limit_denominator(1000)
    return "%d/%d" % (rate.numerator, rate.denominator)


class Frames:
    """The frames of a run: for each step from the first to the last recorded one, the robots'
    poses (the newest recorded at or before it) and the script's drawing as it was then."""

    def __init__(self, track, drawings, config, title="", stride=1):
        self.track, self.config, self.title, self.stride = track, config, title, stride
        self.drawings = sorted(drawings, key=lambda m: m.get("step", 0))   # stable: keeps recorded order
        first, last = (int(track.steps[0]), int(track.steps[-1])) if len(track.steps) else (0, -1)
        self.steps = np.arange(first, last + 1, stride)

    def __len__(self):
        return len(self.steps)

    def render(self, arena_figure, painter=None):
        """Yield (index, step, background_changed) after putting each frame on `arena_figure` (and
        its drawing on `painter`); background_changed: something of the drawing below the robots
        changed (see Blitter)."""
        track, state, d = self.track, DrawingState(), 0
        row = 0
        for index, step in enumerate(self.steps):
            while row + 1 < len(track.steps) and track.steps[row + 1] <= step:
                row += 1
            arena_figure.update(np.vstack((track.x[row], track.y[row], track.theta[row])))
            changed = False
            while d < len(self.drawings) and self.drawings[d].get("step", 0) <= step:
                state.apply(self.drawings[d])
                d += 1
                changed = True
            below = False
            if painter is not None and changed:
                made, removed = painter.paint(state)
                below = any(z < ROBOTS_ZORDER for z in removed) or any(a.get_zorder() < ROBOTS_ZORDER for a in made)
            arena_figure.set_label("%s   t = %7.2f s   step %5d" % (self.title, step * self.config.time_step, step))
            yield index, step, below


class Blitter:
    """Frames drawn the fast way: what lies below the robots (the arena, a goal marker, a label
    at a lower zorder, a background image) is rendered once into a background and drawn again
    only when it changed; each frame restores it and draws the robots, their ids, the label and
    what the script drew above them."""

    def __init__(self, arena_figure, painter):
        self.arena_figure, self.painter = arena_figure, painter
        self.background = None

    def frame(self, background_changed):
        af = self.arena_figure
        figure, canvas = af.figure, af.figure.canvas
        above = [a for _, a in self.painter.artists.values() if a.get_zorder() >= ROBOTS_ZORDER]
        dynamic = [a for a in (af.wheels, af.chassis, af.leds, af.ids, af.label) if a is not None] + above
        for artist in dynamic:
            artist.set_animated(True)   # left out of canvas.draw(): the background
        if self.background is None or background_changed:
            canvas.draw()
            self.background = canvas.copy_from_bbox(figure.bbox)
        else:
            canvas.restore_region(self.background)
        for artist in sorted(dynamic, key=lambda a: a.get_zorder()):   # stable: robots before equal zorders
            figure.draw_artist(artist)
        return canvas.buffer_rgba()


class Progress:
    """'rendering run.mp4:  45% (2250 of 5000 frames)' on stderr: every 5 % on one line on a
    terminal, every 25 % on lines of their own elsewhere (a log)."""

    def __init__(self, name, total, enabled=True):
        self.name, self.total, self.enabled, self.shown = name, max(total, 1), enabled, -1
        self.terminal = sys.stderr.isatty()
        self.every = 5 if self.terminal else 25

    def __call__(self, done):
        percent = 100 * done // self.total
        if self.enabled and percent // self.every != self.shown // self.every:
            self.shown = percent
            print("%srendering %s: %3d%% (%d of %d frames)" % ("\r" if self.terminal else "", self.name, percent,
                                                              done, self.total),
                  end="" if self.terminal else "\n", file=sys.stderr, flush=True)

    def close(self):
        if self.enabled and self.terminal:
            print(file=sys.stderr, flush=True)


def render_video(track, drawings, config, out_dir, title="", progress=True, fmt=None, name="run", obstacles=()):
    """<out_dir>/<name>.mp4 (or .gif when fmt="gif" or no ffmpeg): one frame per step; a GIF has
    every other step at half the rate; `obstacles`: a 2.x experiment's walls. Returns the path, or
    None when there is nothing to show."""
    if not len(track.steps):
        return None
    ffmpeg = ffmpeg_path() if fmt != "gif" else None
    fmt = "mp4" if ffmpeg else "gif"
    path = os.path.join(out_dir, "%s.%s" % (name, fmt))
    frames = Frames(track, drawings, config, title, stride=1 if fmt == "mp4" else 2)
    first = np.vstack((track.x[0], track.y[0], track.theta[0]))
    arena_figure = ArenaFigure.offscreen(config.arena, config.robot_radius, first, *VIDEO_SIZE, dpi=VIDEO_DPI)
    arena_figure.draw_obstacles(obstacles)
    painter = DrawingPainter(arena_figure.axes)
    blitter = Blitter(arena_figure, painter)
    meter = Progress(os.path.basename(path), len(frames), progress)
    width, height = arena_figure.figure.canvas.get_width_height()
    if fmt == "mp4":
        encoder = subprocess.Popen(
            [ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgba", "-s", "%dx%d" % (width, height),
             "-framerate", frame_rate(config.time_step), "-i", "-", "-c:v", "libx264", "-preset", "veryfast",
             "-pix_fmt", "yuv420p", "-movflags", "+faststart", path], stdin=subprocess.PIPE)
        try:
            for index, _, background_changed in frames.render(arena_figure, painter):
                encoder.stdin.write(blitter.frame(background_changed))
                meter(index + 1)
        finally:
            encoder.stdin.close()
            if encoder.wait() != 0:
                raise RuntimeError("ffmpeg could not encode %s (exit code %d)" % (path, encoder.returncode))
    else:
        from PIL import Image
        images = []
        for index, _, background_changed in frames.render(arena_figure, painter):
            pixels = bytes(blitter.frame(background_changed))
            images.append(Image.frombuffer("RGBA", (width, height), pixels, "raw", "RGBA", 0, 1)
                          .convert("RGB").quantize(colors=64))
            meter(index + 1)
        images[0].save(path, save_all=True, append_images=images[1:], loop=0,
                       duration=int(round(1000 * frames.stride * config.time_step)))
    meter.close()
    return path


def plot_trajectories(track, drawings, config, path, title="", obstacles=()):
    """trajectories.png: each robot's path in its colour, its start (open circle and id) and its end
    (the robot with its id), over the script's final drawing (faded)."""
    if not len(track.steps):
        return None
    last = np.vstack((track.x[-1], track.y[-1], track.theta[-1]))
    arena_figure = ArenaFigure.offscreen(config.arena, config.robot_radius, last, *PLOT_SIZE, dpi=PLOT_DPI)
    arena_figure.draw_obstacles(obstacles)
    ax = arena_figure.axes
    state = DrawingState()
    for message in sorted(drawings, key=lambda m: m.get("step", 0)):
        state.apply(message)
    DrawingPainter(ax, alpha=0.35).paint(state)
    n = track.x.shape[1]
    colours = robot_colours(n)
    lw = 1.6 if n <= 10 else 1.1
    for i in range(n):
        ax.plot(track.x[:, i], track.y[:, i], color=colours[i], lw=lw, zorder=0.9, solid_capstyle="round")
        ax.plot(track.x[0, i], track.y[0, i], "o", mfc="white", mec=colours[i], mew=1.5, ms=9, zorder=0.95)
        ax.annotate(str(int(track.ids[i])), (track.x[0, i], track.y[0, i]), fontsize=5, ha="center", va="center",
                    color=colours[i], zorder=0.96, fontweight="bold")
    arena_figure.chassis.set_edgecolor(colours)   # link each robot to its path
    arena_figure.chassis.set_linewidth(1.5)
    steps = int(track.steps[-1])
    arena_figure.figure.text(0.005, 0.995, "%s\n%d robots, %d steps (%.1f s): paths in each robot's colour, "
                             "open circle = start, robot = end" % (title, n, steps, steps * config.time_step),
                             ha="left", va="top", fontsize=6, color="0.2")
    arena_figure.figure.savefig(path)
    return path
