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
import contextlib
import fractions
import os
import shutil
import subprocess
import sys

import numpy as np

from robotarium_recording.arena_figure import ROBOTS_ZORDER, ArenaFigure, robot_colours
from robotarium_recording.drawing import DrawingPainter, DrawingState

VIDEO_SIZE = (1280, 800)
VIDEO_DPI = 200
PLOT_SIZE = (1600, 1000)
PLOT_DPI = 160
# x264's preset: superfast takes half veryfast's time for 2.3 times its file (300 frames of 3 robots:
# 400 kB against 170 kB), and the encoder's time is most of the video's.
X264_PRESET = "superfast"
# The Compositor draws the frames unless the script's drawing changes in more than
# COMPOSITE_MIN_CHANGES + one in COMPOSITE_CHANGES frames (each change renders its layers again).
COMPOSITE_MIN_CHANGES = 5
COMPOSITE_CHANGES = 25


def ffmpeg_path():
    """ffmpeg of the imageio-ffmpeg wheel, else one on PATH, else None."""
    try:
        import imageio_ffmpeg  # here: the wheel is optional
        return imageio_ffmpeg.get_ffmpeg_exe()
    except Exception:   # no wheel, or no binary for this platform
        return shutil.which("ffmpeg")


def frame_rate(time_step):
    """Frames per second for one frame per step in experiment time, as ffmpeg's fraction ("1000/33")."""
    rate = fractions.Fraction(1 / time_step).limit_denominator(1000)
    return "%d/%d" % (rate.numerator, rate.denominator)


def frame_plan(pose_steps, drawing_steps, stride=1):
    """The frames of a run, as what each shows: yield (step, row, drawings) for every `stride`-th step
    from the first pose row's step to the last one's: `row` the newest pose row at or before that step,
    `drawings` how many of the drawing messages (in the order they are applied: sorted by step, recorded
    order kept) are applied by then. The video made as the run goes follows the same rule as steps arrive
    (live_video.LiveFrames.due), and is kept only where its plan is this one."""
    if not len(pose_steps):
        return
    row = d = 0
    for step in range(int(pose_steps[0]), int(pose_steps[-1]) + 1, stride):
        while row + 1 < len(pose_steps) and pose_steps[row + 1] <= step:
            row += 1
        while d < len(drawing_steps) and drawing_steps[d] <= step:
            d += 1
        yield step, row, d


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

    def changes(self):
        """How many frames show a drawing other than the frame before."""
        return drawing_changes(self.drawings, int(self.steps[0]) if len(self.steps) else 0)

    def plan(self):
        """frame_plan of this run: (step, row, drawings applied) per frame."""
        return frame_plan(self.track.steps, [m.get("step", 0) for m in self.drawings], self.stride)


class Scene:
    """The arena figure of a video as one frame shows it: the robots at their poses, the script's drawing
    with the messages applied so far, the time label."""

    def __init__(self, arena_figure, painter, title, time_step):
        self.arena_figure, self.painter, self.title, self.time_step = arena_figure, painter, title, time_step
        self.state = DrawingState()
        self.applied = 0   # drawing messages applied

    def show(self, step, poses, new_drawings):
        """Put the frame of `step` on the figure: returns (background_changed, drawing_changed)."""
        self.arena_figure.update(poses)
        for message in new_drawings:
            self.state.apply(message)
        self.applied += len(new_drawings)
        changed, below = bool(new_drawings), False
        if self.painter is not None and changed:
            made, removed = self.painter.paint(self.state)
            below = any(z < ROBOTS_ZORDER for z in removed) or any(a.get_zorder() < ROBOTS_ZORDER for a in made)
        self.arena_figure.set_label("%s   t = %7.2f s   step %5d" % (self.title, step * self.time_step, step))
        return below, changed


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


# BT.601, limited range: what ffmpeg's swscale uses to turn RGB into yuv420p (and a player back).
_TO_YUV = np.array([[65.738, 129.057, 25.064], [-37.945, -74.494, 112.439], [112.439, -94.154, -18.285]],
                   dtype=np.float32).T / 256
_YUV_OFFSET = np.array([16, 128, 128], dtype=np.float32)


def _union(a, b):
    """The smallest box (top, left, bottom, right) holding boxes a and b (either may be None)."""
    if a is None or b is None:
        return a if b is None else b
    return min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])


def _overlap(a, b):
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


class Compositor:
    """Frames drawn without matplotlib per frame (used while the script's drawing changes seldom:
    see render_video). matplotlib renders, once and again only when the drawing changed, the layer
    below the robots (the arena, obstacles, what the script drew below them) and the layer above
    them (what it drew at the robots' zorder and above, transparent elsewhere); one robot at
    heading 0 and each robot's id are rendered once as small images, with the arena's own artists,
    so they look as in the figure. A frame is the static picture (below and above) with, for each
    robot, its image turned and placed at its pose (Pillow's affine resampling), its id, and the
    layer above composited again over those few pixels; the time label is set by Pillow in the
    same monospace font. Only the pixels that changed since the previous frame are touched, in RGB
    and in the yuv420p planes the encoder takes (so ffmpeg does no colour conversion): a frame
    costs well under a millisecond for a few robots, where a matplotlib redraw costs ten."""

    def __init__(self, arena_figure, painter):
        # matplotlib's fonts and Pillow when a video is drawn, not when this module is imported (by the CLI)
        from matplotlib import font_manager
        from PIL import Image, ImageDraw, ImageFont
        self.Image, self.ImageDraw = Image, ImageDraw
        self.af, self.painter = arena_figure, painter
        figure = arena_figure.figure
        self.width, self.height = figure.canvas.get_width_height()
        self.robots = {arena_figure.wheels, arena_figure.chassis, arena_figure.leds}
        self.static = self.rgb = self.planes = self.static_planes = self.above = None
        self.dirty = []   # (top, left, bottom, right) boxes the last frame drew on
        self.sprite, self.sprite_centre = self._robot_sprite()
        self.id_masks = self._id_masks() if arena_figure.ids is not None else None
        if arena_figure.label is None:
            arena_figure.set_label("")
        size = arena_figure.label.get_fontsize() * figure.dpi / 72.0
        self.font = ImageFont.truetype(font_manager.findfont(font_manager.FontProperties(family="monospace")),
                                       max(1, int(round(size))))
        self.label_colour = (64, 64, 64)   # the label's "0.25"

    # -- rendered by matplotlib, seldom -----------------------------------------------------------

    def _render(self, shown, transparent):
        """RGBA pixels of the figure with only the artists in `shown` drawn."""
        figure, axes = self.af.figure, self.af.axes
        artists = [a for a in list(axes.get_children()) + list(figure.texts) if a is not axes.patch]
        saved = [(a, a.get_visible()) for a in artists]
        patches = [(p, p.get_visible()) for p in (figure.patch, axes.patch)]
        try:
            for artist, visible in saved:
                artist.set_visible(visible and artist in shown)
            if transparent:
                figure.patch.set_visible(False)
                axes.patch.set_visible(False)
            figure.canvas.draw()
            return np.asarray(figure.canvas.buffer_rgba()).copy()
        finally:
            for artist, visible in saved + patches:
                artist.set_visible(visible)

    def _pixel(self, xy):
        """Image coordinates (column, row; continuous) of data points (N x 2)."""
        px = self.af.axes.transData.transform(np.asarray(xy, dtype=float).reshape(-1, 2))
        px[:, 1] = self.height - px[:, 1]
        return px

    def _robot_sprite(self):
        """One robot at heading 0, premultiplied RGBA ("RGBa"), and its centre in that image."""
        af = self.af
        x0, x1, y0, y1 = af.arena
        kept = af.poses
        poses = np.zeros((3, af.number_of_robots))
        poses[0], poses[1] = x1 + 10, y1 + 10   # the others far off the figure
        poses[:2, 0] = (x0 + x1) / 2, (y0 + y1) / 2
        af.update(poses)
        pixels = self._render(self.robots, transparent=True)
        af.update(kept)
        (cx, cy), = self._pixel(poses[:2, 0])
        r = int(np.ceil(1.5 * af.robot_radius * self.af.axes.transData.get_matrix()[0, 0])) + 3
        left, top = int(cx) - r, int(cy) - r
        box = np.ascontiguousarray(pixels[top:top + 2 * r + 1, left:left + 2 * r + 1])
        return self.Image.fromarray(box, "RGBA").convert("RGBa"), (cx - left, cy - top)

    def _id_masks(self):
        """Each robot's id: (alpha, its centre in that image), cut from one rendering of all ids."""
        af = self.af
        n = af.number_of_robots
        x0, x1, y0, y1 = af.arena
        spacing = 0.2
        columns = max(1, int((x1 - x0) / spacing))
        k = np.arange(n)
        grid = np.column_stack((x0 + spacing / 2 + spacing * (k % columns), y1 - spacing / 2 - spacing * (k // columns)))
        af.ids.set_offsets(grid)
        pixels = self._render({af.ids}, transparent=True)
        af.update(af.poses)
        half = int(np.ceil(0.45 * spacing * self.af.axes.transData.get_matrix()[0, 0]))
        masks = []
        for cx, cy in self._pixel(grid):
            left, top = int(round(cx)) - half, int(round(cy)) - half
            mask = np.zeros((2 * half + 1, 2 * half + 1), np.float32)
            if 0 <= left and 0 <= top and top + 2 * half < self.height and left + 2 * half < self.width:
                mask = pixels[top:top + 2 * half + 1, left:left + 2 * half + 1, 3].astype(np.float32) / 255
            masks.append((mask[..., None], cx - left, cy - top))   # (more robots than the grid holds: no id)
        return masks

    def refresh(self):
        """Render the layers again (the first frame, or the script's drawing changed)."""
        af = self.af
        moving = self.robots | {a for a in (af.ids, af.label) if a is not None}
        above = {a for _, a in self.painter.artists.values() if a.get_zorder() >= ROBOTS_ZORDER}
        everything = set(af.axes.get_children()) | set(af.figure.texts)
        static = self._render(everything - moving - above, transparent=False)[..., :3].astype(np.float32)
        self.above = None
        if above:
            layer = self._render(above, transparent=True)
            rows, columns = np.flatnonzero(layer[..., 3].any(axis=1)), np.flatnonzero(layer[..., 3].any(axis=0))
            if len(rows):
                top, bottom, left, right = rows[0], rows[-1] + 1, columns[0], columns[-1] + 1
                alpha = layer[top:bottom, left:right, 3:].astype(np.float32) / 255
                rgb = layer[top:bottom, left:right, :3].astype(np.float32) * alpha
                self.above = (top, left, rgb, alpha)
                static[top:bottom, left:right] = rgb + static[top:bottom, left:right] * (1 - alpha)
        self.static = np.round(static).astype(np.uint8)
        self.rgb = self.static.copy()
        self.static_planes = self._yuv(self.static)
        self.planes = [plane.copy() for plane in self.static_planes]
        self.dirty = []

    # -- a frame ------------------------------------------------------------------------------------

    def frame(self, poses, label):
        """Draw the frame with the robots at `poses` (3 x N) and `label` in the lower left; the
        result is self.rgb (H x W x 3) and self.planes (yuv420p)."""
        if self.static is None:
            self.refresh()
        for top, left, bottom, right in self.dirty:   # back to the static picture where the last frame drew
            self.rgb[top:bottom, left:right] = self.static[top:bottom, left:right]
        boxes = []   # per robot: the box it and its id were drawn in
        centres = self._pixel(np.asarray(poses[:2], dtype=float).T)
        sprite, (sx, sy) = self.sprite, self.sprite_centre
        half = sprite.size[0] // 2 + 1
        size = 2 * half + 1
        for i, ((cx, cy), theta) in enumerate(zip(centres, poses[2])):
            left, top = int(np.floor(cx)) - half, int(np.floor(cy)) - half
            c, s = np.cos(theta), np.sin(theta)
            du, dv = left + 0.5 - cx, top + 0.5 - cy   # an output pixel's centre, from the robot's
            # output pixel (u, v) -> sprite coordinates: turned back by the heading (rows point down)
            turned = sprite.transform((size, size), self.Image.AFFINE, (
                c, -s, sx + c * du - s * dv, s, c, sy + s * du + c * dv), resample=self.Image.BICUBIC)
            premultiplied = np.asarray(turned, dtype=np.float32)
            box = self._over(top, left, premultiplied[..., :3], premultiplied[..., 3:] / 255)
            if self.id_masks is not None:
                mask, mx, my = self.id_masks[i]
                box = _union(box, self._over(int(round(cy - my)), int(round(cx - mx)), 0.0, mask))
            if box is not None:
                boxes.append(box)
        if self.above is not None:
            top_a, left_a, rgb, alpha = self.above
            for box in boxes:
                self._over(top_a, left_a, rgb, alpha, within=box)
        label = self._label(label)
        if label is not None:
            boxes.append(label)
        # Each box of this frame with the one of the same robot (or label) in the last frame, if
        # they overlap (a robot moves a few pixels a frame): one conversion for both.
        boxes = [self._even(box) for box in boxes]
        changed = []
        for k, box in enumerate(boxes):
            old = self.dirty[k] if k < len(self.dirty) else None
            if old is not None and _overlap(old, box):
                changed.append(_union(old, box))
            else:
                changed += [b for b in (old, box) if b is not None]
        changed += self.dirty[len(boxes):]
        self._write_planes(changed)
        self.dirty = boxes

    def _write_planes(self, boxes):
        y, u, v = self.planes
        for top, left, bottom, right in boxes:
            py, pu, pv = self._yuv(self.rgb[top:bottom, left:right])
            y[top:bottom, left:right] = py
            u[top // 2:bottom // 2, left // 2:right // 2] = pu
            v[top // 2:bottom // 2, left // 2:right // 2] = pv

    def _even(self, box):
        top, left, bottom, right = box
        return top - top % 2, left - left % 2, min(bottom + bottom % 2, self.height), min(right + right % 2, self.width)

    @staticmethod
    def _yuv(rgb):
        """yuv420p planes of an RGB image of even height and width."""
        rgb = rgb.astype(np.float32)
        y = rgb @ _TO_YUV[:, 0] + _YUV_OFFSET[0]
        mean = (rgb[0::2, 0::2] + rgb[1::2, 0::2] + rgb[0::2, 1::2] + rgb[1::2, 1::2]) * 0.25
        uv = mean @ _TO_YUV[:, 1:] + _YUV_OFFSET[1:]
        return [np.clip(y + 0.5, 0, 255).astype(np.uint8), np.clip(uv[..., 0] + 0.5, 0, 255).astype(np.uint8),
                np.clip(uv[..., 1] + 0.5, 0, 255).astype(np.uint8)]

    def _over(self, top, left, rgb, alpha, within=None):
        """Composite premultiplied `rgb` with `alpha` (h x w x 1) at (top, left) over the frame,
        clipped to the frame (and to the box `within`); returns the box drawn on, or None."""
        h, w = alpha.shape[:2]
        t0, l0, t1, l1 = max(top, 0), max(left, 0), min(top + h, self.height), min(left + w, self.width)
        if within is not None:
            t0, l0, t1, l1 = max(t0, within[0]), max(l0, within[1]), min(t1, within[2]), min(l1, within[3])
        if t0 >= t1 or l0 >= l1:
            return None
        piece = (slice(t0 - top, t1 - top), slice(l0 - left, l1 - left))
        region = self.rgb[t0:t1, l0:l1]
        colour = rgb[piece] if isinstance(rgb, np.ndarray) else rgb
        region[...] = np.round(colour + region * (1 - alpha[piece]))
        return t0, l0, t1, l1

    def _label(self, text):
        """The time label in the lower left corner (as ArenaFigure.set_label places it)."""
        if not text:
            return None
        x, bottom = int(round(0.005 * self.width)), self.height - int(round(0.005 * self.height))
        left, top, right, below = self.font.getbbox(text, anchor="ld")
        t0, l0 = max(bottom + top, 0), max(x + left, 0)
        t1, l1 = min(bottom + below + 1, self.height), min(x + right + 1, self.width)
        image = self.Image.fromarray(self.rgb[t0:t1, l0:l1])
        self.ImageDraw.Draw(image).text((x - l0, bottom - t0), text, font=self.font, anchor="ld",
                                        fill=self.label_colour)
        self.rgb[t0:t1, l0:l1] = np.asarray(image)
        return t0, l0, t1, l1


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
    None when there is nothing to show.

    Frames come from the Compositor (no matplotlib per frame) unless the script's drawing changes
    in more than one frame in COMPOSITE_CHANGES: then the Blitter (matplotlib draws the robots and
    the drawing above them in every frame, the drawing below them when it changed)."""
    if not len(track.steps):
        return None
    ffmpeg = ffmpeg_path() if fmt != "gif" else None
    fmt = "mp4" if ffmpeg else "gif"
    frames = Frames(track, drawings, config, title, stride=1 if fmt == "mp4" else 2)
    first = np.vstack((track.x[0], track.y[0], track.theta[0]))
    video = Video(os.path.join(out_dir, "%s.%s" % (name, fmt)), ffmpeg, config, first, title, obstacles,
                  composite=composites(frames.changes(), len(frames)), total=len(frames), progress=progress)
    try:
        for step, row, d in frames.plan():
            video.frame(step, np.vstack((track.x[row], track.y[row], track.theta[row])),
                        frames.drawings[video.scene.applied:d])
    except BaseException:
        video.abort()
        raise
    return video.close()


def drawing_changes(drawings, first_step):
    """How many frames show a drawing other than the frame before: the distinct steps of the drawing messages
    (a message before the first frame counts as the first frame's)."""
    return len({max(int(m.get("step", 0)), first_step) for m in drawings})


def composites(changes, frames, margin=0):
    """Whether the Compositor draws `frames` frames whose drawing changes in `changes` of them: seldom enough
    (COMPOSITE_MIN_CHANGES + one in COMPOSITE_CHANGES frames); `margin` moves that limit (the live video's
    hysteresis, live_video.LiveFrames.composites)."""
    return changes <= COMPOSITE_MIN_CHANGES + frames // COMPOSITE_CHANGES + margin


class Video:
    """A video being written, frame by frame: frame() puts each on the arena figure, draws it (Compositor
    or Blitter) and hands it to the encoder (ffmpeg; `ffmpeg` None: a GIF with Pillow, every other step);
    close() finishes the file and returns its path."""

    def __init__(self, path, ffmpeg, config, first_poses, title="", obstacles=(), composite=True, total=0,
                 progress=True):
        self.path, self.fmt = path, "mp4" if ffmpeg else "gif"
        self.stride, self.time_step = 1 if ffmpeg else 2, config.time_step
        self.arena_figure = ArenaFigure.offscreen(config.arena, config.robot_radius, first_poses, *VIDEO_SIZE,
                                                  dpi=VIDEO_DPI)
        self.arena_figure.draw_obstacles(obstacles)
        painter = DrawingPainter(self.arena_figure.axes)
        self.scene = Scene(self.arena_figure, painter, title, config.time_step)
        self.compositor = Compositor(self.arena_figure, painter) if composite else None
        self.blitter = Blitter(self.arena_figure, painter)
        self.meter = Progress(os.path.basename(path), total, progress)
        self.frames, self.images, self.encoder = 0, [], None
        if ffmpeg:
            width, height = self.arena_figure.figure.canvas.get_width_height()
            self.encoder = subprocess.Popen(
                [ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo",
                 "-pix_fmt", "rgba" if self.compositor is None else "yuv420p", "-s", "%dx%d" % (width, height),
                 "-framerate", frame_rate(config.time_step), "-i", "-", "-c:v", "libx264", "-preset", X264_PRESET,
                 "-pix_fmt", "yuv420p", "-movflags", "+faststart", path], stdin=subprocess.PIPE)

    def frame(self, step, poses, new_drawings=()):
        """The frame of `step`: the robots at `poses` (3 x N), the drawing messages that apply from it on."""
        background_changed, drawing_changed = self.scene.show(step, poses, new_drawings)
        if self.compositor is None:
            pixels = self.blitter.frame(background_changed)
            planes = [pixels] if self.encoder else np.asarray(pixels)[..., :3]
        else:
            if drawing_changed:
                self.compositor.refresh()
            self.compositor.frame(self.arena_figure.poses, self.arena_figure.label.get_text())
            planes = self.compositor.planes if self.encoder else self.compositor.rgb
        if self.encoder:
            for plane in planes:
                self.encoder.stdin.write(plane)
        else:
            from PIL import Image  # the GIF fallback only
            self.images.append(Image.fromarray(np.ascontiguousarray(planes)).quantize(colors=64))
        self.frames += 1
        self.meter(self.frames)

    def close(self):
        if self.encoder:
            self.encoder.stdin.close()
            if self.encoder.wait() != 0:
                raise RuntimeError("ffmpeg could not encode %s (exit code %d)" % (self.path, self.encoder.returncode))
        else:
            self.images[0].save(self.path, save_all=True, append_images=self.images[1:], loop=0,
                                duration=int(round(1000 * self.stride * self.time_step)))
        self.meter.close()
        return self.path

    def abort(self):
        """Stop the encoder; the file is not a video (the caller removes it or writes it again)."""
        if self.encoder:
            with contextlib.suppress(OSError):
                self.encoder.stdin.close()
            self.encoder.kill()
            self.encoder.wait()


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
