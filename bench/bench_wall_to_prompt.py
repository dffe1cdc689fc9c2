"""Wall to prompt (issue 26, goal 1): the time from pressing Enter to the prompt with every result
in hand, for one 3-robot script of 300 lockstep steps with no figure and no barrier certificate
(bench/wall_script.py), measured side by side in one run:

  (peer)  the Robotarium simulator 0.0.0 (.venv-reference), `python wall_script.py`: one process,
          no results;
  (cold)  `./robotarium run --lockstep wall_script.py` with no testbed up: it starts one for the
          run and stops it afterwards; every result (report, plot, video, page);
  (cold, --no-video)  the same without the video;
  (cold, localhost discovery)  the same with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (what the
          tests use, and a one-machine user may set): the process table then knows every testbed
          that could answer, so `run` does not wait for one elsewhere on the network;
  (up)    the same with `./robotarium up` already running on the domain; and --no-video;
  (live video off)  with ROBOTARIUM_LIVE_VIDEO=0: the video made from the bag after the run, as before
          the live video (robotarium_recording.live_video) made it while the run goes;
  (up, real time)  the same script in real time (300 steps: 10 s of robots), with the live video and
          without it: what is left after the run's end.

Each command runs through ./robotarium as a user types it (the environment check included),
on a ROS_DOMAIN_ID of its own, with the machine's default discovery range (but where said); the
wall time is from the start of the command to its exit. The script prints its constructor and loop times (inside
the script). Runs are interleaved (--repeat times) so every row sees the same machine load; the
table gives the medians, then the goals' verdicts: <= 2.5 s cold and <= 1.5 s with a testbed up,
both with every result.
Run: ./robotarium bench wall_to_prompt [--repeat 3] [--baseline CHECKOUT]
"""
import argparse
import os
import platform
import re
import resource
import shutil
import signal
import statistics
import subprocess
import tempfile
import time

from devtools.reference import REFERENCE_PYTHON, _reference_env
from devtools.rosutil import unique_domain_id

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(REPO, "bench", "wall_script.py")
GOALS = {"cold": 2.5, "cold local": 2.5, "up": 1.5}   # s, with every result (issue 26, goal 1)


def timed(command, env, cwd):
    """(wall seconds, constructor s, loop s, output, CPU seconds) of one command (the CPU time of its
    whole process tree: the testbed it starts, the script, ffmpeg; not that of a testbed `up` runs)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    out = subprocess.run(command, env=env, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         timeout=300)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    match = re.search(r"TIMES ([0-9.]+) ([0-9.]+)", out.stdout)
    if out.returncode != 0 or not match:
        raise RuntimeError("%s failed (exit code %d):\n%s" % (" ".join(command), out.returncode, out.stdout))
    return wall, float(match.group(1)), float(match.group(2)), out.stdout, cpu


def results_of(output):
    """The files of the run folder the last line names."""
    match = re.search(r"files: (.*)", output)
    return set(match.group(1).split(", ")) if match else set()


class Up:
    """./robotarium up (of the checkout `robotarium` names) on the domain, until stop()."""

    def __init__(self, robotarium, env, bags, flags=()):
        self.process = subprocess.Popen([robotarium, "up", "--bags-dir", bags, *flags], env=env, stdout=subprocess.DEVNULL,
                                        stderr=subprocess.PIPE, text=True, start_new_session=True)
        for line in self.process.stderr:
            if "testbed up" in line:
                return
        raise RuntimeError("./robotarium up did not come up")

    def stop(self):
        os.killpg(self.process.pid, signal.SIGINT)
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()


LABELS = {"peer": "Robotarium simulator 0.0.0 (one process, no results)",
          "cold": "`./robotarium run`, no testbed up (starts one), with video",
          "cold --no-video": "same, `--no-video`",
          "cold local": "`./robotarium run`, no testbed up, localhost discovery, with video",
          "cold local --no-video": "same, `--no-video`",
          "up": "`./robotarium up` already running, with video",
          "up --no-video": "same, `--no-video`",
          "cold live off": "`./robotarium run`, no testbed up, with video, live video off (made from the bag)",
          "up live off": "`./robotarium up` already running, with video, live video off (made from the bag)",
          "up real time": "`./robotarium up` already running, real time (10 s of robots), with video",
          "up real time live off": "same, live video off (made from the bag)"}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--baseline", metavar="CHECKOUT",
                        help="also time the same rows with another checkout's ./robotarium (e.g. a worktree of main "
                             "before a change), interleaved, so both see the same load")
    args = parser.parse_args()
    print("wall to prompt, %s, %s, %d cores, Python %s, load average %.2f %.2f %.2f" % (
        time.strftime("%Y-%m-%d %H:%M"), platform.machine(), os.cpu_count(), platform.python_version(),
        *os.getloadavg()), flush=True)
    checkouts = {"": os.path.join(REPO, "robotarium")}
    if args.baseline:
        checkouts["baseline "] = os.path.join(os.path.abspath(args.baseline), "robotarium")
    for robotarium in checkouts.values():
        subprocess.run([robotarium, "setup"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    work = tempfile.mkdtemp(prefix="bench-wall-")
    bags = os.path.join(work, "bags")
    env = {k: v for k, v in os.environ.items() if k not in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY")}
    rows = {"peer": []}
    files = {}
    ups = []
    try:
        plans = []
        for prefix, robotarium in checkouts.items():
            cold_env = dict(env, ROS_DOMAIN_ID=str(unique_domain_id()))
            local_env = dict(cold_env, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
            up_env = dict(env, ROS_DOMAIN_ID=str(unique_domain_id()))
            ups.append(Up(robotarium, up_env, bags))
            run = [robotarium, "run", "--bags-dir", bags, "--results-dir", os.path.join(work, "results")]
            lockstep, off = ["--lockstep"], {"ROBOTARIUM_LIVE_VIDEO": "0"}
            for name, flags, row_env in (("cold", lockstep, cold_env),
                                         ("cold --no-video", lockstep + ["--no-video"], cold_env),
                                         ("cold live off", lockstep, dict(cold_env, **off)),
                                         ("cold local", lockstep, local_env),
                                         ("cold local --no-video", lockstep + ["--no-video"], local_env),
                                         ("up", lockstep, up_env), ("up --no-video", lockstep + ["--no-video"], up_env),
                                         ("up live off", lockstep, dict(up_env, **off)),
                                         ("up real time", ["--real-time"], up_env),
                                         ("up real time live off", ["--real-time"], dict(up_env, **off))):
                plans.append((prefix + name, run + flags + [SCRIPT], row_env))
                rows[prefix + name] = []
        for _ in range(args.repeat):   # interleaved: every row sees the same load
            rows["peer"].append(timed([REFERENCE_PYTHON, SCRIPT], _reference_env(), tempfile.gettempdir()))
            for name, command, row_env in plans:
                rows[name].append(timed(command, row_env, work))
                files[name] = results_of(rows[name][-1][3])
    finally:
        for up in ups:
            up.stop()
        shutil.rmtree(work, ignore_errors=True)
    print("3 robots, 300 steps (lockstep but where said), no figure, no barrier (bench/wall_script.py); median of "
          "%d runs, interleaved" % args.repeat)
    print("| | wall to prompt (s) | constructor / loop (s) | CPU (s) | runs (s) |")
    print("|---|---|---|---|---|")
    median = {}
    for name, runs in rows.items():
        median[name] = statistics.median(r[0] for r in runs)
        base = name.replace("baseline ", "")
        label = LABELS[base] + (" (baseline checkout)" if name != base else "")
        print("| %s | %.2f | %.2f / %.2f | %.2f | %s |" % (
            label, median[name], statistics.median(r[1] for r in runs), statistics.median(r[2] for r in runs),
            statistics.median(r[4] for r in runs), " ".join("%.2f" % r[0] for r in runs)))
    print("CPU: user + system time of the command's processes (the script, ffmpeg, a testbed it started; not "
          "that of `up`'s testbed)")
    print("load average after: %.2f %.2f %.2f" % os.getloadavg())
    for name, goal in GOALS.items():
        complete = {"report.txt", "trajectories.png", "run.mp4", "index.html"} <= files.get(name, set())
        print("goal: %s with every result <= %.1f s: %.2f s (%.1f x the peer's %.2f s)%s -> %s" % (
            LABELS[name], goal, median[name], median[name] / median["peer"], median["peer"],
            "" if complete else " (results missing: %s)" % sorted(files.get(name, ())),
            "met" if median[name] <= goal and complete else "not met"))


if __name__ == "__main__":
    main()
