"""What a script drew on r.axes, as recorded: the drawing topic's text (encode, decode), the
drawing at a given step (DrawingState: the messages applied in order) and DrawingPainter, which
draws that state on another figure (the video, the trajectory plot, the replay and Foxglove
views), sizes in points scaled so that a 20 cm goal marker stays 20 cm.

The watcher that makes the messages lives with the client (robotarium_client.drawing): only a
script's process has the live figure. The wire format is here, with its reader, because every
recorded bag keeps it: the client encodes through this package's public API (encode_drawing).
The format: docs/ros-interface.md#the-scripts-drawing.
"""
import base64
import io
import json

import numpy as np

from robotarium_recording.arena_figure import points_per_metre

FORMAT = 2   # the version encode() stamps on every message (2: lines may "grow"; 1 is read the same)


def encode(message):
    """A drawing message (robotarium_client.drawing.DrawingWatcher.changes) as the topic's text."""
    return json.dumps({"format": FORMAT, **message}, separators=(",", ":"), allow_nan=True)


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
        for key, tail in message.get("grow", {}).items():
            spec = self.specs.get(key)
            if spec is not None:
                self.specs[key] = dict(spec, x=spec["x"] + tail["x"], y=spec["y"] + tail["y"])
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
        # matplotlib's classes here, not at the top: importing this module must not import matplotlib
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
