"""The arena drawer, the video and the trajectory plot (no ROS). What a script draws, watched by the
client and drawn again here: tests/test_drawing.py."""
import imageio_ffmpeg
import matplotlib.image
import numpy as np
import pytest

from robotarium_core.config import DEFAULT
from robotarium_recording.arena_figure import robot_colours
from robotarium_recording.bag import PoseTrack
from robotarium_recording.pictures import plot_trajectories, render_video


def test_robot_colours_are_distinct_for_50_robots():
    colours = robot_colours(50)[:, :3]
    distances = np.linalg.norm(colours[:, None] - colours[None, :], axis=2) + np.eye(50)
    assert distances.min() > 0.02
    twenty = robot_colours(20)[:, :3]
    assert (np.linalg.norm(twenty[:, None] - twenty[None, :], axis=2) + np.eye(20)).min() > 0.09


def _circles(n, steps):
    k = np.arange(steps + 1)[:, None]
    phase = 2 * np.pi * np.arange(n)[None, :] / n
    x = np.linspace(-1.2, 1.2, n)[None, :] + 0.2 * np.cos(0.05 * k + phase)
    y = 0.6 * np.sin(0.04 * k + phase)
    zeros = np.zeros(steps + 1, dtype=np.int64)
    return PoseTrack(k[:, 0], k[:, 0] * DEFAULT.time_step, zeros, zeros, np.arange(n), x, y, np.zeros_like(x))


def test_the_video_is_in_experiment_time_at_1280_by_800(tmp_path):
    track = _circles(3, 89)
    path = render_video(track, [], DEFAULT, str(tmp_path), "three", progress=False)
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(path)
    assert frames == 90 and seconds == pytest.approx(90 * DEFAULT.time_step, abs=0.04)
    reader = imageio_ffmpeg.read_frames(path)
    assert next(reader)["size"] == (1280, 800)
    reader.close()


def test_a_2x_runs_obstacles_are_in_the_plot(tmp_path):
    track = _circles(2, 30)
    wall = [[[-1.2, -0.8], [-1.2, 0.8]]]   # a vertical wall left of the robots' circles
    without = plot_trajectories(track, [], DEFAULT, str(tmp_path / "plain.png"))
    with_wall = plot_trajectories(track, [], DEFAULT, str(tmp_path / "wall.png"), obstacles=wall)
    grey = [np.all(np.abs(matplotlib.image.imread(p)[..., :3] - 0.5) < 0.02, axis=-1).sum() for p in (without, with_wall)]
    assert grey[1] - grey[0] > 1000, grey   # the thick grey line of 2.x's walls
