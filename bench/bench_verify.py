"""How close `run`'s estimate of what the safety layer prevented comes to the Robotarium's count,
on scripts that crash (issue 23). For each script:

  reference   robotarium-python-simulator 0.0.0 (.venv-reference) runs the file unchanged: its
              debug report's collision and boundary iterations;
  audited     ./robotarium verify SCRIPT: the safety node audits and lets the script's commands
              through, the simulator counts (and the verdict);
  replay      ./robotarium run --lockstep SCRIPT: the safety layer on; the safety node's unfiltered
              replay of the script's own commands (model.UnfilteredReplay), what the report says
              it prevented (run.json: prevented_collisions, prevented_boundary_violations);
  one-step    the same run's recording: from each step's poses, the script's requested commands
              for one step (model.lookahead_violations), summed.

Counts are collisions / boundary iterations. Run: ./robotarium bench verify [SCRIPT ...]
"""
import json
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
from devtools.reference import REFERENCE_PYTHON, _reference_env  # noqa: E402
from devtools.rosutil import node_env, unique_domain_id  # noqa: E402

DATA = os.path.join(REPO, "tests", "data")
SCRIPTS = [os.path.join(DATA, name) for name in ("head_on_no_barrier.py", "line_swap_unicycle.py", "leaves_arena.py",
                                                 "two_robots_to_goals.py")]


def counts(text):
    def count(pattern):
        match = re.search(r"had (\d+) iteration\(s\) " + pattern, text)
        return int(match.group(1)) if match else 0
    return count("where robots collided"), count("robots were outside")


def reference(script):
    out = subprocess.run([REFERENCE_PYTHON, script], env=_reference_env(), capture_output=True, text=True,
                         cwd=os.path.dirname(script), timeout=600)
    return counts(out.stdout)


def cli(env, *args):
    return subprocess.run([sys.executable, "-m", "robotarium_cli", *args], env=env, capture_output=True,
                          text=True, timeout=600)


def one_step(folder):
    from robotarium_core import model
    from robotarium_recording.bag import Bag
    bag = Bag(folder)
    config, track = bag.config(), bag.poses()
    by_step = {int(s): np.vstack((track.x[i], track.y[i], track.theta[i])) for i, s in enumerate(track.steps)}
    commands = np.zeros((2, track.x.shape[1]))
    total = np.zeros(2, dtype=int)
    for k, cmd in enumerate(bag.commands("cmd_requested"), start=1):
        commands[0, cmd.ids], commands[1, cmd.ids] = cmd.v, cmd.omega
        if k - 1 in by_step:   # step k moves from the poses of step k - 1
            total += model.lookahead_violations(by_step[k - 1], commands, config.time_step, config.robot_diameter,
                                                config.arena, **config.limits)
    return tuple(int(v) for v in total)


def main(argv):
    scripts = [os.path.abspath(a) for a in argv] or SCRIPTS
    env = node_env(unique_domain_id())
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for script in scripts:
            name = os.path.basename(script)
            verdict_file = os.path.join(work, name + ".json")
            cli(env, "verify", "--no-record", "--json", verdict_file, "--results-dir", os.path.join(work, "results"),
                script)
            with open(verdict_file) as f:
                verdict = json.load(f)
            audited = (verdict["counts"]["collisions"], verdict["counts"]["boundary_violations"])
            bags = os.path.join(work, "bags_" + name)
            out = cli(env, "run", "--lockstep", "--no-video", "--bags-dir", bags, script)
            (folder,) = [os.path.join(bags, d) for d in os.listdir(bags)]
            with open(os.path.join(folder, "run.json")) as f:
                run = json.load(f)
            replay = (run["prevented_collisions"], run["prevented_boundary_violations"])
            said = ("acceptance likely" if "Acceptance of your experiment is likely" in out.stdout else
                    "safety layer prevented" if "would have made about" in out.stdout else "errors listed")
            rows.append((name, reference(script), audited, replay, one_step(folder),
                         "%s (%s)" % (verdict["verdict"], ", ".join(r["rule"] for r in verdict["rules"]) or "-"), said))
    print("| script | reference 0.0.0 | audited (verify) | replay estimate (run) | one-step look-ahead | verify | run's "
          "report says |")
    print("|---|---|---|---|---|---|---|")
    for name, ref, audited, replay, step, verdict, said in rows:
        print("| %s | %d / %d | %d / %d | %d / %d | %d / %d | %s | %s |" % (name, *ref, *audited, *replay, *step, verdict,
                                                                         said))
    print("(collision iterations / boundary iterations)")


if __name__ == "__main__":
    main(sys.argv[1:])
