"""Initial poses, "at goal" checks, plot sizes with 2.x's names (2.1.0 rps/utilities/misc.py).

generate_random_poses and generate_random_positions draw as 2.x does (rejection sampling, numpy's
global generator, so a seeded script gets the same poses); the testbed's own random initial
conditions and charger slots are robotarium_core.rps2's (without 2.x's N limits).
"""
from datetime import datetime

import numpy as np

from robotarium_core import model as _model
from robotarium_core import rps2 as _rps2
from robotarium_core.config import DEFAULT as _DEFAULT

__all__ = ["np", "determine_font_size", "generate_initial_poses", "generate_random_poses",
           "generate_random_positions", "create_at_pose", "create_at_position", "rotation_matrix", "unique_filename"]


def determine_font_size(robotarium_instance, font_height_meters):
    """Font size in points for text `font_height_meters` tall in the arena figure."""
    fig = robotarium_instance._fig
    fig.canvas.draw()
    height_px = fig.get_size_inches()[1] * fig.dpi
    b = robotarium_instance.BOUNDARIES
    return height_px * (font_height_meters / (b[3] - b[2]))


def generate_initial_poses(N, width=3.0, height=1.0):
    """N charger-slot poses along the top and bottom edges, facing into the arena (2.x's name; the
    slots are robotarium_core.rps2.charger_slots', so any N the testbed accepts fits)."""
    return _rps2.charger_slots(N, np.random, _DEFAULT)


def _random_points(N, spacing, width, height):
    assert isinstance(N, int) and N > 0, "N must be a positive integer."
    assert spacing > 0, "spacing must be positive."
    assert width > 0 and height > 0, "width and height must be positive."
    approx_max = int(np.floor((width * height) / (spacing ** 2)))
    assert N <= approx_max, ("Cannot fit %d poses with spacing %.2f m into a %.2f x %.2f m area. Approximate maximum: "
                             "%d." % (N, spacing, width, height, approx_max))
    # 2.x's rejection sampling from the global stream, shared with the testbed's random initial conditions
    positions = _rps2.spaced_random_positions(N, spacing, width, height, np.random, attempts=10000)
    assert positions is not None, ("Could not place %d poses with spacing %.2f m after 10000 attempts. Try reducing N "
                                   "or Spacing." % (N, spacing))
    return positions


def generate_random_poses(N, spacing=0.5, width=3.0, height=1.8):
    """3 x N poses uniformly in a centred width x height box, at least `spacing` apart."""
    positions = _random_points(N, spacing, width, height)
    return np.vstack([positions, np.random.rand(N) * 2 * np.pi - np.pi])


def generate_random_positions(N, spacing=0.5, width=3.0, height=1.8):
    """2 x N positions uniformly in a centred width x height box, at least `spacing` apart."""
    return _random_points(N, spacing, width, height)


def create_at_pose(position_error=0.05, rotation_error=0.2):
    """f(states 3xN, poses 3xN) -> (all there, per-robot boolean mask)."""
    def check_at_pose(states, poses):
        assert states.shape[0] == 3 and poses.shape[0] == 3, "states and poses must be 3xN."
        assert poses.shape[1] == states.shape[1], "states and poses must have the same number of columns."
        return _rps2.at_pose(states, poses, position_error, rotation_error)
    return check_at_pose


def create_at_position(position_error=0.05):
    """f(states 2+xN, positions 2xN) -> (all there, per-robot boolean mask)."""
    def check_at_position(states, positions):
        assert states.shape[0] >= 2 and positions.shape[0] == 2, "states must be at least 2xN, positions 2xN."
        assert positions.shape[1] == states.shape[1], "states and positions must have the same number of columns."
        mask = _model.at_position_mask(states, positions, position_error)
        return bool(np.all(mask)), mask
    return check_at_position


def rotation_matrix(theta):
    """3 x 3 x N rotation matrices about z."""
    theta = np.atleast_1d(theta).flatten()
    R = np.zeros((3, 3, len(theta)))
    R[0, 0], R[0, 1], R[1, 0], R[1, 1], R[2, 2] = np.cos(theta), -np.sin(theta), np.sin(theta), np.cos(theta), 1.0
    return R


def unique_filename(file_name):
    """file_name + a timestamp + .npy."""
    return "%s_%s.npy" % (file_name, datetime.now().strftime("%Y_%m_%d_%H_%M_%S"))
