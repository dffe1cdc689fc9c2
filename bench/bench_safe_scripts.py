"""Does the always-on safety layer leave a safe script alone? Every guide listing and bundled example
(and, with --rps2, the 2.1.0 examples) through the whole stack, side by side with the Robotarium's
own simulator (issue 36):

  stack:      ./robotarium run --lockstep SCRIPT (numpy seeded: devtools/run_seeded.py) against one
              local testbed started for the benchmark: the client, the safety node, the simulator and
              the recorder over DDS; what the run.json and the bag say;
  reference:  robotarium-python-simulator 0.0.0's robotarium.py run in this process on the same script
              (devtools.safe_scripts): as published ("0.0.0"), and with the guide's thresholding in its
              step ("0.0.0+g": a script beyond the wheel limits drives its commanded arc, as here).

Columns: arrays the safety layer changed and the largest change (m/s or rad/s); iterations of the
stack, of 0.0.0+g and of 0.0.0; the largest distance between a robot on the stack and on 0.0.0+g at
the same step (m); collision / outside iterations of 0.0.0 (a script that is not safe there may be
changed here); actuator-limit iterations of the stack, 0.0.0+g and 0.0.0 (0.0.0 clips v and omega
apart, so its paths and counts differ where a script exceeds the wheel limits: the thresholding, not
the counting).
Listings with fixed loops of thousands of steps run shortened loops (--full: as printed).

--rps2: the 2.1.0 examples instead (examples/rps2/, shortened as tests/test_rps2_examples.py runs
them): arrays changed, and the iterations of the stack and of the Robotarium simulator 2.1.0 (its
source beside the repository, run in .venv-reference; both count the drive-on phase, which differs
by design: docs/rps2.md), with 2.1.0's errors (too close / outside).
Run: ./robotarium bench safe_scripts [--full] [--rps2] [PATTERN ...]
"""
import argparse
import glob
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)
from devtools import safe_scripts  # noqa: E402
from devtools.rosutil import node_env, unique_domain_id  # noqa: E402

RUN_SEEDED = os.path.join(REPO, "devtools", "run_seeded.py")
SCRIPTS = (sorted(glob.glob(os.path.join(REPO, "examples", "guide", "*.py")))
           + sorted(glob.glob(os.path.join(REPO, "examples", "*.py"))))
SHORTER = {"3_3_1_leader_follower_formation_control.py": [("iterations", "1200")],
           "3_4_1_rectangle_formation_control.py": [("iterations", "1000")],
           "3_5_2_unreachable_goals_single_integrator.py": [("iterations", "1200")],
           "3_5_3_unreachable_goals_unicycle.py": [("iterations", "1200")],
           "3_6_1_leader_follower_data_saving.py": [("iterations", "1200")],
           "3_8_2_leader_follower_with_plotting.py": [("iterations", "1200")]}


def run_stack(script, seed, settings, env, bags):
    sets = [arg for name, value in settings for arg in ("--set", "%s=%s" % (name, value))]
    out = subprocess.run([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--lockstep",
                          "--no-video", "--bags-dir", bags, RUN_SEEDED, *sets, str(seed), script], env=env,
                         capture_output=True, text=True, cwd=os.path.dirname(script), timeout=1200)
    folder = re.search(r" recorded in (\S+)", out.stdout + out.stderr)
    if folder is None:
        return None, out.stdout + out.stderr
    return safe_scripts.recorded_trace(folder.group(1)), ""


RPS2 = os.path.join(REPO, "examples", "rps2")
REFERENCE_2 = os.path.join(os.path.dirname(REPO), "shared", "reference", "robotarium_python_simulator-2.1.0")


def rps2_settings(script):
    """The shortening tests/test_rps2_examples.py applies (run_seeded.py arguments)."""
    sys.path.insert(0, os.path.join(REPO, "tests"))
    import test_rps2_examples as examples
    name = os.path.relpath(script, RPS2)
    with open(script) as f:
        long_loop = "\niterations = " in f.read()
    args = ["--iterations", str(examples.SHORT_ITERATIONS)] if long_loop else []
    args += [arg for setting in examples.SHORTER.get(name, []) for arg in ("--set", setting)]
    return args, examples.SCRIPT_ARGS.get(name, [])


def rps2_reference(script, seed, args, script_args):
    """(iterations, too close, outside) from 2.1.0's debug() text, or None."""
    from devtools.reference import REFERENCE_PYTHON
    env = dict(os.environ, PYTHONPATH=REFERENCE_2, MPLBACKEND="Agg")
    env.pop("AMENT_PREFIX_PATH", None)
    out = subprocess.run([REFERENCE_PYTHON, RUN_SEEDED, *args, str(seed), script, *script_args], env=env,
                         capture_output=True, text=True, cwd=os.path.dirname(script), timeout=1800)
    text = out.stdout + out.stderr
    took = re.search(r"took approximately ([0-9.]+) real seconds", text)
    if took is None:
        return None
    close = re.search(r"(\d+) time steps where robots were too close", text)
    outside = re.search(r"(\d+) time steps where robots were outside", text)
    return (round(float(took.group(1)) / 0.033), int(close.group(1)) if close else 0,
            int(outside.group(1)) if outside else 0)


def main_rps2(args, env, bags):
    scripts = sorted(p for p in glob.glob(os.path.join(RPS2, "**", "*.py"), recursive=True) if not p.endswith("uni_ekf.py"))
    scripts = [s for s in scripts if not args.patterns or any(p in s for p in args.patterns)]
    print("%-52s %7s %8s %13s %12s" % ("2.x example", "changed", "largest", "iterations", "2.1.0"))
    print("%-52s %7s %8s %13s %12s" % ("", "arrays", "change", "stack/2.1.0", "close/out"))
    unchanged = 0
    for script in scripts:
        run_args, script_args = rps2_settings(script)
        out = subprocess.run([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--lockstep",
                              "--no-video", "--no-verdict", "--bags-dir", bags, RUN_SEEDED, *run_args, str(args.seed),
                              script, *script_args], env=env, capture_output=True, text=True,
                             cwd=os.path.dirname(script), timeout=1800)
        folder = re.search(r" recorded in (\S+)", out.stdout + out.stderr)
        name = os.path.relpath(script, RPS2)[:52]
        if folder is None:
            print("%-52s no run: %s" % (name, (out.stdout + out.stderr).strip().splitlines()[-1:]), flush=True)
            continue
        stack = safe_scripts.recorded_trace(folder.group(1))
        reference = rps2_reference(script, args.seed, run_args, script_args)
        unchanged += stack.changed == 0
        print("%-52s %7d %8.3g %13s %12s" % (
            name, stack.changed, stack.largest_change,
            "%d/%s" % (stack.iterations, reference[0] if reference else "-"),
            "%d/%d" % reference[1:] if reference else "(no report)"), flush=True)
    print("2.x examples with no array changed: %d of %d. Load average now %.1f." % (unchanged, len(scripts),
                                                                                    os.getloadavg()[0]))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("patterns", nargs="*", help="only scripts whose file name contains one of these")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--full", action="store_true", help="run the long listings as printed (minutes)")
    parser.add_argument("--rps2", action="store_true", help="the 2.1.0 examples, beside 2.1.0")
    args = parser.parse_args()
    scripts = [s for s in SCRIPTS if not args.patterns or any(p in os.path.basename(s) for p in args.patterns)]

    from robotarium_bringup.testbed import LocalTestbed, testbed_answers
    domain = unique_domain_id()
    env = node_env(domain)
    saved = dict(os.environ)
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    bags = tempfile.mkdtemp(prefix="bench-safe-")
    testbed = LocalTestbed(log_dir=bags, bags_dir=bags).start()
    try:
        if not testbed_answers(timeout=60):
            sys.exit("the testbed did not come up: %s" % testbed.failed())
        os.environ.clear()
        os.environ.update(saved)
        print("safe scripts, %s, %s, %d cores, seed %d, lockstep, load average %.1f" % (
            time.strftime("%Y-%m-%d %H:%M"), platform.machine(), os.cpu_count(), args.seed, os.getloadavg()[0]))
        if args.rps2:
            return main_rps2(args, env, bags)
        print("%-52s %7s %8s %17s %10s %9s %13s" % ("script", "changed", "largest", "iterations", "position",
                                                   "0.0.0", "actuator"))
        print("%-52s %7s %8s %17s %10s %9s %13s" % ("", "arrays", "change", "stack/+g/0.0.0", "diff (m)",
                                                   "col/out", "st/+g/0.0.0"))
        unchanged = 0
        for script in scripts:
            settings = [] if args.full else SHORTER.get(os.path.basename(script), [])
            stack, problem = run_stack(script, args.seed, settings, env, bags)
            raw = safe_scripts.run_script(script, safe_scripts.reference_robotarium(), args.seed, settings)
            guide = safe_scripts.run_script(script, safe_scripts.reference_robotarium(guide_thresholding=True),
                                            args.seed, settings)
            name = os.path.basename(script)[:52]
            if stack is None:
                print("%-52s no run: %s" % (name, problem.strip().splitlines()[-1:]), flush=True)
                continue
            unchanged += stack.changed == 0
            print("%-52s %7d %8.3g %17s %10.2g %4d/%-4d %13s" % (
                name, stack.changed, stack.largest_change, "%d/%d/%d" % (stack.iterations, guide.iterations,
                                                                         raw.iterations),
                stack.difference(guide), raw.collisions, raw.boundary,
                "%d/%d/%d" % (stack.actuator, guide.actuator, raw.actuator)), flush=True)
        print("scripts with no array changed: %d of %d. Load average now %.1f." % (unchanged, len(scripts),
                                                                                  os.getloadavg()[0]))
    finally:
        testbed.stop()
        shutil.rmtree(bags, ignore_errors=True)


if __name__ == "__main__":
    main()
