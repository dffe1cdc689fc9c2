"""The live figure of the Robotarium class (r.figure, r.axes): robotarium_recording's ArenaFigure
in rps's layout, the same drawer as the video and the replay figure.

With no display (or MPLBACKEND=Agg) the figure is built on the Agg backend and not redrawn every
step: nobody would see it, and a script's savefig() still renders it fully. What a script draws
on r.axes is recorded as data for the video (robotarium_recording.drawing), not rendered here.
"""
from robotarium_recording.arena_figure import ArenaFigure, is_interactive, pyplot


def live_figure(arena, robot_radius, poses, figure_class=ArenaFigure):
    plt = pyplot()
    arena_figure = figure_class.live(arena, robot_radius, poses, plt=plt)
    arena_figure.interactive = is_interactive(plt)
    if arena_figure.interactive:
        plt.ion()
        plt.show()
    return arena_figure
