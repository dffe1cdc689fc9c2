"""The live figure of the Robotarium class (r.figure, r.axes): robotarium_recording's ArenaFigure
in rps's layout, the same drawer as the video and the replay figure.

With no display (or MPLBACKEND=Agg) the figure is built on the Agg backend and not redrawn every
step: nobody would see it, and a script's savefig() still renders it fully. What a script draws
on r.axes is recorded as data for the video (robotarium_client.drawing), not rendered here.
"""
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
    fully. Canvases of screen backends define their own draw_idle and are untouched."""
    # matplotlib here: the runner calls this before the script, which may never plot
    from matplotlib.backend_bases import FigureCanvasBase
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    if getattr(FigureCanvasBase.draw_idle, "skips_agg", False):
        return
    draw_idle = FigureCanvasBase.draw_idle

    def draw_idle_unless_headless(self, *args, **kwargs):
        if type(self) is not FigureCanvasAgg:
            return draw_idle(self, *args, **kwargs)

    draw_idle_unless_headless.skips_agg = True
    FigureCanvasBase.draw_idle = draw_idle_unless_headless
