"""How fast a testbed that `./robotarium run` started goes away when `run` is stopped by a signal.

For each signal (SIGTERM, SIGHUP, SIGINT, SIGKILL) and --repeats times: `./robotarium run` starts
a local testbed for a real-time 2-robot script that runs forever (tests/data/run_forever.py), the
script's loop runs, and the signal goes to the `run` process alone (as `kill PID` does).
Measured from the signal (wall clock):
  - noticed: the latest of the three nodes' "stopping: ..." log lines (their own ROS stamps): how
    long each node took to learn that it must stop (SIGKILL: through its lifeline);
  - bag closed: the run's metadata.yaml says complete (the recorder closed the bag after recording
    the end of the experiment);
  - all gone: no process with the run's ROS_DOMAIN_ID is left (the script, `run`, the nodes).
Run: ./robotarium bench testbed_lifetime [--repeats 3]
"""
import argparse
import glob
import os
import platform
import re
import shutil
import signal
import statistics
import tempfile
import time

import yaml

from devtools.rosutil import CliRun, node_env, processes_on_domain, unique_domain_id  # noqa: E402

FOREVER = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests", "data", "run_forever.py")
NS = "/lifetime"


def bag_complete(folder):
    try:
        with open(os.path.join(folder, "metadata.yaml")) as f:
            info = yaml.safe_load(f)["rosbag2_bagfile_information"]
        return str(info.get("custom_data", {}).get("complete")) == "true"
    except (OSError, KeyError, TypeError, yaml.YAMLError):
        return False


def stop_lines(log_dir):
    """Wall-clock stamps of the nodes' "stopping:" log lines."""
    stamps = []
    for path in glob.glob(os.path.join(log_dir, "*.log")):
        with open(path, errors="replace") as f:
            for line in f:
                match = re.search(r"\[(\d+\.\d+)\] \[[^]]+\]: stopping: ", line)
                if match:
                    stamps.append(float(match.group(1)))
    return stamps


def once(sig, work, k):
    domain = unique_domain_id()
    root = os.path.join(work, "%s_%d" % (sig.name, k))
    os.makedirs(root)
    script = os.path.join(root, "forever.py")
    shutil.copy(FOREVER, script)
    bags = os.path.join(root, "bags")
    env = node_env(domain, ROBOTARIUM_NAMESPACE=NS, ROBOTARIUM_ROOT=root, ROBOTARIUM_PROGRESS="0")
    run = CliRun(["--bags-dir", bags, "--no-video", script], env, cwd=root)
    try:
        if not run.wait_for("RUNNING", timeout=90):
            raise RuntimeError("the run did not start:\n" + run.output())
        time.sleep(1.0)
        t0 = time.time()
        os.kill(run.proc.pid, sig)
        closed = gone = None
        while time.time() - t0 < 30 and (closed is None or gone is None):
            now = time.time() - t0
            folders = glob.glob(os.path.join(bags, "forever_*"))
            if closed is None and folders and bag_complete(folders[0]):
                closed = now
            if gone is None and not processes_on_domain(domain):
                gone = now
            time.sleep(0.01)
        run.wait(timeout=30)
    finally:
        run.close()
        for pid in processes_on_domain(domain):
            os.kill(pid, signal.SIGKILL)
    (log_dir,) = glob.glob(os.path.join(root, "log", "testbed", "*"))
    stamps = stop_lines(log_dir)
    noticed = max(stamps) - t0 if len(stamps) == 3 else None
    return noticed, closed, gone


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print("%s, %s, Python %s, load average %.1f" % (time.strftime("%Y-%m-%d"), platform.machine(),
                                                    platform.python_version(), os.getloadavg()[0]))
    print("| signal to ./robotarium run | nodes noticed (s) | bag closed (s) | all processes gone (s) |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="bench-lifetime-") as work:
        for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT, signal.SIGKILL):
            results = [once(sig, work, k) for k in range(args.repeats)]

            def cell(i):
                values = [r[i] for r in results if r[i] is not None]
                missing = len(results) - len(values)
                text = "%.2f / %.2f" % (statistics.median(values), max(values)) if values else "-"
                return text + (" (%d never)" % missing if missing else "")
            print("| %s | %s | %s | %s |" % (sig.name, cell(0), cell(1), cell(2)), flush=True)
    print("(median / max of %d runs each, seconds after the signal)" % args.repeats)


if __name__ == "__main__":
    main()
