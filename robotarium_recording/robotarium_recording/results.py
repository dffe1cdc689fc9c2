"""The Robotarium's results for a recorded run, made from its bag alone (no ROS needed).

The Robotarium's results page (guide §1.3.2) gives back the experiment settings, a video of the
run, the printed output and data files. From a bag folder this makes, beside the bag:
  report.txt        the debug report of rps.Robotarium.call_at_scripts_end(), recomputed from the
                    recorded poses and safe commands with robotarium_core.model's own counting
                    functions, then the run's settings and a cross-check against the counters the
                    testbed published (status topic);
  trajectories.png  the arena with every robot's path, start (open circle) and end (robot drawn
                    to scale with its heading);
  run.mp4           the run replayed at 30 frames a second of simulated time (ffmpeg from the
                    imageio-ffmpeg wheel), or run.gif with Pillow when no encoder is found.

How the report is recomputed, as the simulator counts (robotarium_core.model.Testbed.step): step
k+1 counts collisions and robots outside the arena on the poses of step k (before the move) and
an actuator-limit iteration when the commands in force exceed the wheel limits. In lockstep mode
the k-th valid command array on cmd_safe is exactly the one applied at step k; in real-time mode
the commands in force at a tick are the ones stamped before that tick's poses, stopped after the
0.5 s timeout, which can differ from the simulator for a command that crossed a tick (the
cross-check then says so).

Usage: ./robotarium report BAG [--out DIR] [--no-video]   (BAG: a run folder under bags/)
"""
import argparse
import json
import os
import sys

import numpy as np

from robotarium_core import model
from robotarium_recording.bag import Bag

FPS = 30
ROBOT_COLORS = "tab10"


# -- the report ----------------------------------------------------------------------------------

def _run_settings(bag):
    """experiment, run id, mode, N and the testbed's final counters from the status topic."""
    running = [s for s in bag.statuses() if s.state == 1]
    if not running:
        return {"experiment": "", "run_id": "", "mode": "", "number_of_robots": 0, "final": None}
    last_step = max(s.step for s in running)
    final = [s for s in running if s.step == last_step][-1]   # the simulator's last word: counters, end reason
    return {"experiment": final.experiment, "run_id": final.run_id, "mode": final.mode,
            "number_of_robots": int(final.number_of_robots), "final": final}


def _commands_in_force_lockstep(commands, n, steps):
    """(velocities 2 x N, requested_exceeds_limits) in force at each step 1..steps: the k-th
    valid array sets them."""
    velocities = np.zeros((2, n))
    applied = 0
    for cmd in commands:
        if applied >= steps:
            break
        if model.check_commands(cmd.ids, cmd.v, cmd.omega, n) is not None:
            continue   # the simulator drops it without stepping
        velocities[0, cmd.ids] = cmd.v
        velocities[1, cmd.ids] = cmd.omega
        applied += 1
        yield velocities, cmd.requested_exceeds_limits
    return applied


def _commands_in_force_realtime(commands, n, tick_ns, timeout):
    """(velocities, requested_exceeds_limits) in force at each tick (stamps of the poses it
    produced), with the simulator's 0.5 s command timeout."""
    velocities = np.zeros((2, n))
    since = np.full(n, -np.inf)
    flag = False
    valid = [c for c in commands if model.check_commands(c.ids, c.v, c.omega, n) is None]
    valid.sort(key=lambda c: c.stamp_ns or c.log_ns)
    k = 0
    for t in tick_ns:
        while k < len(valid) and (valid[k].stamp_ns or valid[k].log_ns) < t:
            c = valid[k]
            velocities[0, c.ids], velocities[1, c.ids] = c.v, c.omega
            since[c.ids] = (c.stamp_ns or c.log_ns) * 1e-9
            flag = c.requested_exceeds_limits
            k += 1
        stale = (t * 1e-9 - since > timeout) & np.any(velocities != 0, axis=0)
        if stale.any():
            velocities[:, stale] = 0.0
            flag = False
        yield velocities, flag


def recompute(bag):
    """The debug report's numbers from the bag: a dict with iterations, collisions,
    boundary_violations, actuator_limit_iterations, report (the exact text rps prints),
    settings, testbed (the status counters, or None), mismatches (list of strings), notes."""
    if not isinstance(bag, Bag):
        bag = Bag(bag)
    settings = _run_settings(bag)
    config = bag.config()   # the numbers the run was made with, not today's defaults
    track = bag.poses()
    notes = []
    n = track.x.shape[1] if track.x.size else settings["number_of_robots"]
    steps = int(track.steps[-1]) if len(track.steps) else 0
    by_step = {int(s): i for i, s in enumerate(track.steps)}
    missing = [s for s in range(steps) if s not in by_step]
    if missing:
        notes.append("poses of %d step(s) are missing from the bag (first: step %d); they are not counted."
                     % (len(missing), missing[0]))
    collisions = boundary = 0
    for s in range(steps):
        if s in by_step:
            i = by_step[s]
            poses = np.vstack((track.x[i], track.y[i], track.theta[i]))
            collisions += model.count_collisions(poses, config.robot_diameter)
            boundary += int(np.count_nonzero(model.outside_arena(poses, config.arena)))

    commands = bag.commands("cmd_safe")
    actuator = 0
    if settings["mode"] == "realtime":
        ticks = [int(track.stamp_ns[by_step[s]]) for s in range(1, steps + 1) if s in by_step]
        for velocities, requested_over in _commands_in_force_realtime(commands, n, ticks, config.command_timeout):
            actuator += model.is_actuator_limit_iteration(velocities, requested_over, **config.limits)
    else:
        applied = 0
        for velocities, requested_over in _commands_in_force_lockstep(commands, n, steps):
            actuator += model.is_actuator_limit_iteration(velocities, requested_over, **config.limits)
            applied += 1
        if applied != steps:
            notes.append("%d valid command arrays on cmd_safe for %d steps: the bag is missing commands "
                         "(recorder started late or was killed?)." % (applied, steps))

    result = {"iterations": steps, "collisions": collisions, "boundary_violations": boundary,
              "actuator_limit_iterations": actuator, "number_of_robots": n, "settings": settings,
              "report": model.debug_report(steps, boundary, collisions, actuator, config.time_step), "notes": notes,
              "config": config,
              "mismatches": [], "testbed": None}
    final = settings["final"]
    if final is not None:
        testbed = {"iterations": int(final.step), "collisions": int(final.collisions),
                   "boundary_violations": int(final.boundary_violations),
                   "actuator_limit_iterations": int(final.actuator_limit_iterations),
                   "command_timeouts": int(final.command_timeouts),
                   "commands_accepted": int(final.commands_accepted),
                   "safety_interventions": int(final.safety_interventions),
                   "dropped": _dropped(final), "end_reason": getattr(final, "end_reason", "")}
        result["testbed"] = testbed
        for key in ("iterations", "collisions", "boundary_violations", "actuator_limit_iterations"):
            if testbed[key] != result[key]:
                result["mismatches"].append("%s: %d from the bag, %d counted by the testbed"
                                            % (key.replace("_", " "), result[key], testbed[key]))
    else:
        notes.append("no status of the running experiment in the bag: nothing to cross-check against.")
    return result


def _dropped(status):
    """{input: {reason: count}} of the arrays the testbed dropped (a TestbedStatus); bags recorded
    before the counts by input and reason have three counts of the simulator's input."""
    if hasattr(status, "dropped_cmd_safe"):
        return {name: {reason: int(getattr(counts, reason)) for reason in model.DROP_REASONS}
                for name, counts in (("cmd_requested", status.dropped_cmd_requested),
                                     ("cmd_safe", status.dropped_cmd_safe))}
    return {"cmd_safe": {reason: int(getattr(status, "dropped_" + reason, 0)) for reason in model.DROP_REASONS}}


def report_text(bag, numbers):
    """report.txt: the debug report exactly as rps prints it, then settings and the cross-check."""
    s = numbers["settings"]
    lines = [numbers["report"].rstrip("\n"), "", "##### RUN (recomputed from the recording) #####",
             "bag:          %s%s" % (bag.path, "" if bag.complete else "  (not closed: recorder stopped early; "
                                     "every complete chunk was read)"),
             "experiment:   %s   run id: %s   mode: %s" % (s["experiment"] or "?", s["run_id"] or "?", s["mode"] or "?"),
             "robots:       %d" % numbers["number_of_robots"],
             "steps:        %d (%.2f s of simulated time; the recording spans %.2f s of wall time)"
             % (numbers["iterations"], numbers["iterations"] * numbers["config"].time_step, bag.duration_ns * 1e-9),
             "config:       arena %s, command timeout %g s, time step %g s, robot diameter %g m%s" % (
                 list(numbers["config"].arena), numbers["config"].command_timeout, numbers["config"].time_step,
                 numbers["config"].robot_diameter, "" if bag.topic("config", required=False) in bag.topics
                 else " (defaults: this bag predates recorded configurations)")]
    t = numbers["testbed"]
    if t is not None:
        lines.append("cross-check:  %s" % ("collisions, boundary violations, actuator-limit iterations and steps "
                                          "agree with the testbed's counters" if not numbers["mismatches"]
                                          else "DIFFERS: " + "; ".join(numbers["mismatches"])))
        lines.append("testbed:      %d command timeouts, %d command arrays accepted, %d safety interventions" % (
            t["command_timeouts"], t["commands_accepted"], t["safety_interventions"]))
        for name, counts in t["dropped"].items():
            lines.append("dropped:      %s: %s" % (name, ", ".join("%d %s" % (n, reason) for reason, n in counts.items()
                                                                 if n) or "none"))
        if t["end_reason"]:
            lines.append("ended:        %s" % t["end_reason"])
    lines += ["note:         " + note for note in numbers["notes"]]
    lines.append("messages:     " + ", ".join("%s %d" % (topic, info.count) for topic, info in sorted(bag.topics.items())))
    return "\n".join(lines) + "\n"


# -- pictures -------------------------------------------------------------------------------------

def _pyplot():
    import matplotlib
    if not os.environ.get("DISPLAY") and not os.environ.get("MPLBACKEND"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def arena_axes(ax, arena=(model.ARENA_X_MIN, model.ARENA_X_MAX, model.ARENA_Y_MIN, model.ARENA_Y_MAX), margin=0.1):
    """The arena rectangle on `ax`, to scale, metres on both axes."""
    from matplotlib.patches import Rectangle
    x0, x1, y0, y1 = arena
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, lw=1.5, ec="black"))
    ax.set_xlim(x0 - margin, x1 + margin)
    ax.set_ylim(y0 - margin, y1 + margin)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return ax


class ArenaView:
    """The arena with N robots drawn to scale (circles of the robot diameter and a heading line);
    update() moves them. Used by the video here and by `replay --figure`.

    blit=True (videos): the static part (arena, axes, title) is rendered once and frame() only
    redraws the robots and the time label over it, several times faster than a full redraw.
    """

    def __init__(self, number_of_robots, title="", figsize=(6.4, 4.4), dpi=100, plt=None, blit=False):
        from matplotlib.collections import EllipseCollection, LineCollection
        plt = plt or _pyplot()
        self.fig, self.ax = plt.subplots(figsize=figsize, dpi=dpi)
        arena_axes(self.ax)
        self.ax.set_title(title, fontsize=9)
        colors = plt.get_cmap(ROBOT_COLORS)(np.arange(number_of_robots) % 10)
        self.bodies = EllipseCollection(
            np.full(number_of_robots, model.ROBOT_DIAMETER), np.full(number_of_robots, model.ROBOT_DIAMETER),
            np.zeros(number_of_robots), units="xy", offsets=np.zeros((number_of_robots, 2)),
            offset_transform=self.ax.transData, facecolors=colors, edgecolors="black", linewidths=0.5, alpha=0.85)
        self.ax.add_collection(self.bodies)
        self.headings = LineCollection(np.zeros((number_of_robots, 2, 2)), colors="black", linewidths=1.2)
        self.ax.add_collection(self.headings)
        self.label = self.fig.text(0.99, 0.01, "", ha="right", va="bottom", fontsize=8, family="monospace")
        self.fig.tight_layout()
        self.dynamic = (self.bodies, self.headings, self.label)
        self.blit = blit
        for artist in self.dynamic:
            artist.set_animated(blit)
        self._background = None

    def update(self, x, y, theta, label=""):
        xy = np.column_stack((x, y))
        self.bodies.set_offsets(xy)
        tip = xy + model.ROBOT_RADIUS * np.column_stack((np.cos(theta), np.sin(theta)))
        self.headings.set_segments(np.stack((xy, tip), axis=1))
        self.label.set_text(label)

    def frame(self):
        """The figure as RGBA bytes (Agg canvas)."""
        canvas = self.fig.canvas
        if not self.blit:
            canvas.draw()
            return canvas.buffer_rgba()
        if self._background is None:   # after the writer has fixed the frame size
            canvas.draw()
            self._background = canvas.copy_from_bbox(self.fig.bbox)
        canvas.restore_region(self._background)
        for artist in self.dynamic:
            self.fig.draw_artist(artist)
        return canvas.buffer_rgba()


def plot_trajectories(track, path, title=""):
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 5.5), dpi=120)
    arena_axes(ax)
    n = track.x.shape[1] if track.x.size else 0
    colors = plt.get_cmap(ROBOT_COLORS)(np.arange(n) % 10)
    for i in range(n):
        ax.plot(track.x[:, i], track.y[:, i], color=colors[i], lw=1.2)
        ax.plot(track.x[0, i], track.y[0, i], "o", mfc="none", mec=colors[i], ms=6)
        ax.add_patch(plt.Circle((track.x[-1, i], track.y[-1, i]), model.ROBOT_RADIUS, fc=colors[i], ec="black",
                                lw=0.5, alpha=0.85))
        ax.plot([track.x[-1, i], track.x[-1, i] + model.ROBOT_RADIUS * np.cos(track.theta[-1, i])],
                [track.y[-1, i], track.y[-1, i] + model.ROBOT_RADIUS * np.sin(track.theta[-1, i])], "k-", lw=1)
        ax.annotate(str(int(track.ids[i])), (track.x[-1, i] + model.ROBOT_RADIUS, track.y[-1, i] + model.ROBOT_RADIUS),
                    fontsize=7, ha="left", va="bottom")
    ax.set_title(title + ("\n" if title else "") + "open circle: start, filled: end (to scale, with heading)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def _ffmpeg_writer_class():
    """matplotlib's FFMpegWriter fed with ArenaView.frame() instead of a savefig per frame."""
    from matplotlib import animation

    class FrameFFMpegWriter(animation.FFMpegWriter):
        def grab_frame(self, **savefig_kwargs):
            self._proc.stdin.write(self.view.frame())

    return FrameFFMpegWriter


def _ffmpeg_available():
    """Point matplotlib at the ffmpeg of the imageio-ffmpeg wheel; False if there is no ffmpeg."""
    import matplotlib
    from matplotlib import animation
    try:
        import imageio_ffmpeg
        matplotlib.rcParams["animation.ffmpeg_path"] = imageio_ffmpeg.get_ffmpeg_exe()
        return True
    except Exception:   # no wheel, or no binary for this platform: maybe one on PATH
        return animation.FFMpegWriter.isAvailable()


def render_video(track, out_dir, title="", progress=True, fps=FPS, fmt=None):
    """run.mp4, or run.gif (Pillow) when fmt="gif" or no ffmpeg is found: one frame per recorded
    step (GIF: every other one, at half the rate). Progress in percent on stderr. Returns the path."""
    plt = _pyplot()
    fmt = fmt or ("mp4" if _ffmpeg_available() else "gif")
    path = os.path.join(out_dir, "run." + fmt)
    n = track.x.shape[1] if track.x.size else 0
    frames = len(track.steps)
    stride = 2 if fmt == "gif" else 1
    view = ArenaView(n, title, plt=plt, blit=True)
    shown = -1

    def frames_out():
        nonlocal shown
        for k in range(0, frames, stride):
            view.update(track.x[k], track.y[k], track.theta[k],
                        "t = %6.2f s  step %4d" % (track.steps[k] * model.TIME_STEP, track.steps[k]))
            yield k
            percent = 100 * min(k + stride, frames) // max(frames, 1)
            if progress and percent // 5 != shown // 5:
                shown = percent
                print("\rrendering %s: %3d%%" % (os.path.basename(path), percent), end="", file=sys.stderr, flush=True)

    if fmt == "mp4":
        writer = _ffmpeg_writer_class()(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])
        writer.view = view
        with writer.saving(view.fig, path, dpi=view.fig.dpi):
            for _ in frames_out():
                writer.grab_frame()
    else:
        from PIL import Image
        size = view.fig.canvas.get_width_height()
        images = [Image.frombuffer("RGBA", size, bytes(view.frame()), "raw", "RGBA", 0, 1).convert("RGB")
                  .quantize(colors=64) for _ in frames_out()]
        if images:
            images[0].save(path, save_all=True, append_images=images[1:], loop=0,
                           duration=int(1000 * stride * model.TIME_STEP))
    if progress:
        print(file=sys.stderr, flush=True)
    plt.close(view.fig)
    return path


# -- entry points -----------------------------------------------------------------------------------

def _run_json(bag_dir):
    """run.json beside a bag (./robotarium run writes it: how the script's run ended), or {}."""
    try:
        with open(os.path.join(bag_dir, "run.json"), encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return {}


def write_results(bag_dir, progress=True, *, out_dir=None, video=True):
    """Write report.txt, trajectories.png and run.mp4 (or run.gif) for the run in `bag_dir` (into
    `out_dir`, default the bag folder). Returns {"report": path, "trajectories": path, "video": path}
    ("video" only when video=True and the bag has poses). Prints nothing but progress (stderr)."""
    bag = Bag(bag_dir)
    out_dir = os.path.abspath(out_dir or bag.path)
    os.makedirs(out_dir, exist_ok=True)
    numbers = recompute(bag)
    paths = {"report": os.path.join(out_dir, "report.txt")}
    text = report_text(bag, numbers)
    stopped = _run_json(bag.path).get("time_limit")
    if stopped:   # the client ended the run at its time limit: say so first, as its printed report did
        text = stopped["note"] + "\n" + text
    with open(paths["report"], "w", encoding="utf-8") as f:
        f.write(text)
    track = bag.poses()
    s = numbers["settings"]
    title = "%s: %d robots, %d steps" % (s["run_id"] or bag.name, numbers["number_of_robots"], numbers["iterations"])
    paths["trajectories"] = plot_trajectories(track, os.path.join(out_dir, "trajectories.png"), title)
    if video and len(track.steps):
        paths["video"] = render_video(track, out_dir, title, progress=progress)
    return paths


def main(argv=None):
    parser = argparse.ArgumentParser(prog="robotarium report", description=(
        "Recompute the results of a recorded run from its bag: report.txt (the debug report), "
        "trajectories.png and a video, written beside the bag (or into --out)."))
    parser.add_argument("bag", help="run folder (bags/<run_id>), its metadata.yaml or its .mcap file")
    parser.add_argument("--out", help="folder for the results (default: the bag folder)")
    parser.add_argument("--no-video", action="store_true", help="skip the video")
    parser.add_argument("--quiet", action="store_true", help="no progress output")
    args = parser.parse_args(argv)
    try:
        paths = write_results(args.bag, progress=not args.quiet, out_dir=args.out, video=not args.no_video)
    except (FileNotFoundError, KeyError) as error:
        print("report: %s" % error, file=sys.stderr)
        return 2
    with open(paths["report"], encoding="utf-8") as f:
        print(f.read(), end="")
    print("\nresults:\n" + "\n".join("  %-13s %s" % (k, v) for k, v in paths.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
