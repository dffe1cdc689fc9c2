"""Every guide script (examples/guide/) in the ideal and the hardware-like mode, side by side: which
scripts are fragile on real robots.

Each script runs unchanged through `./robotarium run --lockstep` (and `--hardware --seed S`)
against one local testbed started for the benchmark, numpy seeded (bench/guide_outcome.py), and
prints per mode: the steps it took to finish, its final goal error (as guide_outcome.py measures
it: metres from the script's own goal), and the debug report's counts (iterations with robots
outside the arena, colliding, over the actuator limits). A script still running after
--max-steps is stopped there and marked with "+".

The hardware-like model's numbers are those of testbed.yaml (robotarium_sim/hardware.py).
Run: ./robotarium bench hardware [--seed S] [--max-steps K] [PATTERN ...]
"""
import argparse
import glob
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time

from bench_guide_scripts import GUIDE, report_counts
from guide_outcome import parse_outcome

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUTCOME = os.path.join(REPO, "bench", "guide_outcome.py")
from devtools.rosutil import node_env, unique_domain_id  # noqa: E402


def run(script, seed, max_steps, env, hardware, timeout):
    flags = ["--hardware", "--seed", str(seed)] if hardware else []
    start = time.perf_counter()
    try:
        out = subprocess.run([sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--lockstep",
                              "--no-video", *flags, OUTCOME, str(seed), str(max_steps), script],
                             env=env, capture_output=True, text=True, cwd=os.path.dirname(script), timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, timeout
    text = out.stdout + out.stderr
    outcome = parse_outcome(text)
    counts = report_counts(text)
    if outcome is None or counts is None:
        # say why on stderr (the table stays readable on stdout)
        print("%s (%s): no outcome; the run's last lines:\n%s" % (
            os.path.basename(script), "hardware-like" if hardware else "ideal", "\n".join(text.splitlines()[-15:])),
            file=sys.stderr, flush=True)
        return None, time.perf_counter() - start
    steps, error, _, finished = outcome
    return (steps, error, finished, counts[2], counts[1], counts[3]), time.perf_counter() - start


def cell(result):
    if result is None:
        return "%-34s" % "failed (no outcome)"
    steps, error, finished, collisions, outside, actuator = result
    return "%6d%s %8s %4d %4d %5d  " % (steps, " " if finished else "+", error, collisions, outside, actuator)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("patterns", nargs="*", help="only scripts whose file name contains one of these")
    parser.add_argument("--seed", type=int, default=1, help="numpy's seed (random goals) and the hardware model's")
    parser.add_argument("--max-steps", type=int, default=10000, help="stop a script that has not finished by then")
    parser.add_argument("--timeout", type=float, default=900, help="seconds per run before it counts as failed")
    args = parser.parse_args()
    scripts = [s for s in sorted(glob.glob(os.path.join(GUIDE, "*.py")))
               if not args.patterns or any(p in os.path.basename(s) for p in args.patterns)]

    from robotarium_bringup.testbed import LocalTestbed, testbed_answers
    domain = unique_domain_id()
    env = node_env(domain)
    saved = dict(os.environ)
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    bags = tempfile.mkdtemp(prefix="bench-hardware-")
    testbed = LocalTestbed(log_dir=bags, bags_dir=bags).start()
    try:
        if not testbed_answers(timeout=60):
            sys.exit("the testbed did not come up: %s" % testbed.failed())
        os.environ.clear()
        os.environ.update(saved)
        print("guide scripts, ideal vs hardware-like, lockstep, %s, %s, %d cores, seed %d" % (
            time.strftime("%Y-%m-%d"), platform.machine(), os.cpu_count(), args.seed))
        print("%-44s %-34s %-34s" % ("", "ideal", "hardware-like"))
        print("%-44s %-34s %-34s %s" % ("script", " steps    error  col  out   act", " steps    error  col  out   act",
                                        "wall ideal / hw"))
        for script in scripts:
            ideal, ideal_wall = run(script, args.seed, args.max_steps, env, False, args.timeout)
            hardware, hardware_wall = run(script, args.seed, args.max_steps, env, True, args.timeout)
            print("%-44s %s %s %6.1fs %6.1fs" % (os.path.basename(script)[:44], cell(ideal), cell(hardware),
                                                 ideal_wall, hardware_wall), flush=True)
        print("steps: step() calls to the end (+: stopped unfinished at --max-steps); error: metres from the script's "
              "own goal at its end (bench/guide_outcome.py; n/a: goals unreachable by design); col, out, act: the "
              "debug report's iterations with robots colliding, outside the arena, over the actuator limits.")
    finally:
        testbed.stop()
        shutil.rmtree(bags, ignore_errors=True)


if __name__ == "__main__":
    main()
