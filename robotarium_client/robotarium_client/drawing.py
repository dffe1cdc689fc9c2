"""What a script draws on r.axes, watched while it runs: at every step where some of its artists
changed, DrawingWatcher.changes() says what changed, and the client publishes that on <ns>/drawing
(robotarium_recording.encode_drawing) for the recorder, viewers and the video.

It lives with the client because only a script's process has the live figure to watch; the
recording side (robotarium_recording.drawing) reads the messages back and paints them on another
figure. Watching is cheap: each artist's stale callback marks it, and only marked artists are
serialized and compared with what was sent. The message format: docs/ros-interface.md#the-scripts-drawing.
matplotlib is imported where an artist is serialized, never at import: the client imports this module.
"""
import base64
import io
import sys

import numpy as np

import robotarium_recording as recording


def _rgba(colours):
    if not (isinstance(colours, np.ndarray) and colours.ndim == 2 and colours.shape[1] == 4):
        from matplotlib.colors import to_rgba_array  # names, tuples: resolved once here
        colours = to_rgba_array(colours)
    return np.round(colours, 4).tolist()


def _path(path):
    return {"v": np.round(path.vertices, 6).tolist(),
            "c": None if path.codes is None else np.asarray(path.codes).tolist()}


def _common(artist):
    return {"z": float(artist.get_zorder()), "alpha": artist.get_alpha(), "visible": bool(artist.get_visible())}


def _to_data(artist, axes):
    """The transform from an artist's own coordinates to data coordinates, or None when it is not
    placed in data coordinates (then it is left out)."""
    transform = artist.get_transform()
    if transform == axes.transData:
        return None, True
    try:
        return transform - axes.transData, True
    except ValueError:
        return None, False


def serialize(artist, axes):
    """A JSON-able description of one artist of `axes`, or None for kinds not drawn again."""
    # matplotlib's classes here, not at the top: importing this module must not import matplotlib.
    from matplotlib.collections import Collection, PathCollection
    from matplotlib.image import AxesImage
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from matplotlib.text import Text

    if isinstance(artist, PathCollection) and artist.get_offset_transform() == axes.transData:
        spec = {"kind": "scatter", "paths": [_path(p) for p in artist.get_paths()],
                "sizes": np.asarray(artist.get_sizes(), dtype=float).tolist(),
                "offsets": np.asarray(artist.get_offsets(), dtype=float).reshape(-1, 2).tolist(),
                "fc": _rgba(artist.get_facecolor()), "ec": _rgba(artist.get_edgecolor()),
                "lw": np.atleast_1d(artist.get_linewidth()).astype(float).tolist()}
    elif isinstance(artist, Collection) and not isinstance(artist, PathCollection):
        if artist.get_transform() != axes.transData or len(artist.get_offsets()) > 1:
            return None
        spec = {"kind": "collection", "paths": [_path(p) for p in artist.get_paths()],
                "fc": _rgba(artist.get_facecolor()), "ec": _rgba(artist.get_edgecolor()),
                "lw": np.atleast_1d(artist.get_linewidth()).astype(float).tolist()}
    elif isinstance(artist, Line2D):
        if artist.get_transform() != axes.transData:
            return None
        x, y = line_data(artist)
        return dict(line_style(artist), x=x.tolist(), y=y.tolist())
    elif isinstance(artist, Text):
        transform = artist.get_transform()
        coords = "data" if transform == axes.transData else "axes" if transform == axes.transAxes else None
        if coords is None:
            return None
        x, y = artist.get_position()
        spec = {"kind": "text", "xy": [float(x), float(y)], "coords": coords, "text": artist.get_text(),
                "size": float(artist.get_fontsize()), "color": _rgba(artist.get_color())[0],
                "weight": artist.get_fontweight(), "style": artist.get_fontstyle(),
                "family": artist.get_fontfamily(), "ha": artist.get_horizontalalignment(),
                "va": artist.get_verticalalignment(), "rotation": float(artist.get_rotation())}
        box = artist.get_bbox_patch()
        if box is not None:
            spec["box"] = {"fc": _rgba(box.get_facecolor())[0], "ec": _rgba(box.get_edgecolor())[0],
                           "lw": float(box.get_linewidth())}
    elif isinstance(artist, AxesImage):
        from PIL import Image  # only for a script that shows an image
        rgba = artist.to_rgba(artist.get_array(), bytes=True)
        buffer = io.BytesIO()
        Image.fromarray(np.ascontiguousarray(rgba)).save(buffer, format="PNG")
        spec = {"kind": "image", "png": base64.b64encode(buffer.getvalue()).decode("ascii"),
                "extent": [float(v) for v in artist.get_extent()], "origin": artist.origin,
                "interpolation": artist.get_interpolation()}
    elif isinstance(artist, Patch):
        transform, placeable = _to_data(artist, axes)
        if not placeable:
            return None
        path = artist.get_path()
        if transform is not None:
            path = transform.transform_path(path)
        spec = {"kind": "patch", "path": _path(path), "fc": _rgba(artist.get_facecolor())[0],
                "ec": _rgba(artist.get_edgecolor())[0], "lw": float(artist.get_linewidth()),
                "ls": artist.get_linestyle(), "fill": bool(artist.get_fill())}
    else:
        return None
    spec.update(_common(artist))
    return spec


def line_data(artist):
    """A Line2D's x and y as float arrays."""
    return np.asarray(artist.get_xdata(), dtype=float), np.asarray(artist.get_ydata(), dtype=float)


def line_style(artist):
    """A Line2D's spec but its data (x, y): what must stay the same for the line to be sent as grown."""
    marker = artist.get_marker()
    spec = {"kind": "line", "color": _rgba(artist.get_color())[0],
            "lw": float(artist.get_linewidth()), "ls": artist.get_linestyle(),
            "marker": marker if isinstance(marker, (str, int)) else "o", "ms": float(artist.get_markersize()),
            "mfc": _rgba(artist.get_markerfacecolor())[0] if artist.get_markerfacecolor() != "none" else "none",
            "mec": _rgba(artist.get_markeredgecolor())[0], "mew": float(artist.get_markeredgewidth()),
            "drawstyle": artist.get_drawstyle()}
    spec.update(_common(artist))
    return spec


def fingerprint(artist):
    """A cheap summary of a scatter's state (the kind scripts touch every step), to skip serializing
    one that did not really change; None for other kinds (always serialized and compared)."""
    from matplotlib.collections import PathCollection
    if type(artist) is not PathCollection:
        return None
    return (np.asarray(artist.get_offsets()).tobytes(), np.asarray(artist.get_sizes()).tobytes(),
            np.asarray(artist.get_facecolor()).tobytes(), np.asarray(artist.get_edgecolor()).tobytes(),
            np.asarray(artist.get_linewidth()).tobytes(), tuple(id(p) for p in artist.get_paths()),
            artist.get_zorder(), artist.get_alpha(), artist.get_visible())


# A grown line is sent whole again once this many messages went since it last was: well within the topic's kept
# history (robotarium_core.topics.OUTPUT_HISTORY, 1000 messages), so a viewer that matches late draws it whole.
WHOLE_AFTER_MESSAGES = 250


class DrawingWatcher:
    """Watches the artists of `axes` that are not in `own` (the arena's) and says what changed."""

    def __init__(self, axes, own):
        self.axes = axes
        self.own = set(own)
        self.keys = {}          # artist -> key
        self.sent = {}          # key -> the spec last sent (None: not drawable)
        self.dirty = set()
        self.prints = {}        # key -> fingerprint() when last serialized
        self.lines = {}         # key -> (x, y, sent_whole_at): a line's data as last sent, the message it went whole in
        self.messages = 0       # messages changes() made
        self.failed = set()
        self.next_key = 0
        self.ppm = None

    def _watch(self, artist):
        previous = artist.stale_callback

        def on_change(a, value, previous=previous):
            self.dirty.add(a)
            if previous is not None:
                previous(a, value)

        artist.stale_callback = on_change
        self.keys[artist] = key = str(self.next_key)
        self.next_key += 1
        self.dirty.add(artist)
        return key

    def changes(self, step):
        """The changes since the last call, as a message dict, or None when nothing changed."""
        # What was added to the axes, in order (not its spines, axis and title artists).
        children = getattr(self.axes, "_children", None)
        if children is None:   # matplotlib before 3.5
            children = (self.axes.collections + self.axes.lines + self.axes.patches + self.axes.texts
                        + self.axes.images)
        present = [a for a in children if a not in self.own]
        for artist in present:
            if artist not in self.keys and (artist.axes is self.axes):
                self._watch(artist)
        present_set = set(present)
        removed = [self.keys.pop(a) for a in list(self.keys) if a not in present_set]
        for key in removed:
            self.sent.pop(key, None)
            self.prints.pop(key, None)
            self.lines.pop(key, None)
        updated, moved, grown = {}, {}, {}
        for artist in sorted(self.dirty & present_set, key=lambda a: int(self.keys[a])):
            key = self.keys[artist]
            if key in self.lines:
                tail = self._growth(artist, key)
                if tail is not None:
                    if tail["x"]:
                        grown[key] = tail
                    continue
            print_, before = fingerprint(artist), self.prints.get(key)
            if print_ is not None and print_ == before:
                continue   # touched (set_sizes with the same size every step) but unchanged
            self.prints[key] = print_
            if print_ is not None and before is not None and print_[2:] == before[2:] and key in self.sent:
                # Only where it is and how big: a marker following a robot, the common case.
                moved[key] = {"offsets": np.asarray(artist.get_offsets(), dtype=float).reshape(-1, 2).tolist(),
                              "sizes": np.asarray(artist.get_sizes(), dtype=float).tolist()}
                self.sent[key] = dict(self.sent[key], **moved[key])
                continue
            try:
                spec = serialize(artist, self.axes)
            except Exception as error:   # an artist we cannot describe must never break the script
                spec = None
                if key not in self.failed:
                    self.failed.add(key)
                    print("[robotarium] the video leaves out a %s the script drew (%s: %s)"
                          % (type(artist).__name__, type(error).__name__, error), file=sys.stderr)
            if spec != self.sent.get(key) and (spec is not None or key in self.sent):
                updated[key] = spec
            self.sent[key] = spec
            if spec is not None and spec["kind"] == "line":
                x, y = line_data(artist)
                self.lines[key] = (x.copy(), y.copy(), self.messages)
            else:
                self.lines.pop(key, None)
        self.dirty.clear()
        removed = [k for k in removed] + [k for k, spec in updated.items() if spec is None]
        updated = {k: v for k, v in updated.items() if v is not None}
        ppm = round(recording.points_per_metre(self.axes), 6)
        if not updated and not moved and not grown and not removed and ppm == self.ppm:
            return None
        self.ppm = ppm
        message = {"step": int(step), "ppm": ppm, "set": updated, "removed": removed}
        if moved:
            message["move"] = moved
        if grown:
            message["grow"] = grown
        self.messages += 1
        return message

    def _growth(self, artist, key):
        """What was appended to a line's data since it was sent ({"x": [], "y": []} when nothing), or
        None when it must be sent whole: its style changed, its old data is not where it was, or
        WHOLE_AFTER_MESSAGES messages went since it was last sent whole (a late reader of the topic's
        history then still finds it whole). A trail set_data() with its whole history every step
        (ekf_experiment.py) costs the tail, not the history, each step."""
        old_x, old_y, whole_at = self.lines[key]
        if artist.get_transform() != self.axes.transData:
            return None
        try:
            x, y = line_data(artist)
        except (TypeError, ValueError):
            return None
        n = len(old_x)
        if (len(x) < n or len(y) != len(x)
                or not np.array_equal(x[:n], old_x, equal_nan=True) or not np.array_equal(y[:n], old_y, equal_nan=True)):
            return None
        sent, style = self.sent[key], line_style(artist)
        if any(sent[k] != v for k, v in style.items()):
            return None
        if len(x) == n:
            return {"x": [], "y": []}
        if self.messages - whole_at >= WHOLE_AFTER_MESSAGES:
            return None
        tail = {"x": x[n:].tolist(), "y": y[n:].tolist()}
        self.sent[key] = dict(sent, x=sent["x"] + tail["x"], y=sent["y"] + tail["y"])
        self.lines[key] = (x.copy(), y.copy(), whole_at)
        return tail

    def close(self):
        """Stop watching (restores nothing: the script's figure is going away)."""
        self.keys.clear()
        self.dirty.clear()
