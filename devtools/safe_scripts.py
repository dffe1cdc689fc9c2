"""A Robotarium script run in this process two ways, step by step, for issue 36 ("a safe script
behaves on the testbed as on the Robotarium"):

  reference:  the Robotarium's own simulator 0.0.0 (PyPI robotarium-python-simulator, its
              robotarium.py and robotarium_abc.py read from .venv-reference and run here), in
              lockstep; with guide_thresholding=True its step() drives the commands scaled to the
              wheel limits along their arc (guide §2.5), as this testbed does, instead of 0.0.0's
              separate clips of v and omega (its own _threshold has no effect: it never returns).
  pure stack: what the safety node's filter (robotarium_safety.guard.filter_commands with the
              node's certificate) and the simulator's model (robotarium_core.model.Testbed) make of
              the script's commands: the stack in lockstep without DDS.

Both run the script's own rps utilities (this project's: the certificates on OSQP), so the only
difference between them is the testbed. Each returns a Trace: the poses of every step, the
debug report's counts, and (pure stack) the arrays the safety layer changed.
"""
import contextlib
import dataclasses
import io
import os
import re
import sys

import numpy as np

from devtools.reference import REFERENCE_PYTHON

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GUIDE = os.path.join(REPO, "examples", "guide")


@dataclasses.dataclass
class Trace:
    poses: list                    # 3 x N poses before each step, and after the last
    collisions: int = 0
    boundary: int = 0
    actuator: int = 0
    changed: int = 0               # pure stack: command arrays the safety layer changed
    largest_change: float = 0.0
    output: str = ""

    @property
    def iterations(self):
        return len(self.poses) - 1

    def difference(self, other):
        """Largest distance (m) between the two runs' robot centres at a step both reached."""
        steps = min(len(self.poses), len(other.poses))
        if steps == 0:
            return float("nan")
        a, b = np.array(self.poses[:steps]), np.array(other.poses[:steps])
        return float(np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1]).max())


def _reference_sources():
    site = os.path.join(os.path.dirname(os.path.dirname(REFERENCE_PYTHON)), "lib")
    for root, _, files in os.walk(site):
        if root.endswith(os.path.join("site-packages", "rps")) and "robotarium.py" in files:
            return os.path.join(root, "robotarium_abc.py"), os.path.join(root, "robotarium.py")
    raise RuntimeError("the Robotarium simulator 0.0.0 is not in .venv-reference: run ./robotarium setup")


def reference_robotarium(guide_thresholding=False):
    """0.0.0's Robotarium class, loaded from its source, recording its poses (r.trace) and with
    sim_in_real_time off (it would only busy-wait)."""
    import matplotlib.patches as patches
    abc_file, robotarium_file = _reference_sources()
    namespace = {"__name__": "rps_reference"}
    with open(abc_file) as f:
        code = f.read()
    # 0.0.0 passes RegularPolygon's radius and orientation by position, which matplotlib 3.8+ refuses.
    code = code.replace("patches.RegularPolygon(", "_regular_polygon(")
    namespace["_regular_polygon"] = lambda xy, n, radius, orientation, **kw: patches.RegularPolygon(
        xy, n, radius=radius, orientation=orientation, **kw)
    exec(compile(code, abc_file, "exec"), namespace)
    with open(robotarium_file) as f:
        code = f.read().replace("from rps.robotarium_abc import *", "")
    exec(compile(code, robotarium_file, "exec"), namespace)
    base = namespace["Robotarium"]

    from robotarium_core import model

    class Reference(base):
        def __init__(self, number_of_robots=-1, show_figure=True, sim_in_real_time=True,
                     initial_conditions=np.array([])):
            super().__init__(number_of_robots, show_figure, False, initial_conditions)
            self.trace = Trace([np.array(self.poses, dtype=float)])
            self._own_errors = {}
            self._raw = np.zeros((2, self.number_of_robots))
            Reference.last = self

        def set_velocities(self, ids, velocities):
            if not guide_thresholding:
                return super().set_velocities(ids, velocities)
            # The script's commands as they are (0.0.0 clips v and omega apart, in the script's own
            # array): the move thresholds them along their arc, the count sees them clipped as 0.0.0's.
            self._raw = np.array(velocities, dtype=float)
            super().set_velocities(ids, np.array(velocities, dtype=float))

        def _validate(self, errors=None):
            # 0.0.0's errors={} default is one dict for the whole process: a second run would go on
            # counting from the first's. Each run here counts in its own.
            saved = self.velocities
            self.velocities = self._asked
            try:
                return super()._validate(self._own_errors)
            finally:
                self.velocities = saved

        def step(self):
            self._asked = self.velocities   # counted as the script set them, as 0.0.0 does
            if guide_thresholding:
                self.velocities = model.threshold_keeping_arc(self._raw[:2])
            try:
                super().step()
            finally:
                self.velocities = self._asked
            self.trace.poses.append(np.array(self.poses, dtype=float))

        def call_at_scripts_end(self):
            errors = self._errors
            self.trace.collisions = errors.get("collision", 0)
            self.trace.boundary = errors.get("boundary", 0)
            self.trace.actuator = errors.get("actuator", 0)
            super().call_at_scripts_end()

    return Reference


def pure_stack_robotarium(config=None):
    """A lockstep Robotarium whose step() goes through the safety node's filter and the
    simulator's model in this process (the stack's pure cores, no DDS)."""
    from robotarium_client.robotarium_abc import RobotariumABC
    from robotarium_core import model
    from robotarium_core.config import DEFAULT
    from robotarium_safety.guard import filter_commands
    from robotarium_safety.testbed_certificate import TestbedCertificate
    config = config or DEFAULT

    class PureStack(RobotariumABC):
        def __init__(self, number_of_robots=-1, show_figure=True, sim_in_real_time=True,
                     initial_conditions=np.array([])):
            super().__init__(number_of_robots, show_figure, False, initial_conditions, config)
            self._testbed = model.Testbed(self.poses.copy(), config)
            self._certificate = TestbedCertificate(config)
            self.trace = Trace([self.poses.copy()])
            self._make_figure()
            PureStack.last = self

        def _advance(self, velocities):
            x = self._testbed.poses.copy()
            filtered = filter_commands(self._certificate, velocities.copy(), x, config)
            change = float(filtered.change.max(initial=0.0))
            if model.is_intervention(change > 0, change, config.intervention_tolerance):
                self.trace.changed += 1
                self.trace.largest_change = max(self.trace.largest_change, change)
            self._testbed.set_commands(np.arange(self.number_of_robots), filtered.safe[0], filtered.safe[1],
                                       requested_exceeds_limits=filtered.over_limits)
            self._testbed.step()
            self.trace.poses.append(self._testbed.poses.copy())
            return self._testbed.poses.copy()

        def _end(self, outcome=0, detail=""):
            t = self._testbed
            self.trace.collisions, self.trace.boundary = t.collisions, t.boundary_violations
            self.trace.actuator = t.actuator_limit_iterations
            return model.debug_report(t.steps, t.boundary_violations, t.collisions, t.actuator_limit_iterations,
                                      config.time_step)

    return PureStack


def run_script(script, robotarium_class, seed=1, settings=()):
    """Run `script` (its own folder as the working directory, numpy seeded with `seed`, each
    (NAME, VALUE) of settings replacing its top-level `NAME = ...` line) with
    rps.robotarium.Robotarium replaced by robotarium_class; returns its Trace. Its figure is drawn on
    but never rendered: a trace is poses, and 0.0.0 renders it every step (over half of its time in a
    listing with plotting)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    import rps.robotarium
    script = os.path.abspath(script)
    with open(script) as f:
        source = f.read()
    for name, value in settings:
        source, count = re.subn(r"(?m)^%s[ \t]*=[^#\n]*" % re.escape(name), "%s = %s " % (name, value), source)
        assert count == 1, (script, name)
    saved = rps.robotarium.Robotarium, os.getcwd(), list(sys.path), sys.argv
    rps.robotarium.Robotarium = robotarium_class
    render, FigureCanvasAgg.draw = FigureCanvasAgg.draw, lambda canvas: None
    robotarium_class.last = None
    out = io.StringIO()
    try:
        os.chdir(os.path.dirname(script))
        sys.path.insert(0, os.path.dirname(script))
        sys.argv = [script]
        np.random.seed(seed)
        with contextlib.redirect_stdout(out):
            exec(compile(source, script, "exec"), {"__name__": "__main__", "__file__": script})
    finally:
        rps.robotarium.Robotarium, cwd, sys.path[:], sys.argv = saved
        FigureCanvasAgg.draw = render
        os.chdir(cwd)
        plt.close("all")
    trace = robotarium_class.last.trace
    trace.output = out.getvalue()
    return trace


def recorded_trace(folder):
    """The Trace of a run ./robotarium run recorded in `folder`: its poses (the bag's), the debug
    report's counts and the safety layer's interventions (run.json, the testbed's), and the largest
    change of those (the safety node's reports in the bag)."""
    import json

    from robotarium_core.config import DEFAULT
    from robotarium_recording import results
    from robotarium_recording.bag import Bag
    with open(os.path.join(folder, "run.json")) as f:
        info = json.load(f)
    bag = Bag(folder)
    track = bag.poses()
    poses = [np.array([track.x[k], track.y[k], track.theta[k]]) for k in range(len(track.steps))]
    summary = results.safety_summary(bag, bag.config().intervention_tolerance if bag.config() else
                                     DEFAULT.intervention_tolerance)
    return Trace(poses, info.get("collisions", 0), info.get("boundary_violations", 0),
                 info.get("actuator_limit_iterations", 0), info.get("safety_interventions", 0),
                 summary["largest_change"])


def compare(script, seed=1, settings=()):
    """(pure stack, 0.0.0, 0.0.0 with the guide's thresholding) traces of one script."""
    stack = run_script(script, pure_stack_robotarium(), seed, settings)
    reference = run_script(script, reference_robotarium(), seed, settings)
    thresholded = run_script(script, reference_robotarium(guide_thresholding=True), seed, settings)
    return stack, reference, thresholded


if __name__ == "__main__":
    import glob
    scripts = sys.argv[1:] or sorted(glob.glob(os.path.join(GUIDE, "*.py"))) + sorted(
        glob.glob(os.path.join(REPO, "examples", "*.py")))
    print("%-52s %8s %10s %14s %14s %10s %10s" % ("script", "changed", "largest", "iter stack/ref",
                                                  "coll/bound", "act s/r/g", "max diff m"))
    for script in scripts:
        stack, ref, guide = compare(script)
        print("%-52s %8d %10.3g %6d/%-6d %6s/%-6s %10s %10.2g %10.2g" % (
            os.path.basename(script)[:52], stack.changed, stack.largest_change, stack.iterations, ref.iterations,
            "%d/%d" % (stack.collisions, stack.boundary), "%d/%d" % (ref.collisions, ref.boundary),
            "%d/%d/%d" % (stack.actuator, ref.actuator, guide.actuator), stack.difference(ref),
            stack.difference(guide)), flush=True)
