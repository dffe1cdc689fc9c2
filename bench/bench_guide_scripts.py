"""Every example script of the guide (examples/guide/), run on this stack and on the Robotarium's
own simulator, side by side: the steps each run took and the counts of its debug report, and the
wall time of each run with the ratio.

  stack:      ./robotarium run SCRIPT (unchanged) against one local testbed (simulator, safety
              node, recorder) started for the benchmark; lockstep unless --real-time.
  reference:  robotarium-python-simulator 0.0.0 in .venv-reference, on a copy of the script with
              sim_in_real_time=False (real time would only make it slower), its figure drawn
              with the Agg backend. rps 0.0.0 passes RegularPolygon's radius and orientation by
              position, which matplotlib 3.8+ refuses: REFERENCE_COMPAT passes them by name.

numpy is seeded (tests/run_seeded.py) so both sides draw the same random goals. The safety node is
always on in the stack; the reference applies only the script's own certificates, so paths (and
step counts) differ where the safety node had to step in. Wall times are whole processes, start to
exit: "script" is the process that runs the script on each side (the reference's; on the stack
the runner's, from run.json: its imports, the client's start-up over DDS, the loop, the end), and
"command" the whole `./robotarium run` (also its look for a testbed, and the results it makes
from the recording afterwards: report, trajectory plot). "ratio" is reference / script. Both draw the figure
when the script asks for it: the reference renders every step, the stack headless only moves the
artists (a frame is rendered when the script saves the figure).
Run: ./robotarium bench guide_scripts [--seed S] [--real-time] [PATTERN ...]
"""
import argparse
import glob
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GUIDE = os.path.join(REPO, "examples", "guide")
RUN_SEEDED = os.path.join(REPO, "devtools", "run_seeded.py")
from devtools.reference import REFERENCE_PYTHON, _reference_env  # noqa: E402
from devtools.rosutil import node_env, unique_domain_id  # noqa: E402

REFERENCE_COMPAT = """
import runpy, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.patches as patches
class RegularPolygon(patches.RegularPolygon):
    def __init__(self, xy, numVertices, radius=5, orientation=0, **kwargs):
        super().__init__(xy, numVertices, radius=radius, orientation=orientation, **kwargs)
patches.RegularPolygon = RegularPolygon
sys.argv = sys.argv[1:]
runpy.run_path(sys.argv[0], run_name="__main__")
"""


def report_counts(output):
    """(seconds, boundary, collisions, actuator) from the last debug report in output: the
    report's "approximately N real seconds" (N = ceil(steps * 0.033)) and its three counts."""
    start = output.rfind("##### DEBUG OUTPUT #####")
    if start < 0:
        return None
    text = output[start:]
    seconds = re.search(r"approximately (\d+) real seconds", text)

    def count(pattern):
        match = re.search(r"had (\d+) iteration\(s\) " + pattern, text)
        return int(match.group(1)) if match else 0

    return (int(seconds.group(1)) if seconds else None, count("robots were outside"), count("where robots collided"),
            count("where the actuator"))


def run_reference(script, seed, timeout):
    with tempfile.TemporaryDirectory() as folder:
        copy = os.path.join(folder, os.path.basename(script))
        with open(script) as f:
            code = f.read().replace("sim_in_real_time=True", "sim_in_real_time=False")
        with open(copy, "w") as f:
            f.write(code)
        for extra in glob.glob(os.path.join(GUIDE, "*.png")):
            shutil.copy(extra, folder)
        start = time.perf_counter()
        try:
            out = subprocess.run([REFERENCE_PYTHON, "-c", REFERENCE_COMPAT, RUN_SEEDED, str(seed), copy],
                                 env=_reference_env(),
                                 capture_output=True, text=True, cwd=folder, timeout=timeout)
        except subprocess.TimeoutExpired:
            return "timed out", timeout
        return report_counts(out.stdout + out.stderr), time.perf_counter() - start


def run_stack(script, seed, env, real_time, timeout):
    """(report counts, the script process's wall time, the whole command's wall time)."""
    mode = "--real-time" if real_time else "--lockstep"
    start = time.perf_counter()
    try:
        out = subprocess.run([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", mode, "--no-video",
                              RUN_SEEDED, str(seed), script], env=env, capture_output=True, text=True,
                             cwd=os.path.dirname(script), timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timed out", timeout, timeout
    command = time.perf_counter() - start
    output = out.stdout + out.stderr
    folder = re.search(r"results in (\S+) \(open", output)
    try:
        with open(os.path.join(os.path.dirname(script), folder.group(1), "run.json")) as f:
            script_wall = json.load(f)["wall_time"]
    except (AttributeError, OSError, KeyError, ValueError):
        script_wall = float("nan")
    return report_counts(output), script_wall, command


def cell(counts):
    if counts is None or isinstance(counts, str):
        return "%-22s" % (counts or "failed (no report)")
    seconds, boundary, collisions, actuator = counts
    return "%4s s %3d %3d %5d    " % (seconds, boundary, collisions, actuator)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("patterns", nargs="*", help="only scripts whose file name contains one of these")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--real-time", action="store_true", help="run the stack side at 30 Hz (takes minutes)")
    parser.add_argument("--timeout", type=float, default=600, help="seconds per run before it counts as unfinished")
    args = parser.parse_args()
    scripts = [s for s in sorted(glob.glob(os.path.join(GUIDE, "*.py")))
               if not args.patterns or any(p in os.path.basename(s) for p in args.patterns)]

    from robotarium_bringup.testbed import LocalTestbed, testbed_answers
    domain = unique_domain_id()
    env = node_env(domain)
    saved = dict(os.environ)
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    bags = tempfile.mkdtemp(prefix="bench-guide-")
    testbed = LocalTestbed(log_dir=bags, bags_dir=bags).start()
    try:
        if not testbed_answers(timeout=60):
            sys.exit("the testbed did not come up: %s" % testbed.failed())
        os.environ.clear()
        os.environ.update(saved)
        print("guide scripts, %s, %s, %d cores, seed %d, stack in %s, load average %.1f" % (
            time.strftime("%Y-%m-%d"), platform.machine(), os.cpu_count(), args.seed,
            "real time (30 Hz)" if args.real_time else "lockstep", os.getloadavg()[0]))
        print("%-46s %-22s %-22s %9s %9s %9s %6s" % ("", "reference", "stack", "ref wall", "stack", "stack",
                                                      "ratio"))
        print("%-46s %-22s %-22s %9s %9s %9s" % ("script", "time  out col  act", "time  out col  act", "",
                                                 "script", "command"))
        ratios = {}   # script -> the reference's wall time / the stack's script wall time
        for script in scripts:
            ref, ref_wall = run_reference(script, args.seed, args.timeout)
            ours, our_wall, command_wall = run_stack(script, args.seed, env, args.real_time, args.timeout)
            ratio = ratios[os.path.basename(script)] = ref_wall / our_wall
            print("%-46s %s %s %8.1fs %8.1fs %8.1fs %6.2f" % (
                os.path.basename(script)[:46], cell(ref), cell(ours), ref_wall, our_wall, command_wall, ratio),
                flush=True)
        print("time: the report's estimate of the real testbed's duration (steps x 0.033 s); out, col, act: "
              "iterations with robots outside the arena, colliding, over the actuator limits. ratio: reference "
              "wall time / the stack's script wall time (> 1: the stack is faster). Load average now %.1f."
              % os.getloadavg()[0])
        faster = sum(ratio >= 1 for ratio in ratios.values())
        print("the stack's script at least as fast as the reference: %d of %d" % (faster, len(scripts)))
        if ratios:
            slowest = min(ratios, key=lambda name: ratios[name])
            print("goal: every listing at >= 1x the reference (issue 40, goal 4): %d of %d, the slowest %s at %.2fx "
                  "-> %s" % (faster, len(scripts), slowest, ratios[slowest],
                             "met" if faster == len(scripts) else "not met"))
    finally:
        testbed.stop()
        shutil.rmtree(bags, ignore_errors=True)


if __name__ == "__main__":
    main()
