"""What a script draws on r.axes: watched on the live figure by the client (robotarium_client.drawing),
sent as changes through the drawing topic's text, and drawn again by the recording on another figure
at another scale (robotarium_recording.drawing): the same things in the same places, sizes in metres
kept; the live figure skips idle draws nobody sees (no ROS)."""
import subprocess
import sys

import matplotlib.image
import numpy as np
import pytest

from robotarium_client.drawing import WHOLE_AFTER_MESSAGES, DrawingWatcher
from robotarium_core.config import DEFAULT
from robotarium_recording.arena_figure import ArenaFigure, points_per_metre, pyplot, robot_colours
from robotarium_recording.bag import PoseTrack
from robotarium_recording.drawing import DrawingPainter, DrawingState, decode, encode
from robotarium_recording.pictures import plot_trajectories

ARENA = DEFAULT.arena
START = np.array([[0.0, 0.6, -0.6], [0.0, 0.3, -0.3], [0.0, 1.0, 2.0]])


@pytest.fixture
def live():
    plt = pyplot()
    figure = ArenaFigure.live(ARENA, DEFAULT.robot_radius, START, plt=plt)
    yield figure
    plt.close(figure.figure)


def test_the_script_drawing_is_sent_as_changes_and_drawn_again(live):
    ax = live.axes
    watcher = DrawingWatcher(ax, live.own_artists)
    assert watcher.changes(0)["set"] == {}   # the arena's own artists are not the script's
    marker = ax.scatter([0.5], [0.2], s=400, marker="s", facecolors="none", edgecolors="r", linewidth=4, zorder=-2)
    ax.text(0, 0.5, "G0", fontsize=20, color="b")
    (line,) = ax.plot([0, 1], [0, -0.5], "g--", lw=3)
    ax.arrow(-1, -0.5, 0.3, 0.1, width=0.02, color="m")
    ax.imshow(np.linspace(0, 1, 12).reshape(3, 4), extent=(-1.4, -1.0, 0.4, 0.8))
    first = decode(encode(watcher.changes(0)))   # through JSON, as on the topic
    assert first["format"] == 2
    assert sorted(spec["kind"] for spec in first["set"].values()) == ["image", "line", "patch", "scatter", "text"]
    assert watcher.changes(1) is None                      # nothing changed
    marker.set_sizes([400])
    assert watcher.changes(2) is None                      # touched, not changed (scripts do this every step)
    marker.set_offsets([[0.6, 0.1]])
    moved = watcher.changes(3)
    assert moved["set"] == {} and list(moved["move"].values()) == [{"offsets": [[0.6, 0.1]], "sizes": [400.0]}]
    line.remove()
    removed = watcher.changes(4)
    assert len(removed["removed"]) == 1

    state = DrawingState()
    for message in (first, moved, removed):
        state.apply(message)
    video = ArenaFigure.offscreen(ARENA, DEFAULT.robot_radius, START)
    painter = DrawingPainter(video.axes)
    made, _ = painter.paint(state)
    assert len(made) == 4 and len(painter.artists) == 4
    again = next(a for _, a in painter.artists.values() if hasattr(a, "get_offsets"))
    assert np.allclose(again.get_offsets(), [[0.6, 0.1]])
    # A 400 pt^2 marker on the live figure is as many metres wide on the video's figure.
    k = points_per_metre(video.axes) / points_per_metre(ax)
    assert again.get_sizes()[0] == pytest.approx(400 * k * k)
    # ... and the video has more pixels per metre than the live figure (it is sharper).
    assert video.axes.transData.get_matrix()[0, 0] > 1.5 * ax.transData.get_matrix()[0, 0]


def test_a_trail_drawn_with_its_whole_history_every_step_is_sent_as_what_it_grew(live):
    """ekf_experiment.py set_data()s its trails with their whole history every step: sending the
    whole line each time made the run quadratic in its length (a quarter of the script's process
    at 2000 steps, 160 MB of text). A grown line goes as its tail; a reader gets the same line; a
    line changed otherwise goes whole, and so does one not sent whole for WHOLE_AFTER_MESSAGES messages (a
    viewer that matches late finds it in the topic's kept history)."""
    watcher = DrawingWatcher(live.axes, live.own_artists)
    (trail,) = live.axes.plot([0.0], [0.0], "r-")
    messages = [decode(encode(watcher.changes(0)))]
    xs, ys = [0.0], [0.0]
    for step in range(1, WHOLE_AFTER_MESSAGES + 20):
        xs.append(0.001 * step)
        ys.append(np.sin(step / 30))
        trail.set_data(np.array(xs), np.array(ys))
        messages.append(decode(encode(watcher.changes(step))))
    grows = [m for m in messages if m.get("grow")]
    whole = [m for m in messages if m["set"]]
    assert len(grows) == WHOLE_AFTER_MESSAGES + 18 and len(whole) == 2   # the first, and once after the limit
    assert [len(g["x"]) for m in grows for g in m["grow"].values()] == [1] * len(grows)
    assert whole[1]["step"] == WHOLE_AFTER_MESSAGES and not whole[1].get("grow")
    state = DrawingState()
    for message in messages:
        state.apply(message)
    (spec,) = state.specs.values()
    assert spec["x"] == xs and spec["y"] == ys
    late = DrawingState()   # a reader that only has the history since the line was last sent whole
    for message in messages[WHOLE_AFTER_MESSAGES:]:
        late.apply(message)
    assert late.specs == state.specs

    trail.set_data(np.array(xs), np.array(ys))
    assert watcher.changes(900) is None                     # touched, not grown: nothing to send
    xs[0] = 5.0                                             # its history changed: sent whole
    trail.set_data(np.array(xs + [1.0]), np.array(ys + [1.0]))
    changed = watcher.changes(901)
    assert list(changed["set"].values())[0]["x"] == xs + [1.0] and not changed.get("grow")
    trail.set_data(np.array(xs + [1.0, 2.0]), np.array(ys + [1.0, 2.0]))
    trail.set_color("b")                                    # grown and restyled: sent whole
    changed = watcher.changes(902)
    assert list(changed["set"].values())[0]["color"] == [0.0, 0.0, 1.0, 1.0] and not changed.get("grow")
    trail.set_data([9.0], [9.0])                            # shorter: sent whole
    assert list(watcher.changes(903)["set"].values())[0]["x"] == [9.0]


def test_a_trail_that_grows_now_and_then_among_other_changes_is_sent_whole_within_the_kept_history(live):
    """The whole sends are counted in messages, not grows: a trail grown every 10th step while a marker moves every
    step is sent whole again at its first growth once WHOLE_AFTER_MESSAGES messages went."""
    watcher = DrawingWatcher(live.axes, live.own_artists)
    marker = live.axes.scatter([0.0], [0.0], s=100)
    (trail,) = live.axes.plot([0.0], [0.0], "b-")
    messages = []
    for step in range(1200):
        marker.set_offsets([[0.001 * step, 0.0]])
        if step % 10 == 0:
            trail.set_data(np.arange(step // 10 + 1) * 0.01, np.zeros(step // 10 + 1))
        messages.append(watcher.changes(step))
    key = next(k for k, spec in messages[0]["set"].items() if spec["kind"] == "line")
    whole = [i for i, m in enumerate(messages) if key in m["set"]]
    assert len(whole) >= 4 and max(b - a for a, b in zip(whole, whole[1:])) <= WHOLE_AFTER_MESSAGES + 10, whole


def _circles(n, steps):
    k = np.arange(steps + 1)[:, None]
    phase = 2 * np.pi * np.arange(n)[None, :] / n
    x = np.linspace(-1.2, 1.2, n)[None, :] + 0.2 * np.cos(0.05 * k + phase)
    y = 0.6 * np.sin(0.04 * k + phase)
    zeros = np.zeros(steps + 1, dtype=np.int64)
    return PoseTrack(k[:, 0], k[:, 0] * DEFAULT.time_step, zeros, zeros, np.arange(n), x, y, np.zeros_like(x))


def test_the_trajectory_plot_shows_every_robot_in_its_colour_and_the_goals(tmp_path, live):
    n = 20
    track = _circles(n, 120)
    watcher = DrawingWatcher(live.axes, live.own_artists)
    live.axes.scatter([1.4], [0.8], s=900, marker="s", facecolors="none", edgecolors=(0.0, 0.0, 1.0), linewidth=6)
    path = plot_trajectories(track, [watcher.changes(0)], DEFAULT, str(tmp_path / "t.png"), "twenty")
    image = np.round(matplotlib.image.imread(path)[..., :3] * 255).astype(np.int64)
    assert image.shape[:2] == (1000, 1600)
    packed, counts = np.unique(image[..., 0] << 16 | image[..., 1] << 8 | image[..., 2], return_counts=True)
    pixels = dict(zip(packed.tolist(), counts.tolist()))

    def count(rgb):   # pixels of exactly this colour (the middle of a line has it)
        r, g, b = np.round(np.asarray(rgb) * 255).astype(int)
        return pixels.get(int(r) << 16 | int(g) << 8 | int(b), 0)

    for i, colour in enumerate(robot_colours(n)[:, :3]):
        assert count(colour) > 100, "robot %d's colour is not in the plot (%d pixels)" % (i, count(colour))
    faded_blue = [1 - 0.35, 1 - 0.35, 1.0]   # the goal, drawn at alpha 0.35 over white
    assert count(faded_blue) > 100


@pytest.mark.parametrize("patched", ["before the script imports matplotlib", "after"])
def test_headless_idle_draws_are_skipped_and_real_draws_are_not(patched):
    """./robotarium run without a display: a script's canvas.draw_idle() renders nothing (nobody
    sees an Agg canvas; ekf_experiment.py spent 4/5 of its time there), while draw() and
    savefig() still render (their draw events counted). The runner asks for it before the script
    runs, which imports no matplotlib (a script with no figure never pays for it): the patch comes
    with the script's own import. In a process of its own: it patches matplotlib."""
    before = patched.startswith("before")
    code = (
        "import io, sys\n"
        "from robotarium_client.figure import skip_headless_idle_draws\n"
        + ("skip_headless_idle_draws(); assert 'matplotlib' not in sys.modules, 'imported matplotlib'\n" if before else "")
        + "import matplotlib; matplotlib.use('Agg')\n"
        "import matplotlib.pyplot as plt\n"
        "fig, ax = plt.subplots(); ax.plot([0, 1], [0, 1])\n"
        "draws = []; fig.canvas.mpl_connect('draw_event', lambda e: draws.append(1))\n"
        + ("" if before else "fig.canvas.draw_idle(); skip_headless_idle_draws(); skip_headless_idle_draws()\n")
        + "first = len(draws)\n"
        "for _ in range(5): fig.canvas.draw_idle()\n"
        "idle = len(draws) - first\n"
        "fig.canvas.draw(); fig.savefig(io.BytesIO(), format='png')\n"
        "print(first, idle, len(draws) - first - idle)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    # Agg rendered at once before the patch; not after
    assert done.stdout.split() == ["0" if before else "1", "0", "2"], done.stdout
