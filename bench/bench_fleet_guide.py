"""Every guide listing (examples/guide/) through `./robotarium up --fleet` on a simulated fleet tracked by
motion capture: per listing, how the run ended, its steps, and the debug report's collision and boundary
iterations (both must be 0), with the seconds it took (the drive-on phase included).

One fleet and testbed per number of robots the listings use (a fleet's robots that an experiment does not
use would stand in its way), numpy seeded (devtools/run_seeded.py); loops of more than --iterations steps
are shortened to it, and every run ends at --time-limit s of testbed time at the latest (exit 5, "time
limit": a listing that runs until its goals are reached may take longer in real time).

Run: ./robotarium bench fleet_guide [--iterations K] [--time-limit S] [PATTERN ...]
"""
import argparse
import glob
import os
import platform
import re
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
from devtools.e2e import own_domain_testbed  # noqa: E402
from devtools.rosutil import node_env, unique_domain_id  # noqa: E402

GUIDE = sorted(glob.glob(os.path.join(REPO, "examples", "guide", "*.py")))
SEEDED = os.path.join(REPO, "devtools", "run_seeded.py")


class Folders:
    """tmp_path_factory's mktemp, for own_domain_testbed outside pytest."""

    def __init__(self):
        self.root = tempfile.mkdtemp(prefix="bench-fleet-guide-")

    def mktemp(self, name):
        return tempfile.mkdtemp(prefix=name, dir=self.root)


def robots_of(script):
    with open(script) as f:
        return int(re.search(r"^N\s*=\s*(\d+)", f.read(), re.MULTILINE).group(1))


def settings_of(script, iterations):
    with open(script) as f:
        found = re.search(r"^iterations\s*=\s*(\d+)", f.read(), re.MULTILINE)
    return ["--set", "iterations=%d" % iterations] if found and int(found.group(1)) > iterations else []


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--iterations", type=int, default=300, help="longest loop of a listing (default 300)")
    parser.add_argument("--time-limit", type=float, default=60.0, help="s of testbed time a run may take")
    parser.add_argument("patterns", nargs="*", help="only listings whose name contains one of these")
    args = parser.parse_args()
    from robotarium_hardware.sim_fleet import SimulatedFleet
    scripts = [s for s in GUIDE if not args.patterns or any(p in os.path.basename(s) for p in args.patterns)]
    by_robots = {}
    for script in scripts:
        by_robots.setdefault(robots_of(script), []).append(script)
    load = os.getloadavg()
    print("bench_fleet_guide: %s, %s (%s, %d cores), load %.2f %.2f %.2f; loops <= %d steps, time limit %g s" % (
        time.strftime("%Y-%m-%d %H:%M"), platform.node(), platform.machine(), os.cpu_count(), *load,
        args.iterations, args.time_limit), flush=True)
    print("%-52s %3s %-12s %6s %10s %9s %7s" % ("listing", "N", "outcome", "steps", "collisions", "boundary",
                                                 "seconds"), flush=True)
    folders = Folders()
    for number, group in sorted(by_robots.items()):
        domain = unique_domain_id()
        # 0.15 s before a robot or the tracking counts as gone (tests/test_own_robots.py's RELAXED): this measures
        # the listings, not the stop bounds, which need 0.06 s
        fleet = SimulatedFleet(number, "mocap", os.path.join(folders.root, "fleet-%d.yaml" % number),
                               env=node_env(domain), log_dir=folders.mktemp("fleet-%d-" % number),
                               answer_timeout=0.15, lost_after=0.15)
        fleet.start(say=lambda line: None)
        try:
            if not fleet.wait_ready():
                sys.exit("the fleet of %d did not come up: %s" % (number, fleet.failed()))
            with own_domain_testbed(folders, domain=domain, fleet_file=fleet.fleet_file) as (env, bags, _):
                for script in group:
                    start = time.monotonic()
                    out = subprocess.run(
                        [sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--no-video", "--no-verdict",
                         "--time-limit", "%g" % args.time_limit, SEEDED, "--", *settings_of(script, args.iterations),
                         "1", script], env=env, capture_output=True, text=True, cwd=os.path.dirname(script),
                        timeout=args.time_limit * 4 + 120)
                    text = out.stdout + out.stderr
                    outcome = {0: "completed", 5: "time limit"}.get(out.returncode, "exit %d" % out.returncode)
                    collisions = re.search(r"(\d+) iteration\(s\) where robots collided", text)
                    outside = re.search(r"(\d+) iteration\(s\) robots were outside", text)
                    steps = re.search(r'"steps": (\d+)', open(os.path.join(run_folder(text), "run.json")).read()) \
                        if run_folder(text) else None
                    print("%-52s %3d %-12s %6s %10s %9s %7.1f" % (
                        os.path.basename(script)[:52], number, outcome, steps.group(1) if steps else "?",
                        collisions.group(1) if collisions else 0, outside.group(1) if outside else 0,
                        time.monotonic() - start), flush=True)
                    if out.returncode not in (0, 5):
                        print("    " + "\n    ".join(text.splitlines()[-6:]), flush=True)
        finally:
            fleet.stop()


def run_folder(text):
    found = [line.split("results in ", 1)[1].split(" (open ")[0] for line in text.splitlines() if "] results in " in line]
    return found[-1] if found else None


if __name__ == "__main__":
    main()
