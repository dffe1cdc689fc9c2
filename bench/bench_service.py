"""Benchmark: the Robotarium service on PostgreSQL with its workers (./robotarium bench service).

    ./robotarium bench service [--submissions 1] [--robots 5 20 50]

A PostgreSQL server of its own (initdb into a temporary folder), the portal (./robotarium serve
--database ... --jobs 0) and 1, then 2 workers (./robotarium worker: each one verification and one run at
a time) on this machine. Printed:
- verified submissions per hour: a batch of 300-step scripts (the robots turn in place: accepted),
  --submissions of each robot count, submitted at once; the wall time from the submission to the last one
  completed (verified, run in real time at 30 Hz, its results and video made), and for each robot count
  the mean time of ./robotarium verify and ./robotarium run (their timings on the experiment);
- the queue's claim latency: a one-step-script submitted to idle workers, the time until a worker holds its
  verification (the database's state polled every 10 ms), and from queued to running (the database's own
  timestamps); median of 5;
- the time to notice a lost worker: a worker killed outright (kill -9 of every process it started) while it
  runs an experiment, until the experiment says "failed: the testbed was lost" (heartbeat 1 s here, lost
  after 5 missed beats; the default is 2 s and 10 s).
"""
import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)

from devtools.postgres import PostgreSQL, server_binaries  # noqa: E402
from devtools.service import HEARTBEAT, HOLD, Service  # noqa: E402

WAIT = 1800.0   # s for one experiment at most: a loaded machine is slow, and the benchmark says how slow
# 300 steps, the robots on a grid turning in place (no collision, nobody leaves the arena).
TURNING = """import numpy as np
import rps.robotarium as robotarium
N = {robots}
columns = 10
x = -1.35 + 0.3 * (np.arange(N) % columns)
y = -0.75 + 0.3 * (np.arange(N) // columns)
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=False,
                          initial_conditions=np.array([x, y, np.zeros(N)]))
for k in range({steps}):
    r.get_poses()
    r.set_velocities(np.arange(N), np.vstack([np.zeros(N), 0.5 * np.ones(N)]))
    r.step()
r.call_at_scripts_end()
"""


def wait_all(service, pks):
    for pk in pks:
        row = service.wait_for(pk, ("completed", "failed", "rejected"), timeout=WAIT)
        if row["state"] != "completed":
            raise SystemExit("experiment %d %s: %s" % (pk, row["state"], row["detail"]))


def timings(service, pks):
    rows = service.query("SELECT timings FROM robotarium_portal_experiment WHERE id = ANY(%s)", pks)
    verify = [t["verify_command"] for (t,) in rows if "verify_command" in t]
    run = [t["run_command"] for (t,) in rows if "run_command" in t]
    return statistics.mean(verify), statistics.mean(run)


def throughput(service, robot_counts, submissions):
    """(per hour, wall s, {robots: (verify s, run s)}) of one batch."""
    batch = [(robots, k) for k in range(submissions) for robots in robot_counts]
    began = time.monotonic()
    pks = service.submit([{"title": "%d robots %d" % (robots, k), "robots": robots,
                           "script": TURNING.format(robots=robots, steps=300)} for robots, k in batch])
    wait_all(service, pks)
    wall = time.monotonic() - began
    per_count = {robots: timings(service, [pk for pk, (r, _) in zip(pks, batch) if r == robots])
                 for robots in robot_counts}
    return len(pks) / wall * 3600.0, wall, per_count


def claim_latency(service, samples=5):
    to_verifying, to_running = [], []
    script = TURNING.format(robots=2, steps=1)
    for k in range(samples):
        (pk,) = service.submit([{"title": "claim %d" % k, "robots": 2, "script": script}])
        submitted = service.query("SELECT submitted_at FROM robotarium_portal_experiment WHERE id = %s", pk)[0][0]
        while True:
            state, now = service.query("SELECT state, now() FROM robotarium_portal_experiment WHERE id = %s", pk)[0]
            if state != "submitted":
                break
            time.sleep(0.01)
        to_verifying.append((now - submitted).total_seconds())
        wait_all(service, [pk])
        queued, started = service.query("SELECT queued_at, started_at FROM robotarium_portal_experiment "
                                        "WHERE id = %s", pk)[0]
        to_running.append((started - queued).total_seconds())
    return statistics.median(to_verifying), statistics.median(to_running)


def time_to_notice(service, folder):
    release = os.path.join(folder, "release-never")
    (pk,) = service.submit([{"title": "lost", "robots": 2, "script": HOLD.format(release=release, hold_in="work")}])
    service.wait_for(pk, ("running",), timeout=WAIT)
    while not os.path.exists(os.path.join(service.data, "experiments", str(pk), "run-1", "output.txt")):
        time.sleep(0.1)
    name = service.worker_of(pk)
    killed = time.monotonic()
    service.workers.pop(name).kill()
    row = service.wait_for(pk, ("failed",), timeout=WAIT)
    noticed = time.monotonic() - killed
    assert "the testbed was lost" in row["detail"], row
    return noticed


def main():
    parser = argparse.ArgumentParser(prog="./robotarium bench service", description=__doc__.split("\n\n")[0])
    parser.add_argument("--submissions", type=int, default=1,
                        help="submissions of each robot count in a batch (default 1)")
    parser.add_argument("--robots", type=int, nargs="+", default=[5, 20, 50], help="robot counts (default 5 20 50)")
    parser.add_argument("--parts", nargs="+", default=["throughput", "claim", "lost"],
                        choices=["throughput", "claim", "lost"], help="what to measure (default: all three)")
    args = parser.parse_args()
    if server_binaries() is None:
        raise SystemExit("no PostgreSQL server here: apt-get install postgresql")
    folder = tempfile.mkdtemp(prefix="robotarium-bench-service-")
    service = Service(folder)
    try:
        service.postgres = PostgreSQL()
        service.start_portal()
        print("service benchmark: PostgreSQL %s, heartbeat %s s, %d CPU cores; a batch: %d submission(s) of each of "
              "%s robots, 300 steps" % (os.path.basename(os.path.dirname(server_binaries())), HEARTBEAT,
                                        os.cpu_count(), args.submissions, ", ".join(map(str, args.robots))),
              flush=True)
        for workers in (1, 2) if "throughput" in args.parts else ():
            while len(service.workers) < workers:
                service.start_worker("worker-%d" % (len(service.workers) + 1))
            per_hour, wall, per_count = throughput(service, args.robots, args.submissions)
            print("%d worker(s): %.0f verified submissions per hour (the batch of %d in %.1f s); mean ./robotarium "
                  "verify / run: %s" % (workers, per_hour, len(args.robots) * args.submissions, wall, ", ".join(
                      "%d robots %.1f s / %.1f s" % (robots, v, r) for robots, (v, r) in per_count.items())),
                  flush=True)
        if not service.workers:
            service.start_worker("worker-1")
        to_verifying, to_running = claim_latency(service) if "claim" in args.parts else (None, None)
        if "claim" in args.parts:
            print("claim latency (median of 5, idle workers): submitted -> verifying %.3f s, queued -> running %.3f s"
                  % (to_verifying, to_running), flush=True)
        if "lost" in args.parts:
            print("time to notice a worker killed outright mid-run (until its page says failed: the testbed was lost): "
                  "%.1f s" % time_to_notice(service, folder), flush=True)
    finally:
        service.close()
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
