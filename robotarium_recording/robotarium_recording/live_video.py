"""The run's video, made while the run goes (issue 40: results as the run goes).

./robotarium run hears the testbed's poses, the run's configuration and settings, the script's drawing and
its command arrays, and draws and encodes each frame once the script's step() calls have passed it, and a
second of experiment time more (pictures.Video, the same code and frame plan as the video made from the bag),
at nice +10, so that when a real-time run ends only that last second is left to draw, instead of the whole
video after the bag is closed (a lockstep run outpaces the drawing: what is left is drawn after it).

The bag stays the record. Once it is closed, what these frames were made from (the poses, the drawing
messages and the order they were applied in, the configuration, the settings, the title) is compared with
the bag's (LiveVideo.video_for): the same, the video is the run's (byte for byte what the bag would give);
else (a message one side missed or got late, a foreign publisher) it is made from the bag as before. The
renderer (pictures.Video's Compositor, or the Blitter for a drawing that changes often) follows the bag's
rule on what was heard so far; where that changes its mind, the video begins again from the first frame.
ROBOTARIUM_LIVE_VIDEO=0 turns it off.

LiveFrames is the pure core (what is heard, which frames are due); LiveVideo the shell (an rclpy node on
the command's probe context, a thread that spins it and one that draws)."""
import json
import os
import shutil
import stat
import tempfile
import threading
import time

import numpy as np
import yaml

from robotarium_core.config import SAFE_LOADER, ConfigError, TestbedConfig
from robotarium_recording import pictures

VARIABLE = "ROBOTARIUM_LIVE_VIDEO"
# Experiment time a frame is drawn behind the script: a frame's drawing is the one the script sent with its
# step() calls up to that step, so frames wait for the script's command arrays (one a step() call, sent after
# the call's drawing; in real time they carry no step, so they are counted), and this much more for a drawing
# message that arrives after a later command (sent again after a lost packet, 0.1 s heartbeats).
LAG = 1.0
ROWS_WAIT = 0.5   # s video_for waits for poses the bag holds and this reader has not heard yet
# While the run goes, the drawing thread and its encoder yield to everything else (the run itself, a real-time
# testbed, the portal's live view): nice +10, back to the process's own at the end where that is allowed
# (root: a service's worker, the tests; a user without CAP_SYS_NICE draws what is left at +10).
NICE = 10


def _nice(by, pid=None):
    """Change the niceness of this thread (or of process `pid`) by `by`; False where it is not allowed."""
    who = threading.get_native_id() if pid is None else pid
    if not who:
        return True
    try:
        os.setpriority(os.PRIO_PROCESS, who, os.getpriority(os.PRIO_PROCESS, who) + by)
        return True
    except OSError:
        return False


def _text(message):
    return json.dumps(message, sort_keys=True)   # (NaN equals NaN here, as in the bag's text)


def enabled():
    return os.environ.get(VARIABLE, "1").strip() not in ("0", "false", "no", "off")


class LiveFrames:
    """What the live video heard of one run, and which of its frames are due: the run's poses rows (its
    run id, the ids of its first row, in arrival order), its drawing messages in arrival order, its
    configuration and settings; due() yields the frames to draw, as pictures.frame_plan would."""

    def __init__(self):
        self.run_id = None          # the run to show (the runner's started.json)
        self.newest_run = None      # the run of the rows kept (rows of an earlier run are dropped)
        self.steps, self.x, self.y, self.theta = [], [], [], []
        self.ids = None
        self.drawings = []          # messages in arrival order
        self.commands = 0           # command arrays heard since the run's first poses: the script's step() calls
        self.config_text = None     # the newest configuration heard
        self.config = None          # the configuration the frames are drawn with
        self.settings = {}          # run id -> the experiment's settings (obstacles)
        self.next_step = None       # the step of the next frame
        self.row = 0                # the newest row at or before the last frame
        self.applied = 0            # drawing messages the frames applied
        self.plan = []              # (step, row, drawings applied) of every frame drawn

    def restart(self):
        """Draw again from the first frame (the video is begun again in the other renderer)."""
        self.next_step, self.row, self.applied, self.plan = None, 0, 0, []

    def poses(self, run_id, step, ids, x, y, theta):
        if run_id != self.newest_run:
            if self.plan:
                return   # drawing has begun: a later run's rows are not this video's
            self.newest_run = run_id
            self.steps, self.x, self.y, self.theta, self.ids = [], [], [], [], None
            self.commands = 0
        ids = tuple(ids)
        if self.ids is None:
            self.ids = ids
        elif ids != self.ids:
            return   # another set of robots: left out, as Bag.poses leaves it out
        self.steps.append(int(step))
        self.x.append(np.array(x, dtype=float))
        self.y.append(np.array(y, dtype=float))
        self.theta.append(np.array(theta, dtype=float))

    def command(self):
        self.commands += 1

    def drawing(self, message):
        self.drawings.append(message)

    def experiment(self, text):
        try:
            settings = yaml.load(text, Loader=SAFE_LOADER)
        except yaml.YAMLError:
            return   # not the simulator's
        if isinstance(settings, dict) and settings.get("run_id"):
            self.settings[str(settings["run_id"])] = settings

    def ready(self):
        """(config, title, obstacles, first poses) once the first frame can be drawn, else None."""
        if self.run_id is None or self.newest_run != self.run_id or not self.steps or self.config_text is None:
            return None
        settings = self.settings.get(self.run_id)
        if settings is None:
            return None
        try:
            self.config = TestbedConfig.from_yaml(self.config_text)
        except ConfigError:
            return None
        return self.config, self.run_id, settings.get("obstacles") or (), self.pose(0)

    def pose(self, row):
        return np.vstack((self.x[row], self.y[row], self.theta[row]))

    def due(self, lag_steps, final=False):
        """Yield (step, poses, new drawing messages) of each frame due: up to the newest step the script's
        step() calls passed, less lag_steps; or (final) up to the newest step."""
        if not self.steps:
            return
        if self.next_step is None:
            self.next_step = self.steps[0]
        last = self.steps[-1] if final else min(self.steps[-1], self.commands - 1 - lag_steps)
        while self.next_step <= last:
            step = self.next_step
            while self.row + 1 < len(self.steps) and self.steps[self.row + 1] <= step:
                self.row += 1
            d = self.applied
            while d < len(self.drawings) and self.drawings[d].get("step", 0) <= step:
                d += 1
            new, self.applied = self.drawings[self.applied:d], d
            self.plan.append((step, self.row, d))
            self.next_step += 1
            yield step, self.pose(self.row), new

    def batch(self, composite, lag_steps, final=False):
        """(renderer, frames due): the renderer the frames are to be drawn with (composites), and the frames
        due (see due) in it; where it is not `composite`, the video begins again, from the first frame."""
        wanted = self.composites(composite, final)
        if wanted != composite:
            self.restart()
        return wanted, list(self.due(lag_steps, final))

    def composites(self, now=None, final=False):
        """Whether the Compositor draws the frames, by pictures.composites's rule on what was heard so far
        (the run's frames up to the newest step, every drawing message heard). While the run goes, the
        renderer drawing them now (`now`: True for the Compositor) is kept unless the rule is clearly
        against it (by COMPOSITE_MIN_CHANGES), so that a few changes early on do not switch it back and
        forth; at the end (`final`) the rule as the bag's video applies it."""
        if not self.steps:
            return True
        changes = pictures.drawing_changes(self.drawings, self.steps[0])
        frames = self.steps[-1] - self.steps[0] + 1
        if final or now is None:
            return pictures.composites(changes, frames)
        margin = pictures.COMPOSITE_MIN_CHANGES
        return pictures.composites(changes, frames, margin if now else -margin)

    def differs(self, track, drawings, config, title, obstacles, composite=True):
        """Why the frames drawn (by the Compositor where `composite`, else the Blitter) are not those the bag
        gives ("" when they are)."""
        if title != self.run_id:
            return "another run (%s, the bag's %s)" % (self.run_id, title)
        if config != self.config:
            return "another configuration"
        if not np.array_equal(np.asarray(obstacles, dtype=float), np.asarray(self.settings[self.run_id].get(
                "obstacles") or (), dtype=float)):
            return "other obstacles"
        if len(track.steps) != len(self.steps) or not np.array_equal(track.steps, self.steps):
            return "other poses (%d rows heard, %d recorded)" % (len(self.steps), len(track.steps))
        for heard, recorded in ((self.x, track.x), (self.y, track.y), (self.theta, track.theta)):
            if not np.array_equal(np.asarray(heard), recorded):
                return "other poses"
        frames = pictures.Frames(track, drawings, config, title)
        if composite != pictures.composites(frames.changes(), len(frames)):
            return "the other renderer (the Compositor or the Blitter)"
        if self.plan != list(frames.plan()) or [_text(m) for m in self.drawings[:self.applied]] != [
                _text(m) for m in frames.drawings[:self.applied]]:
            return "another drawing, or one heard late"
        return ""


class LiveVideo:
    """The live video of the run that `started` (the runner's started.json) will name, on testbed `ns`, heard
    on the rclpy context that `context()` gives: start() hears and draws in threads of this process;
    video_for() finishes it and keeps it if it is what the bag gives; close() drops it."""

    def __init__(self, ns, started, context):
        # A folder of this process's own (0700): not the run's scratch folder, which a job box's script may write.
        self.folder = tempfile.mkdtemp(prefix="robotarium-live-video-")
        self.ns, self.started, self.path = ns.rstrip("/"), started, os.path.join(self.folder, "run.mp4")
        self.context = context   # () -> the rclpy context to listen on (made in the drawing thread, where needed)
        self.frames = LiveFrames()
        self.lock = threading.Condition()
        self.final = self.stop = self.closed = False
        self.video = None
        self.composite = None    # the video's renderer: the Compositor (True) or the Blitter (False)
        self.progress = False    # the frames left at the end show progress (video_for)
        self.niced = False       # the drawing thread runs at NICE
        self.why_not = ""        # why there is no live video (it failed, or gave up)
        self.drawn = threading.Event()   # no drawing thread (not started, or done: its video closed, or none)
        self.drawn.set()
        self.ffmpeg = pictures.ffmpeg_path()
        self.node = self.executor = self.spinner = None

    def start(self):
        if self.ffmpeg is None:
            self.why_not = "no ffmpeg (a GIF is made from the bag)"
            return self
        self.drawn.clear()
        threading.Thread(target=self._run, daemon=True, name="live video").start()
        return self

    # -- heard (the spinning thread) ----------------------------------------------------------------

    def _on_poses(self, msg):
        with self.lock:
            self.frames.poses(msg.run_id, msg.step, msg.ids, msg.x, msg.y, msg.theta)
            self.lock.notify()

    def _on_drawing(self, msg):
        from robotarium_recording import drawing
        try:
            message = drawing.decode(msg.data)
        except ValueError:
            return   # not a drawing (the bag's reader leaves it out too)
        with self.lock:
            self.frames.drawing(message)
            self.lock.notify()

    def _on_command(self, _):
        with self.lock:
            self.frames.command()
            self.lock.notify()

    def _on_config(self, msg):
        with self.lock:
            self.frames.config_text = msg.data

    def _on_experiment(self, msg):
        with self.lock:
            self.frames.experiment(msg.data)
            self.lock.notify()

    def _spin(self):
        while not self.stop:
            self.executor.spin_once(timeout_sec=0.05)

    # -- drawn (the drawing thread) -----------------------------------------------------------------

    def _run(self):
        try:
            self._listen()   # (its spinning thread at the process's niceness: it only keeps what is heard)
            self.niced = _nice(NICE)   # the drawing thread's own (its encoder, started from it, inherits it)
            self._draw()
        except Exception as error:   # noqa: BLE001 - the video is made from the bag then
            self.why_not = "%s: %s" % (type(error).__name__, error)
            if self.video is not None:
                self.video.abort()
                self.video = None
        finally:
            self.drawn.set()

    def _listen(self):
        """A node on the command's context (./robotarium run's probe context, robotarium_bringup.testbed: one
        participant for the command's life) with the run's topics, spun in a thread of its own."""
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from std_msgs.msg import String

        from robotarium_core import topics
        from robotarium_msgs.msg import RobotPoses, TwistArray
        context = self.context()
        # Named as a script's client is (robotarium_client_*): SROS2's policy lets it read the poses.
        self.node = Node("robotarium_client_live_video_%d" % os.getpid(), context=context,
                         start_parameter_services=False)
        qos = topics.OUTPUT_QOS   # the whole history a writer keeps: nothing dropped while a frame is drawn
        self.node.create_subscription(RobotPoses, "%s/%s" % (self.ns, topics.POSES), self._on_poses, qos)
        self.node.create_subscription(TwistArray, "%s/%s" % (self.ns, topics.CMD_REQUESTED), self._on_command, qos,
                                      raw=True)   # (only counted)
        self.node.create_subscription(String, "%s/%s" % (self.ns, topics.DRAWING), self._on_drawing,
                                      topics.DRAWING_QOS)
        self.node.create_subscription(String, "%s/%s" % (self.ns, topics.CONFIG), self._on_config, topics.LATCHED)
        self.node.create_subscription(String, "%s/%s" % (self.ns, topics.EXPERIMENT), self._on_experiment,
                                      topics.LATCHED)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.spinner = threading.Thread(target=self._spin, daemon=True, name="live video DDS")
        self.spinner.start()

    def _draw(self):
        with self.lock:   # the first frame: once the run, its configuration, settings and first poses are heard
            while True:
                if self.frames.run_id is None:
                    self.frames.run_id = self._run_id()
                ready = self.frames.ready()
                if ready is not None or self.final or self.stop:
                    break
                self.lock.wait(0.02)
        if ready is None or self.stop:
            self.why_not = "the run's poses, configuration or settings were not heard"
            return
        config, title, obstacles, first = ready
        lag = int(round(LAG / config.time_step))
        while True:
            if self.stop:   # (close(): no video wanted)
                self.why_not = self.why_not or "stopped"
                if self.video is not None:
                    self.video.abort()
                    self.video = None
                return
            with self.lock:
                final = self.final
                composite, due = self.frames.batch(self.composite, lag, final)
                if not due and not final and composite == self.composite:
                    self.lock.wait(0.05)
                    continue
            if composite != self.composite:
                if self.video is not None:
                    self.video.abort()
                self.video = pictures.Video(self.path, self.ffmpeg, config, first, title, obstacles,
                                            composite=composite, progress=False)
                self.composite = composite
            if final and self.niced:   # the run is over: what is left is what the prompt waits for
                self.niced = not (_nice(-NICE) and _nice(-NICE, self.video.encoder.pid if self.video.encoder else 0))
            if final and not self.video.meter.enabled and self.progress:
                # The frames left at the end (a lockstep run outpaces the drawing): progress, as the bag's video has.
                self.video.meter = pictures.Progress("run.mp4", len(self.frames.plan), True)
            for step, poses, drawings in due:
                if self.stop:
                    break
                self.video.frame(step, poses, drawings)
            if final and not self.stop:
                self.video.close()
                return

    def _run_id(self):
        """The run id in the runner's started.json, once it is there (a regular file, read without waiting:
        a job box's script may write that folder)."""
        try:
            fd = os.open(self.started, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
        except OSError:
            return None
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                return None
            return str(json.loads(os.read(fd, 1 << 16)).get("run_id") or "") or None
        except (OSError, ValueError, AttributeError):
            return None
        finally:
            os.close(fd)

    # -- the end ------------------------------------------------------------------------------------

    def video_for(self, track, drawings, config, title, obstacles, out_path, progress=False):
        """The run's video at `out_path` when the frames drawn are those of the bag's poses, drawing,
        configuration, title and obstacles (then True); else False (why_not says why) and nothing is left.
        `progress`: the frames still to draw show their progress on stderr."""
        if self.closed:   # (asked again: the results made again elsewhere, after a full disk refused them)
            self.why_not = self.why_not or "closed"
            return False
        try:
            deadline = time.monotonic() + ROWS_WAIT
            while not self.drawn.is_set() and time.monotonic() < deadline:
                with self.lock:
                    if self.frames.newest_run == self.frames.run_id and len(self.frames.steps) >= len(track.steps):
                        break
                time.sleep(0.01)
            with self.lock:
                self.final, self.progress = True, progress
                self.lock.notify_all()
            self.drawn.wait()
            if self.video is None or self.why_not:
                return False
            with self.lock:
                self.why_not = self.frames.differs(track, drawings, config, title, obstacles, self.composite)
            if self.why_not:
                return False
            shutil.move(self.path, out_path)
            return True
        finally:
            self.close()

    def close(self):
        """Stop hearing and drawing; the node goes once its spinning thread has stopped (it is left to the
        process's exit should Fast DDS hold it: robotarium_cli.main ends with os._exit)."""
        with self.lock:
            self.final = self.stop = self.closed = True
            self.lock.notify_all()
        if self.drawn.wait(timeout=5.0):
            shutil.rmtree(self.folder, ignore_errors=True)
        if self.spinner is not None:
            self.spinner.join(timeout=1.0)
            if not self.spinner.is_alive() and self.node is not None:
                self.executor.shutdown()
                self.node.destroy_node()
                self.node = None
