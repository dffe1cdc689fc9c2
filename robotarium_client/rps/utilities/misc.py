"""Initial conditions, "close enough" tests and plot sizes (guide section 4.7).

Like rps, this module carries matplotlib.pyplot as plt, and `from rps.utilities.misc import *`
brings `np` and `plt` into a script (the guide's plotting examples rely on it). pyplot is imported
when `plt` is first asked for (the star import asks), not by `import rps.robotarium`, which
loads this module too: a script that never plots saves pyplot's import (about 0.3 s).

Differences from rps 0.0.0, each marked "Fix:" in the code:
* at_position compared against an undefined name (poses) and always raised NameError.
* generate_initial_conditions accepted any N > 0; the testbed takes 1 to 50 robots.
* determine_marker_size / determine_font_size failed with an AttributeError on a Robotarium
  made with show_figure=False (its axes is an empty list); they now say what is wrong.
"""
import numpy as np

from robotarium_core import model
from robotarium_core.model import MAX_ROBOTS, MIN_ROBOTS
from rps.utilities import RobotariumError, _check_array, _check_number, _describe


def __getattr__(name):
    if name == "plt":   # (PEP 562) imported on first use, then a plain attribute
        import matplotlib.pyplot as plt
        globals()["plt"] = plt
        return plt
    raise AttributeError("module %r has no attribute %r" % (__name__, name))


__all__ = [
    "np",
    "plt",   # noqa: F822 - made by __getattr__ on first use
    "generate_initial_conditions",
    "at_pose",
    "at_position",
    "determine_marker_size",
    "determine_font_size",
]


def generate_initial_conditions(N, spacing=0.3, width=3, height=1.8):
    """Return 3xN random poses on a grid of pitch `spacing` in a width x height area at the origin (guide 4.7.1).

    The algorithm and its draws from numpy's global random state are those of rps, so a script
    that seeds numpy (np.random.seed) gets the same poses as on the Robotarium's simulator:
    N distinct grid cells from np.random.choice, then one np.random.rand() heading per robot.
    Distinct cells are at least `spacing` apart.

    N: number of robots, 1 to 50. spacing, width, height: > 0 (m).
    """
    where = "generate_initial_conditions"
    N = _check_number(N, "N (number of robots)", where, low=MIN_ROBOTS, high=MAX_ROBOTS, integer=True)
    spacing = _check_number(spacing, "spacing", where, low=0, strict=True)
    width = _check_number(width, "width", where, low=0, strict=True)
    height = _check_number(height, "height", where, low=0, strict=True)

    # Grid columns and rows that fit (rps's arithmetic, kept bit for bit).
    x_range = int(np.floor(width / spacing))
    y_range = int(np.floor(height / spacing))
    if x_range == 0:
        raise RobotariumError("%s: spacing must be at most width; received spacing %r for width %r."
                              % (where, spacing, width))
    if y_range == 0:
        raise RobotariumError("%s: spacing must be at most height; received spacing %r for height %r."
                              % (where, spacing, height))
    if x_range * y_range <= N:
        # rps's condition (strict: one cell fewer than the grid holds).
        raise RobotariumError(
            "%s: N must be less than the %d grid cells that a %r x %r m area holds at spacing %r; received N=%d."
            % (where, x_range * y_range, width, height, spacing, N))

    # rps's grid and draws, which the simulator's random initial conditions share: N distinct cells
    # from np.random.choice (numbered from 1, (column, row) = divmod(cell, y_range)), then one heading
    # per robot from the global stream (random(N) is rps's loop of rand()).
    return model.random_initial_conditions(N, np.random, spacing, width, height)


def _check_error(value, name, where):
    return _check_number(value, name, where, low=0, allow_inf=True)


def at_pose(states, poses, position_error=0.05, rotation_error=0.2):
    """Which robots are within position_error (m) and rotation_error (rad) of their poses (guide 4.7.1).

    states, poses: 3xN [x; y; theta]. Heading errors are wrapped to (-pi, pi].
    Returns, like rps, the tuple from np.nonzero: `at_pose(...)[0]` is the index array and
    `np.size(at_pose(...))` the number of robots there.
    """
    where = "at_pose"
    states = _check_array(states, "states", where, 3, what="of unicycle states [x; y; theta]")
    poses = _check_array(poses, "poses", where, 3, states.shape[1],
                         "of desired poses [x; y; theta], one column per column of states")
    position_error = _check_error(position_error, "position_error", where)
    rotation_error = _check_error(rotation_error, "rotation_error", where)

    return np.nonzero(model.at_pose_mask(states, poses, position_error, rotation_error))


def at_position(states, points, position_error=0.02):
    """Which robots are within position_error (m) of their points (guide 4.7.2).

    states: 3xN [x; y; theta]; points: 2xN [x; y]. Returns the np.nonzero tuple, as at_pose.
    """
    where = "at_position"
    states = _check_array(states, "states", where, 3, what="of unicycle states [x; y; theta]")
    # Fix: rps compared states.shape[1] with poses.shape[1], an undefined name (NameError).
    points = _check_array(points, "points", where, 2, states.shape[1],
                          "of desired points [x; y], one column per column of states")
    position_error = _check_error(position_error, "position_error", where)
    return np.nonzero(model.at_position_mask(states, points, position_error))


def _figure_of(robotarium_instance, where):
    """The instance's axes and boundaries [x_min, y_min, width, height], checked."""
    axes = getattr(robotarium_instance, "axes", None)
    if not (hasattr(axes, "transData") and hasattr(axes, "get_window_extent")):
        raise RobotariumError(
            "%s: robotarium_instance must have a matplotlib Axes in .axes (create the Robotarium with "
            "show_figure=True); received .axes = %s." % (where, _describe(axes)))
    boundaries = getattr(robotarium_instance, "boundaries", None)
    try:
        values = [float(b) for b in boundaries]
    except (TypeError, ValueError):
        values = []
    if len(values) != 4 or not np.all(np.isfinite(values)) or values[2] <= 0 or values[3] <= 0:
        raise RobotariumError(
            "%s: robotarium_instance.boundaries must be [x_min, y_min, width, height] with a positive "
            "width and height; received %s." % (where, _describe(boundaries) if not isinstance(
                boundaries, (list, tuple)) else repr(boundaries)))
    return axes, values


def determine_marker_size(robotarium_instance, marker_size_meters):
    """Scatter marker size (the `s` argument) for a marker `marker_size_meters` across (guide 4.7.3).

    rps's formula, kept so that plots look the same as on the Robotarium's simulator: the display
    x coordinate of the data point (width, height) times marker_size_meters / width, squared
    (scatter sizes are areas). Call it again after the window is resized.
    """
    where = "determine_marker_size"
    axes, boundaries = _figure_of(robotarium_instance, where)
    size = _check_number(marker_size_meters, "marker_size_meters", where, low=0)
    display = axes.transData.transform(np.array([[boundaries[2], boundaries[3]]]))
    return (display[0, 0] * (size / boundaries[2])) ** 2.


def determine_font_size(robotarium_instance, font_height_meters):
    """Font size for text `font_height_meters` tall (guide 4.7.4).

    rps's formula, kept for the same look: the axes' height in display units divided by the arena
    width (boundaries[2], as rps does), times font_height_meters.
    """
    where = "determine_font_size"
    axes, boundaries = _figure_of(robotarium_instance, where)
    height = _check_number(font_height_meters, "font_height_meters", where, low=0)
    y1, y2 = axes.get_window_extent().get_points()[:, 1]
    return (y2 - y1) / boundaries[2] * height
