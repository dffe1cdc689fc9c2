"""Results benchmark: what the video of a run costs, and what recording the script's drawing costs.

1. Rendering: a synthetic 5,000-step run (the length of the guide's longest scripts) of N robots
   driving circles, with a drawing like the guide's plotting scripts (a goal square and a label per
   robot, a marker following each robot, changed every step), rendered to run.mp4 (1280 x 800,
   one frame per step) by robotarium_recording.pictures.render_video, the function ./robotarium run
   and ./robotarium report use. Printed: seconds, frames per second, and the ratio to the run's
   own time (5,000 steps x 0.033 s = 165 s of experiment time, its wall time in real time).
2. Capture: the client's per-step cost of watching the script's drawing
   (robotarium_client.drawing.DrawingWatcher.changes) for the same drawing on the live figure, in
   microseconds per step, and as a share of a lockstep step through the stack (docs/benchmarks.md, the stack benchmark:
   170 steps/s at N = 20, so 5.9 ms a step).
3. Trails: a script that set_data()s two trails with their whole history every step (ekf_experiment.py's
   pattern), --trail-steps steps: the watcher's and the topic's encoding per step over the first and the last
   tenth of the run (flat: a grown line goes as its tail), and the drawing topic's bytes in all.
Run: ./robotarium bench results [--steps 5000] [--robots 6 20 50] [--trail-steps 2000]
"""
import argparse
import os
import platform
import tempfile
import time

import numpy as np

from robotarium_core.config import DEFAULT
from robotarium_recording.bag import PoseTrack

LOCKSTEP_STEP = 1 / 170.1   # s, docs/benchmarks.md: the whole stack in lockstep at N = 20


def synthetic_run(n, steps):
    """Poses of N robots on circles, step 0..steps."""
    k = np.arange(steps + 1)[:, None]
    phase = 2 * np.pi * np.arange(n)[None, :] / n
    centre_x = np.linspace(-1.1, 1.1, n)[None, :]
    x = centre_x + 0.25 * np.cos(0.01 * k + phase)
    y = 0.5 * np.sin(0.013 * k + phase)
    theta = np.arctan2(np.gradient(y, axis=0), np.gradient(x, axis=0))
    empty = np.zeros(steps + 1, dtype=np.int64)
    return PoseTrack(k[:, 0], k[:, 0] * DEFAULT.time_step, empty, empty, np.arange(n), x, y, theta)


def live_drawing(n, track):
    """The guide's plotting pattern on a live figure: goal squares, labels, a marker per robot."""
    from robotarium_client.drawing import DrawingWatcher
    from robotarium_recording.arena_figure import ArenaFigure, pyplot
    plt = pyplot()
    figure = ArenaFigure.live(DEFAULT.arena, DEFAULT.robot_radius, np.vstack((track.x[0], track.y[0], track.theta[0])),
                              plt=plt)
    ax = figure.axes
    colours = np.random.default_rng(1).random((n, 3))
    for i in range(n):
        ax.scatter(track.x[-1, i], track.y[-1, i], s=300, marker="s", facecolors="none", edgecolors=colours[i],
                   linewidth=4, zorder=-2)
        ax.text(track.x[-1, i], track.y[-1, i], "G%d" % i, fontsize=12, ha="center", va="center", zorder=-2)
    markers = [ax.scatter(track.x[0, i], track.y[0, i], s=200, marker="o", facecolors="none",
                          edgecolors=colours[i], linewidth=3) for i in range(n)]
    return DrawingWatcher(ax, figure.own_artists), markers, plt, figure


def bench(n, steps, work):
    from robotarium_recording.pictures import render_video
    track = synthetic_run(n, steps)
    watcher, markers, plt, figure = live_drawing(n, track)
    messages = []
    capture = 0.0
    for k in range(steps + 1):
        for i, marker in enumerate(markers):   # what the script does each step
            marker.set_offsets([[track.x[k, i], track.y[k, i]]])
            marker.set_sizes([200])
        started = time.perf_counter()
        message = watcher.changes(k)
        capture += time.perf_counter() - started
        if message is not None:
            messages.append(message)
    plt.close(figure.figure)
    started = time.perf_counter()
    path = render_video(track, messages, DEFAULT, work, "bench N=%d" % n, progress=False, name="bench_%d" % n)
    render = time.perf_counter() - started
    return render, capture / (steps + 1), os.path.getsize(path)


def trails(steps):
    """(µs per step over the first tenth, over the last tenth, bytes in all) of capturing and encoding two trails
    set_data() with their whole history every step."""
    import robotarium_recording as recording
    from robotarium_client.drawing import DrawingWatcher
    from robotarium_recording.arena_figure import ArenaFigure, pyplot
    track = synthetic_run(2, steps)
    plt = pyplot()
    figure = ArenaFigure.live(DEFAULT.arena, DEFAULT.robot_radius,
                              np.vstack((track.x[0], track.y[0], track.theta[0])), plt=plt)
    lines = [figure.axes.plot([], [], "-", lw=2)[0] for _ in range(2)]
    watcher = DrawingWatcher(figure.axes, figure.own_artists)
    per_step, size = [], 0
    for k in range(steps + 1):
        for i, line in enumerate(lines):
            line.set_data(track.x[:k + 1, i], track.y[:k + 1, i])
        started = time.process_time()
        message = watcher.changes(k)
        text = recording.encode_drawing(message) if message is not None else ""
        per_step.append(time.process_time() - started)
        size += len(text)
    plt.close(figure.figure)
    tenth = max(1, len(per_step) // 10)
    return 1e6 * np.mean(per_step[:tenth]), 1e6 * np.mean(per_step[-tenth:]), size


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--robots", type=int, nargs="+", default=[6, 20, 50])
    parser.add_argument("--trail-steps", type=int, default=2000)
    args = parser.parse_args()
    run_time = args.steps * DEFAULT.time_step
    print("%s, %s, Python %s, load average %.1f" % (time.strftime("%Y-%m-%d"), platform.machine(),
                                                   platform.python_version(), os.getloadavg()[0]))
    print("video: %d steps = %.0f s of experiment time, 1280 x 800, one frame per step" % (args.steps, run_time))
    print("| N | render (s) | frames/s | render / run time | video MB | capture per step (us) | capture / lockstep step |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for n in args.robots:
            render, capture, size = bench(n, args.steps, work)
            print("| %d | %.1f | %.0f | %.2f | %.1f | %.0f | %.1f %% |" % (
                n, render, (args.steps + 1) / render, render / run_time, size / 1e6, capture * 1e6,
                100 * capture / LOCKSTEP_STEP), flush=True)
    first, last, size = trails(args.trail_steps)
    print("trails: two lines set_data() with their whole history every step, %d steps: capture and encoding %.0f us a "
          "step over the first tenth, %.0f us over the last; the drawing topic's text %.2f MB in all"
          % (args.trail_steps, first, last, size / 1e6))


if __name__ == "__main__":
    main()
