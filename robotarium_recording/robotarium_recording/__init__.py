"""Recording of Robotarium runs: bag I/O (`bag` reads, `bag_writer` writes, `schema`: the message
definitions and QoS profiles they store), the recorder, replay and view nodes, and the results of
a run made from its bag alone (`results`, `pictures`, `page`).

What other packages use of it is the public API below, imported as `import robotarium_recording
as recording`: a run's bag and results, the replay, view and report commands, and two things the
client shares with the results: the arena drawer (the live figure is the video's, `ArenaFigure`)
and the drawing topic's text (`encode_drawing`, read back from every bag by `drawing`). The
client's own side of the live figure and of a script's drawing is in robotarium_client (`figure`,
`drawing`). The import costs nothing: each name loads its module on first use (matplotlib and the
bag reader's types take seconds to import).
"""
import importlib

_API = {
    # name: (module, its name there)
    "ArenaFigure": ("arena_figure", "ArenaFigure"),              # the one arena drawer (live, video, replay)
    "is_interactive": ("arena_figure", "is_interactive"),
    "pyplot": ("arena_figure", "pyplot"),
    "points_per_metre": ("arena_figure", "points_per_metre"),
    "encode_drawing": ("drawing", "encode"),                    # a drawing change as the drawing topic's text
    "Bag": ("bag", "Bag"),                                      # a recorded run, read
    "recover_bag": ("bag", "recover_bag"),                      # a bag nothing will close, made readable
    "write_results": ("results", "write_results"),              # report, plot, video and page of a run's bag
    "preload_results": ("results", "preload"),                  # their imports, ahead of time
    "LiveVideo": ("live_video", "LiveVideo"),                   # the video, made while the run goes
    "live_video_enabled": ("live_video", "enabled"),
    "write_page": ("page", "write_page"),                       # the results page of a run folder
    "ViewProcess": ("view_node", "ViewProcess"),                # the Foxglove view in a process of its own
    "add_view_arguments": ("view_node", "add_view_arguments"),
    # The replay, view and report commands: main(argv) parses its own arguments; add_arguments(parser)
    # and the function that takes the parsed ones serve `ros2 robotarium <verb>`.
    "replay_main": ("replay_node", "main"),                     # ./robotarium replay
    "replay_arguments": ("replay_node", "add_arguments"),
    "replay": ("replay_node", "replay"),
    "view_main": ("view_node", "main"),                         # ./robotarium view
    "view_arguments": ("view_node", "add_arguments"),
    "view": ("view_node", "view"),
    "report_main": ("results", "main"),                         # ./robotarium report
    "report_arguments": ("results", "add_report_arguments"),
    "report": ("results", "report"),
}
__all__ = sorted(_API)


def __getattr__(name):
    if name not in _API:
        raise AttributeError("module %r has no attribute %r" % (__name__, name))
    module, attribute = _API[name]
    value = getattr(importlib.import_module("%s.%s" % (__name__, module)), attribute)
    globals()[name] = value   # once
    return value
