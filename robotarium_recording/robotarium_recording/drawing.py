"""What a script draws on r.axes, as data: recorded while it runs, drawn again in the video.

On the Robotarium, whatever a script draws on r.axes (goal markers, labels, lines, a background
image) is projected onto the arena and so appears in the video of the run. Here the client watches
the script's artists on r.axes and, at every step where some of them changed, publishes the
changes (JSON on <ns>/drawing, so the recorder keeps them in the bag); the video, the trajectory
plot and the replay figure draw them again at the step they belong to.

Watching is cheap: each artist's stale callback (matplotlib calls it whenever a property changes)
marks it, and only marked artists are serialized and compared with what was sent before (a
scatter of which only the positions or sizes changed - a marker following a robot - is sent as
just those). One message: {"step": k, "ppm": points per metre of the script's figure, "set":
{key: spec}, "move": {key: {"offsets": .., "sizes": ..}}, "removed": [key, ...]}. Keys number
the artists in the order they were added (matplotlib's drawing order among equal zorders).
Sizes in points (marker sizes, line widths, font sizes) are the script's, made for its figure's
scale; they are scaled by the ratio of points per metre when drawn on another figure, so a 20 cm
goal marker stays 20 cm.

Kinds: "scatter" (PathCollection), "collection" (LineCollection, PolyCollection and other data
collections), "line" (Line2D), "text", "image" (AxesImage, as PNG), "patch" (any Patch: circles,
rectangles, arrows, polygons). Anything else (a legend, a quiver) is left out.
"""
import base64
import io
import json
import sys

import numpy as np

FORMAT = 1


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
        marker = artist.get_marker()
        spec = {"kind": "line", "x": np.asarray(artist.get_xdata(), dtype=float).tolist(),
                "y": np.asarray(artist.get_ydata(), dtype=float).tolist(), "color": _rgba(artist.get_color())[0],
                "lw": float(artist.get_linewidth()), "ls": artist.get_linestyle(),
                "marker": marker if isinstance(marker, (str, int)) else "o", "ms": float(artist.get_markersize()),
                "mfc": _rgba(artist.get_markerfacecolor())[0] if artist.get_markerfacecolor() != "none" else "none",
                "mec": _rgba(artist.get_markeredgecolor())[0], "mew": float(artist.get_markeredgewidth()),
                "drawstyle": artist.get_drawstyle()}
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
        from PIL import Image
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


class DrawingWatcher:
    """Watches the artists of `axes` that are not in `own` (the arena's) and says what changed."""

    def __init__(self, axes, own):
        self.axes = axes
        self.own = set(own)
        self.keys = {}          # artist -> key
        self.sent = {}          # key -> the spec last sent (None: not drawable)
        self.dirty = set()
        self.prints = {}        # key -> fingerprint() when last serialized
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
        from robotarium_recording.arena_figure import points_per_metre
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
        updated, moved = {}, {}
        for artist in sorted(self.dirty & present_set, key=lambda a: int(self.keys[a])):
            key = self.keys[artist]
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
        self.dirty.clear()
        removed = [k for k in removed] + [k for k, spec in updated.items() if spec is None]
        updated = {k: v for k, v in updated.items() if v is not None}
        ppm = round(points_per_metre(self.axes), 6)
        if not updated and not moved and not removed and ppm == self.ppm:
            return None
        self.ppm = ppm
        message = {"format": FORMAT, "step": int(step), "ppm": ppm, "set": updated, "removed": removed}
        if moved:
            message["move"] = moved
        return message

    def close(self):
        """Stop watching (restores nothing: the script's figure is going away)."""
        self.keys.clear()
        self.dirty.clear()


def encode(message):
    return json.dumps(message, separators=(",", ":"), allow_nan=True)


def decode(text):
    return json.loads(text)


class DrawingState:
    """The script's drawing at a given step: apply() the messages in order."""

    def __init__(self):
        self.specs = {}   # key -> spec
        self.ppm = None
        self.version = 0

    def apply(self, message):
        for key in message.get("removed", []):
            self.specs.pop(key, None)
        self.specs.update(message.get("set", {}))
        for key, fields in message.get("move", {}).items():
            if key in self.specs:
                self.specs[key] = dict(self.specs[key], **fields)
        self.ppm = message.get("ppm", self.ppm)
        self.version += 1


class DrawingPainter:
    """Draws a DrawingState on another axes (the video's, the replay's), scaling sizes in points
    from the script's figure to this one."""

    def __init__(self, axes, alpha=None):
        self.axes = axes
        self.alpha = alpha      # force a transparency (the trajectory plot fades the drawing)
        self.artists = {}       # key -> (spec, artist)
        self.scale = 1.0

    def paint(self, state):
        """Make the axes show `state`. Returns (changed, removed): the artists made or changed, and
        the zorders of those taken away (the video redraws its background when one below the
        robots changed)."""
        from robotarium_recording.arena_figure import points_per_metre
        scale = points_per_metre(self.axes) / state.ppm if state.ppm else 1.0
        rescaled = abs(scale - self.scale) > 1e-9
        self.scale = scale
        changed, removed = [], []
        for key in list(self.artists):
            if key not in state.specs:
                artist = self.artists.pop(key)[1]
                removed.append(artist.get_zorder())
                artist.remove()
        for key in sorted(state.specs, key=int):
            spec = state.specs[key]
            old = self.artists.get(key)
            if old is not None and old[0] is spec and not rescaled:
                continue
            if old is not None and not rescaled and self._update(old[1], old[0], spec):
                self.artists[key] = (spec, old[1])
                changed.append(old[1])
                continue
            if old is not None:
                removed.append(old[1].get_zorder())
                old[1].remove()
            artist = self._make(spec)
            if artist is not None:
                artist.set_zorder(spec["z"] + (int(key) + 1) * 1e-9)   # equal zorders keep the script's order
                self.artists[key] = (spec, artist)
                changed.append(artist)
            else:
                self.artists.pop(key, None)
        return changed, removed

    def _update(self, artist, old, spec):
        """Change an artist in place where only its data moved (the common case: a marker that
        follows a robot, a label's text); False when it must be made again."""
        same = {k: v for k, v in old.items() if k not in ("offsets", "sizes", "xy", "text", "x", "y")}
        if same != {k: v for k, v in spec.items() if k not in ("offsets", "sizes", "xy", "text", "x", "y")}:
            return False
        if spec["kind"] == "scatter":
            artist.set_offsets(np.asarray(spec["offsets"]).reshape(-1, 2))
            artist.set_sizes(np.asarray(spec["sizes"]) * self.scale ** 2)
        elif spec["kind"] == "text":
            artist.set_position(spec["xy"])
            artist.set_text(spec["text"])
        elif spec["kind"] == "line":
            artist.set_data(spec["x"], spec["y"])
        else:
            return False
        return True

    def _make(self, spec):
        from matplotlib.collections import PathCollection
        from matplotlib.patches import PathPatch
        from matplotlib.path import Path
        from matplotlib.transforms import Affine2D

        ax, k = self.axes, self.scale
        kind = spec["kind"]

        def path(p):
            return Path(np.asarray(p["v"], dtype=float).reshape(-1, 2), None if p["c"] is None else p["c"])

        if kind == "scatter":
            artist = PathCollection([path(p) for p in spec["paths"]], sizes=np.asarray(spec["sizes"]) * k * k,
                                    offsets=np.asarray(spec["offsets"]).reshape(-1, 2), offset_transform=ax.transData,
                                    facecolors=spec["fc"], edgecolors=spec["ec"],
                                    linewidths=np.asarray(spec["lw"]) * k)
            artist.set_transform(Affine2D())   # marker paths in points, as scatter makes them
            ax.add_collection(artist, autolim=False)
        elif kind == "collection":
            artist = PathCollection([path(p) for p in spec["paths"]], facecolors=spec["fc"] or "none",
                                    edgecolors=spec["ec"], linewidths=np.asarray(spec["lw"]) * k,
                                    transform=ax.transData)
            ax.add_collection(artist, autolim=False)
        elif kind == "line":
            (artist,) = ax.plot(spec["x"], spec["y"], color=spec["color"], linewidth=spec["lw"] * k,
                                linestyle=spec["ls"], marker=spec["marker"], markersize=spec["ms"] * k,
                                markerfacecolor=spec["mfc"], markeredgecolor=spec["mec"],
                                markeredgewidth=spec["mew"] * k, drawstyle=spec["drawstyle"], scalex=False,
                                scaley=False)
        elif kind == "text":
            artist = ax.text(*spec["xy"], spec["text"], fontsize=spec["size"] * k, color=spec["color"],
                             fontweight=spec["weight"], fontstyle=spec["style"], fontfamily=spec["family"],
                             ha=spec["ha"], va=spec["va"], rotation=spec["rotation"],
                             transform=ax.transData if spec["coords"] == "data" else ax.transAxes, clip_on=True)
            if "box" in spec:
                box = spec["box"]
                artist.set_bbox({"facecolor": box["fc"], "edgecolor": box["ec"], "linewidth": box["lw"] * k})
        elif kind == "image":
            from PIL import Image
            pixels = np.asarray(Image.open(io.BytesIO(base64.b64decode(spec["png"]))))
            artist = ax.imshow(pixels, extent=spec["extent"], origin=spec["origin"],
                               interpolation=spec["interpolation"], aspect=ax.get_aspect())
        elif kind == "patch":
            artist = PathPatch(path(spec["path"]), facecolor=spec["fc"], edgecolor=spec["ec"],
                               linewidth=spec["lw"] * k, linestyle=spec["ls"], fill=spec["fill"])
            ax.add_patch(artist)
        else:
            return None
        artist.set_visible(spec["visible"])
        alpha = self.alpha if self.alpha is not None else spec["alpha"]
        if alpha is not None:
            artist.set_alpha(alpha if self.alpha is None or spec["alpha"] is None else alpha * spec["alpha"])
        return artist
