"""What a replay shows and reads besides its topics: the keys of a terminal (Keyboard) and the run
drawn as its live figure was, or written as a video without a display (Figure)."""
import json
import os
import select
import sys
import termios
import time
import tty

import numpy as np

from robotarium_recording.arena_figure import ArenaFigure, is_interactive, pyplot
from robotarium_recording.drawing import DrawingPainter, DrawingState
from robotarium_recording.pictures import render_video

FIGURE_HZ = 15   # at most this many redraws a second on a screen


class Keyboard:
    """Single keys from a terminal without Enter (no-op when stdin is not a terminal)."""

    def __init__(self):
        self.enabled = sys.stdin.isatty()
        self.saved = None
        if self.enabled:
            self.saved = termios.tcgetattr(sys.stdin)
            tty.setcbreak(sys.stdin.fileno())

    def key(self):
        if self.enabled and select.select([sys.stdin], [], [], 0)[0]:
            return sys.stdin.read(1)
        return None

    def close(self):
        if self.saved is not None:
            termios.tcsetattr(sys.stdin, termios.TCSADRAIN, self.saved)


class Figure:
    """The replay drawn as the run's live figure was (arena_figure.ArenaFigure, ids, what the
    script drew). On a screen: update() moves the artists (cheap) and draw() renders, which play()
    calls only when the next message is far enough away not to be delayed. Without a display the
    replayed run is written as a video (pictures.render_video) when the replay ends."""

    def __init__(self, bag, path):
        self.plt, self.bag, self.path = pyplot(), bag, path
        self.interactive = is_interactive(self.plt)
        self.config = bag.config()
        self.view = self.painter = None
        self.state = None
        self.dirty = False
        self.last_draw = 0.0
        if self.interactive:
            self.plt.ion()

    def update(self, data, type_name):
        """A replayed poses message."""
        if not self.interactive:
            return
        msg = self.bag.typestore.deserialize_cdr(data, type_name)
        poses = np.array([msg.x, msg.y, msg.theta])
        if self.view is None:
            self.view = ArenaFigure.window(self.config.arena, self.config.robot_radius, poses, self.plt,
                                           title="replay of %s" % self.bag.name)
            self.view.draw_obstacles(self.bag.experiment().get("obstacles") or ())   # a 2.x run's walls
            self.painter, self.state = DrawingPainter(self.view.axes), DrawingState()
            self.view.figure.show()
        self.view.update(poses)
        self.view.set_label("%s   t = %7.2f s   step %5d" % (self.bag.name, msg.sim_time, msg.step))
        self.dirty = True

    def drawing(self, data, type_name):
        """A replayed drawing message (what the script drew)."""
        if self.interactive and self.state is not None:
            try:
                self.state.apply(json.loads(self.bag.typestore.deserialize_cdr(data, type_name).data))
            except ValueError:
                return
            self.painter.paint(self.state)
            self.dirty = True

    def draw(self):
        """Render on screen, at most FIGURE_HZ times a second."""
        if not (self.dirty and self.interactive) or time.monotonic() - self.last_draw < 1.0 / FIGURE_HZ:
            return False
        self.view.show()
        self.last_draw, self.dirty = time.monotonic(), False
        return True

    def close(self):
        if not self.interactive:
            folder, name = os.path.split(os.path.abspath(self.path))
            os.makedirs(folder, exist_ok=True)
            written = render_video(self.bag.poses(), self.bag.drawings(), self.config, folder, self.bag.name,
                                   name=os.path.splitext(name)[0], obstacles=self.bag.experiment().get("obstacles") or ())
            if written:
                print("[replay] no display: the replay is the video %s" % written, file=sys.stderr)
