"""`run`'s verdict beside `verify`'s and the Robotarium simulator's count, on scripts that crash or
leave the arena (issue 36: no count a student reads is a guess). For each script:

  0.0.0       robotarium-python-simulator 0.0.0's robotarium.py in this process (devtools.safe_scripts),
              as published, and with the guide's thresholding ("+g": what the testbed drives);
  verify      ./robotarium verify --json SCRIPT: the safety node audits (the script's own commands go
              through), the simulator counts, the rules judge;
  run         ./robotarium run --lockstep SCRIPT: the safety layer keeps the robots apart and inside, so
              the run's own counts are 0 / 0; it then judges the script as verify does and prints that
              verdict (run.json: verdict).

Counts are collision / boundary iterations. Run: ./robotarium bench verify [SCRIPT[:NAME=VALUE] ...]
"""
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)
from devtools import safe_scripts  # noqa: E402
from devtools.rosutil import node_env, unique_domain_id  # noqa: E402

DATA = os.path.join(REPO, "tests", "data")
RUN_SEEDED = os.path.join(REPO, "devtools", "run_seeded.py")
CASES = ["head_on_no_barrier.py", "held_apart.py", "brief_exit.py", "brief_exit.py:EXIT_STEPS=102", "chases_into.py",
         "line_swap_unicycle.py", "leaves_arena.py", "two_robots_to_goals.py"]


def cli(env, *args):
    return subprocess.run([sys.executable, "-m", "robotarium_cli", *args], env=env, capture_output=True,
                          text=True, timeout=900)


def main(argv):
    cases = argv or CASES
    env = node_env(unique_domain_id())
    print("verdicts, %s, %s, %d cores, load average %.1f" % (time.strftime("%Y-%m-%d %H:%M"), platform.machine(),
                                                            os.cpu_count(), os.getloadavg()[0]))
    print("| script | 0.0.0 | 0.0.0+g | verify | run's own run | run's verdict | arrays changed |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as work:
        for case in cases:
            name, _, setting = case.partition(":")
            script = os.path.join(DATA, name) if not os.path.isabs(name) else name
            settings = [tuple(setting.split("=", 1))] if setting else []
            sets = [arg for key, value in settings for arg in ("--set", "%s=%s" % (key, value))]
            raw = safe_scripts.run_script(script, safe_scripts.reference_robotarium(), 1, settings)
            guide = safe_scripts.run_script(script, safe_scripts.reference_robotarium(guide_thresholding=True), 1,
                                            settings)
            verdict_file = os.path.join(work, "verdict.json")
            cli(env, "verify", "--no-record", "--json", verdict_file, "--results-dir", os.path.join(work, "results"),
                RUN_SEEDED, *sets, "1", script)
            with open(verdict_file) as f:
                verified = json.load(f)
            bags = tempfile.mkdtemp(dir=work)
            cli(env, "run", "--lockstep", "--no-video", "--bags-dir", bags, "--results-dir", bags, RUN_SEEDED, *sets,
                "1", script)
            (folder,) = [os.path.join(bags, d) for d in os.listdir(bags) if not d.startswith(".")]
            with open(os.path.join(folder, "run.json")) as f:
                run = json.load(f)
            judged = run.get("verdict") or {"verdict": "(none: nothing changed)", "counts": run, "rules": []}

            def pair(counts):
                return "%d / %d" % (counts["collisions"], counts["boundary_violations"])

            def said(document):
                rules = ", ".join(r["rule"] for r in document["rules"])
                return "%s %s%s" % (pair(document["counts"]), document["verdict"], " (%s)" % rules if rules else "")

            print("| %s | %d / %d | %d / %d | %s | %s | %s | %d |" % (
                case, raw.collisions, raw.boundary, guide.collisions, guide.boundary, said(verified), pair(run),
                said(judged), run["safety_interventions"]), flush=True)
    print("(collision / boundary iterations; the limits: 100 each)")


if __name__ == "__main__":
    main(sys.argv[1:])
