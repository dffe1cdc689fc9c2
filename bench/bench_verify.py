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

--wall: a verdict in seconds (issue 40, goal 2: `verify` of a 300-step script <= 3 s). The wall time from
Enter to the prompt of `./robotarium verify` (through ./robotarium, as a user types it: the environment
check included) of bench/wall_script.py (3 robots, 300 lockstep steps), median of --repeat runs,
interleaved so every row sees the same load: the Robotarium simulator 0.0.0 printing its debug report
(.venv-reference, one process); verify on a testbed of its own, recorded (the default) and --no-record
(the portal's); the same with a warm verification testbed (./robotarium up --verification, and
--no-record) running; with --baseline CHECKOUT, that checkout's ./robotarium verify too (e.g. a worktree
of main before a change), and each row's ratio to the baseline's row of the same flags.
Run: ./robotarium bench verify --wall [--repeat 5] [--baseline CHECKOUT]
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


GOAL = 3.0   # s, issue 40 goal 2: verify of a 300-step script


def wall(argv):
    """--wall: the table and the goal's verdict (see the module's doc)."""
    import argparse
    import shutil
    import statistics

    from bench_wall_to_prompt import SCRIPT, Up, timed

    from devtools.reference import REFERENCE_PYTHON, _reference_env
    parser = argparse.ArgumentParser(prog="./robotarium bench verify --wall",
                                     description="A verdict in seconds (issue 40, goal 2): see ./robotarium bench verify --help.")
    parser.add_argument("--repeat", type=int, default=5, help="runs of each row, interleaved (the median is shown)")
    parser.add_argument("--baseline", metavar="CHECKOUT", help="also time that checkout's ./robotarium verify")
    args = parser.parse_args(argv)
    print("a verdict in seconds, %s, %s, %d cores, Python %s, load average %.2f %.2f %.2f" % (
        time.strftime("%Y-%m-%d %H:%M"), platform.machine(), os.cpu_count(), platform.python_version(),
        *os.getloadavg()), flush=True)
    robotarium = os.path.join(REPO, "robotarium")
    checkouts = [robotarium] + ([os.path.join(os.path.abspath(args.baseline), "robotarium")] if args.baseline else [])
    for each in checkouts:
        subprocess.run([each, "setup"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    work = tempfile.mkdtemp(prefix="bench-verify-")
    env = {k: v for k, v in os.environ.items() if k not in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY")}

    def on(domain, **more):
        return dict(env, ROS_DOMAIN_ID=str(domain), **more)
    own, warm, warm_unrecorded = (on(unique_domain_id()) for _ in range(3))
    ups = []
    # (row, command, environment, the baseline's row of the same flags)
    plans = []
    for name, command_of in (("", robotarium), ("baseline ", checkouts[-1] if args.baseline else None)):
        if command_of is None:
            continue
        verify = [command_of, "verify", "--bags-dir", os.path.join(work, "bags"), "--results-dir",
                  os.path.join(work, "results")]
        plans += [(name + "own", verify + [SCRIPT], own), (name + "own --no-record", verify + ["--no-record", SCRIPT], own)]
    try:
        ups.append(Up(robotarium, warm, os.path.join(work, "bags"), ["--verification"]))
        ups.append(Up(robotarium, warm_unrecorded, os.path.join(work, "bags"), ["--verification", "--no-record"]))
        verify = [robotarium, "verify", "--bags-dir", os.path.join(work, "bags"), "--results-dir",
                  os.path.join(work, "results")]
        plans += [("warm", verify + [SCRIPT], warm), ("warm --no-record", verify + ["--no-record", SCRIPT], warm_unrecorded)]
        rows = {"peer": []}
        rows.update({name: [] for name, _, _ in plans})
        for _ in range(args.repeat):   # interleaved: every row sees the same load
            rows["peer"].append(timed([REFERENCE_PYTHON, SCRIPT], _reference_env(), tempfile.gettempdir()))
            for name, command, row_env in plans:
                rows[name].append(timed(command, row_env, work))
    finally:
        for up in ups:
            up.stop()
        shutil.rmtree(work, ignore_errors=True)
    labels = {"peer": "Robotarium simulator 0.0.0 (one process, its debug report)",
              "own": "`./robotarium verify`, a testbed of its own, recorded (the default)",
              "own --no-record": "same, `--no-record` (the portal's)",
              "warm": "`./robotarium verify`, `up --verification` running, recorded",
              "warm --no-record": "same, `--no-record`, `up --verification --no-record` running"}
    same_flags = {"own": "baseline own", "own --no-record": "baseline own --no-record",
                  "warm": "baseline own", "warm --no-record": "baseline own --no-record"}
    median = {name: statistics.median(r[0] for r in runs) for name, runs in rows.items()}
    print("3 robots, 300 lockstep steps (bench/wall_script.py); median of %d runs, interleaved; load average after: "
          "%.2f %.2f %.2f" % (args.repeat, *os.getloadavg()))
    print("| | wall (s) | CPU (s) | runs (s) |%s" % (" baseline, same flags: wall (s) | ratio |" if args.baseline else ""))
    print("|---|---|---|---|%s" % ("---|---|" if args.baseline else ""))
    for name, runs in rows.items():
        base = name.replace("baseline ", "")
        label = labels[base] + (" (baseline checkout)" if name != base else "")
        paired = same_flags.get(name) if args.baseline else None
        print("| %s | %.2f | %.2f | %s |%s" % (
            label, median[name], statistics.median(r[4] for r in runs), " ".join("%.2f" % r[0] for r in runs),
            " %.2f | %.2f |" % (median[paired], median[name] / median[paired]) if paired else
            (" | |" if args.baseline else "")))
    print("CPU: user + system time of the command's processes (the script, a testbed it started; not that of "
          "`up --verification`'s testbed)")
    goals = {"warm": "verify, up --verification running, recorded", "warm --no-record": "the same, --no-record",
             "own": "verify, a testbed of its own, recorded", "own --no-record": "the same, --no-record"}
    for name, label in goals.items():
        print("goal: %s <= %.1f s: %.2f s (%.1f x the peer's %.2f s) -> %s" % (
            label, GOAL, median[name], median[name] / median["peer"], median["peer"],
            "met" if median[name] <= GOAL else "not met"))


def main(argv):
    if argv[:1] == ["--wall"]:
        return wall(argv[1:])
    import argparse
    parser = argparse.ArgumentParser(prog="./robotarium bench verify", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("cases", nargs="*", metavar="SCRIPT[:NAME=VALUE]",
                        help="scripts (in tests/data/ unless absolute), a module constant to set after the colon "
                             "(default: %s)" % " ".join(CASES))
    parser.add_argument("--wall", action="store_true",
                        help="the wall-time table instead (first argument; its options: --wall --help)")
    cases = parser.parse_args(argv).cases or CASES
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
