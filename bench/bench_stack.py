"""End-to-end steps per second: the same N = 20 script with a single-integrator barrier
certificate (bench/stack_script.py), run
  (a) through this stack in lockstep: the client, the safety node and the simulator in separate
      processes over DDS (a local testbed started for the run, not recorded), and
  (b) on the Robotarium's own simulator (robotarium-python-simulator 0.0.0 in .venv-reference,
      sim_in_real_time=False, show_figure=False), in one process,
printed side by side with the ratio. Each side is timed inside the script, over the loop only.
Run: ./robotarium bench stack [--iterations K] [--repeat R]
"""
import argparse
import os
import platform
import re
import statistics
import subprocess
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(REPO, "bench", "stack_script.py")
from devtools.reference import REFERENCE_PYTHON, _reference_env  # noqa: E402
from devtools.rosutil import node_env, unique_domain_id  # noqa: E402


def steps_per_second(output):
    match = re.search(r"STEPS_PER_SECOND ([0-9.]+)", output)
    if not match:
        raise RuntimeError("the script printed no rate:\n" + output)
    return float(match.group(1))


def ours(iterations):
    env = node_env(unique_domain_id())
    out = subprocess.run([sys.executable, "-m", "robotarium_cli", "run", "--lockstep", "--no-record",
                          SCRIPT, str(iterations)], env=env, capture_output=True, text=True, cwd=REPO, timeout=600)
    return steps_per_second(out.stdout + out.stderr)


def reference(iterations):
    out = subprocess.run([REFERENCE_PYTHON, SCRIPT, str(iterations)], env=_reference_env(), capture_output=True,
                         text=True, cwd="/tmp", timeout=600)
    return steps_per_second(out.stdout + out.stderr)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--iterations", type=int, default=300)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print("stack benchmark, %s, %s, %d cores, load average %.1f" % (
        time.strftime("%Y-%m-%d"), platform.machine(), os.cpu_count(), os.getloadavg()[0]))
    a, b = [], []
    for _ in range(args.repeat):  # interleaved, so both sides see the same machine load
        a.append(ours(args.iterations))
        b.append(reference(args.iterations))
    print("N = 20, single-integrator barrier certificate with boundary, %d iterations, %d runs each (median)"
          % (args.iterations, args.repeat))
    print("  %-58s %10.1f steps/s" % ("(a) this stack, lockstep, 3 processes over DDS", statistics.median(a)))
    print("  %-58s %10.1f steps/s" % ("(b) Robotarium simulator 0.0.0, one process (cvxopt)", statistics.median(b)))
    print("  ratio (a)/(b): %.2f   (runs: a %s, b %s)" % (statistics.median(a) / statistics.median(b),
                                                         [round(x) for x in a], [round(x) for x in b]))


if __name__ == "__main__":
    main()
