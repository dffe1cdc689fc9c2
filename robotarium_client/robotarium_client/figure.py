"""The live figure of the Robotarium class (r.figure, r.axes): robotarium_recording's ArenaFigure
in rps's layout, the same drawer as the video and the replay figure.

With no display (or MPLBACKEND=Agg) the figure is built on the Agg backend and not redrawn every
step: nobody would see it, and a script's savefig() still renders it fully. What a script draws
on r.axes is recorded as data for the video (robotarium_client.drawing), not rendered here.
"""
import importlib.util
import sys

import robotarium_recording as recording


def live_figure(arena, robot_radius, poses, figure_class=None):
    """The live figure: `figure_class` (default robotarium_recording's ArenaFigure) shown on a screen,
    or on the Agg backend."""
    plt = recording.pyplot()
    arena_figure = (figure_class or recording.ArenaFigure).live(arena, robot_radius, poses, plt=plt)
    arena_figure.interactive = recording.is_interactive(plt)
    if arena_figure.interactive:
        plt.ion()
        plt.show()
    return arena_figure


def skip_headless_idle_draws():
    """Make canvas.draw_idle() on the Agg backend (no display) a no-op, as it is on a screen
    with nobody waiting for the next frame: a request to redraw "when the GUI is idle", which
    matplotlib's base class honours on Agg by rendering at once. Scripts that redraw their figures
    every step (2.x's ekf_experiment.py: three figures, 2000 steps) spent their time rendering
    pictures nobody sees. draw(), savefig() and everything that reads a figure still render it
    fully. Canvases of screen backends define their own draw_idle and are untouched.

    The runner calls this before the script, which may never plot: matplotlib is patched when the
    script first imports it, not imported here (0.3-0.5 CPU-s of every run of a script with no figure)."""
    bases = sys.modules.get(_BACKEND_BASES)
    if bases is not None:
        _skip_agg_idle_draws(bases)
    elif not any(isinstance(finder, _AfterImport) for finder in sys.meta_path):
        sys.meta_path.insert(0, _AfterImport(_BACKEND_BASES, _skip_agg_idle_draws))


_BACKEND_BASES = "matplotlib.backend_bases"


def _skip_agg_idle_draws(backend_bases):
    canvas = backend_bases.FigureCanvasBase
    if getattr(canvas.draw_idle, "skips_agg", False):
        return
    draw_idle = canvas.draw_idle

    def draw_idle_unless_headless(self, *args, **kwargs):
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # (headless: imported with the canvas)
        if type(self) is not FigureCanvasAgg:
            return draw_idle(self, *args, **kwargs)

    draw_idle_unless_headless.skips_agg = True
    canvas.draw_idle = draw_idle_unless_headless


class _AfterImport:
    """A finder on sys.meta_path (importlib.abc.MetaPathFinder's protocol; importing importlib.abc
    costs 40 ms) that calls then(module) once the module `name` has been imported (executed),
    wherever it is imported from; then leaves sys.meta_path."""

    def __init__(self, name, then):
        self.name, self.then = name, then

    def find_spec(self, fullname, path, target=None):
        if fullname != self.name:
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)   # the finders after this one
        if spec is None or spec.loader is None:
            return spec
        exec_module, then = spec.loader.exec_module, self.then

        def exec_module_then(module):
            exec_module(module)
            then(module)

        spec.loader.exec_module = exec_module_then   # (this module's own loader instance)
        return spec
