"""The video made while the run goes (robotarium_recording.live_video): frames drawn from what was heard, a
second behind the newest step, are byte for byte the video the bag gives, and anything heard otherwise than
the bag holds it (a drawing that came after its frame, a missed pose row, another run) is caught, so the
video is then made from the bag. No ROS here: the end to end run is in tests/test_run_results.py."""
import os

import imageio_ffmpeg
import numpy as np
import pytest

from robotarium_client.drawing import DrawingWatcher
from robotarium_core.config import DEFAULT
from robotarium_recording import pictures
from robotarium_recording.arena_figure import ArenaFigure, pyplot
from robotarium_recording.bag import PoseTrack
from robotarium_recording.drawing import decode, encode
from robotarium_recording.live_video import LAG, LiveFrames

RUN = "live_20261130-120000"
SETTINGS = "run_id: %s\napi: ''\nnumber_of_robots: 3\n" % RUN
LAG_STEPS = int(round(LAG / DEFAULT.time_step))


def _track(steps, missing=()):
    """Three robots on circles, one row per step but `missing` (a late recorder, a real-time tick's gap)."""
    k = np.array([s for s in range(steps + 1) if s not in missing])
    phase = 2 * np.pi * np.arange(3)[None, :] / 3
    x = np.linspace(-1.0, 1.0, 3)[None, :] + 0.2 * np.cos(0.05 * k[:, None] + phase)
    y = 0.5 * np.sin(0.04 * k[:, None] + phase)
    zeros = np.zeros(len(k), dtype=np.int64)
    return PoseTrack(k, k * DEFAULT.time_step, zeros, zeros, np.arange(3), x, y, 0.1 * k[:, None] + phase)


def _drawn(moves):
    """A goal marker and a label drawn at step 0, the marker moved at each step of `moves` (as a script's
    client sends them)."""
    plt = pyplot()
    figure = ArenaFigure.live(DEFAULT.arena, DEFAULT.robot_radius, np.zeros((3, 3)), plt=plt)
    watcher = DrawingWatcher(figure.axes, figure.own_artists)
    marker = figure.axes.scatter([0.5], [0.2], s=400, marker="s", facecolors="none", edgecolors="r", linewidth=4)
    figure.axes.text(-1.2, 0.8, "goal", fontsize=12, color="b")
    messages = [decode(encode(watcher.changes(0)))]
    for step in moves:
        marker.set_offsets([[0.5 - 0.01 * step, 0.2 - 0.004 * step]])
        messages.append(decode(encode(watcher.changes(step))))
    plt.close(figure.figure)
    return messages


@pytest.fixture
def drawings():
    return _drawn([50])


def _heard(track, drawings, drawing_late_by=0):
    """LiveFrames fed as a lockstep run's messages arrive: the configuration and settings at the start, then
    for each step its poses, the script's drawing message of that step (or `drawing_late_by` steps later)
    and its command array."""
    frames = LiveFrames()
    frames.run_id, frames.config_text = RUN, DEFAULT.to_yaml()
    frames.experiment(SETTINGS)
    pending = list(drawings)
    for row, step in enumerate(track.steps):
        frames.poses(RUN, step, track.ids, track.x[row], track.y[row], track.theta[row])
        while pending and pending[0]["step"] + drawing_late_by <= step:
            frames.drawing(pending.pop(0))
        frames.command()   # the script's step() call for these poses: its drawing, then its command
        yield frames


def _live_video(tmp_path, track, drawings, drawing_late_by=0):
    """The live video as LiveVideo._draw makes it: (LiveFrames, its renderer, its path)."""
    video = composite = None
    heard = _heard(track, drawings, drawing_late_by)
    for frames in heard:
        ready = frames.ready()
        if ready is not None:
            break
    config, title, obstacles, first = ready
    final = False
    while True:
        wanted, due = frames.batch(composite, LAG_STEPS, final)
        if wanted != composite:
            if video is not None:
                video.abort()
            video = pictures.Video(str(tmp_path / "live.mp4"), pictures.ffmpeg_path(), config, first, title,
                                   obstacles, composite=wanted, progress=False)
            composite = wanted
        for step, poses, new in due:
            video.frame(step, poses, new)
        if final:
            return frames, composite, video.close()
        final = next(heard, None) is None


def test_the_live_video_is_the_bags_byte_for_byte(tmp_path, drawings):
    track = _track(120, missing=(7, 8, 60))
    frames, composite, live = _live_video(tmp_path, track, drawings)
    assert composite and frames.differs(track, drawings, DEFAULT, RUN, (), composite) == ""
    from_bag = pictures.render_video(track, drawings, DEFAULT, str(tmp_path), RUN, progress=False)
    assert open(live, "rb").read() == open(from_bag, "rb").read()
    assert imageio_ffmpeg.count_frames_and_secs(live)[0] == 121   # every step, a missing row's frame included
    assert os.path.getsize(live) > 10_000


def test_a_drawing_that_changes_every_step_goes_to_the_blitter_as_the_bags_does(tmp_path):
    """Changes at the first steps only stay with the Compositor; a marker moved every step switches the
    live video to the Blitter (begun again from the first frame): the bag's video both times."""
    track = _track(80)
    for moves, expected in ((range(1, 7), True), (range(1, 81), False)):
        drawings = _drawn(moves)
        frames, composite, live = _live_video(tmp_path, track, drawings)
        assert composite == expected and frames.differs(track, drawings, DEFAULT, RUN, (), composite) == ""
        from_bag = pictures.render_video(track, drawings, DEFAULT, str(tmp_path), RUN, progress=False)
        assert open(live, "rb").read() == open(from_bag, "rb").read()


def test_a_drawing_heard_after_its_frame_is_caught(tmp_path, drawings):
    track = _track(120)
    frames, _, _ = _live_video(tmp_path, track, drawings, drawing_late_by=LAG_STEPS + 5)
    assert frames.differs(track, drawings, DEFAULT, RUN, ()) == "another drawing, or one heard late"


def test_a_pose_row_the_live_video_missed_or_another_run_is_caught(tmp_path, drawings):
    track = _track(60)
    frames, _, _ = _live_video(tmp_path, _track(60, missing=(30,)), drawings)
    assert frames.differs(track, drawings, DEFAULT, RUN, ()).startswith("other poses")
    assert frames.differs(track, drawings, DEFAULT, "another_run", ()).startswith("another run")
    assert frames.differs(track, drawings, DEFAULT, RUN, [[[0, 0], [1, 1]]]) == "other obstacles"


def test_asked_again_after_it_was_closed_it_leaves_the_video_to_the_bag(tmp_path):
    """The results made a second time (a full disk refused the first folder): the live video, closed by then,
    says no, so the bag's video is made; its own folder is gone."""
    from robotarium_recording.live_video import LiveVideo
    live = LiveVideo("/robotarium", str(tmp_path / "started.json"), context=None)
    assert os.path.isdir(live.folder)
    live.close()
    track = _track(10)
    assert not live.video_for(track, [], DEFAULT, RUN, (), str(tmp_path / "run.mp4"))
    assert live.why_not == "closed" and not os.path.exists(live.folder) and not (tmp_path / "run.mp4").exists()
