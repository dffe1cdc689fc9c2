"""The soak (issue 41): one testbed started as `./robotarium up` starts it, driven for --runs runs (500 by
default) through `./robotarium run --no-local-testbed`, a mix of the guide's listings and the 2.x examples in
lockstep and real time, short and long, with faults injected at random (seeded) and logged: the script's
process killed (SIGKILL), `run` interrupted (SIGINT) or killed (SIGKILL) mid-run, a node killed or frozen
(SIGSTOP for longer than its lease, then SIGCONT) about every --node-every runs, floods of foreign and forged
arrays, the recorder's disk full once (a small tmpfs under its bags: root only). devtools/soak.py says how each
run's end is judged against the fault injected into it.

    ./robotarium bench soak [--runs 500] [--seed 1] [--node-every 50] [--sample-every 100] [--work DIR] [--keep]

It prints the date, machine and load at the start and the end; runs completed; runs ended by a fault, with the
cause each report named, checked against the fault injected; runs lost (no cause, or a wrong one), each listed
with its run.json's words; node restarts (a killed node: `up` stops the testbed, and the soak starts `up`
again, as a supervisor would; nodes that restarted in place, from their log); the largest start latency and
its p99 (from the start of the run's process to its experiment's first RUNNING status, heard by a probe of this
process); RSS, open file descriptors and threads of every node (/proc/<pid>/status and /proc/<pid>/fd) at run 1,
100, 200, ... and at the end. Every run is logged, one JSON line each, in WORK/soak.jsonl; the folders of runs
that were not lost are removed as they are judged (--keep keeps them).

--service: the same through the service (devtools/soak_service.py): PostgreSQL of its own, `./robotarium serve
--jobs 0` and one `./robotarium worker`, --runs experiments (200 by default) submitted a few at a time (the
single-file listings and examples, numpy seeded, long loops shortened), each verified and run in real time;
the worker killed outright mid-run about every --worker-every experiments (a new one started), PostgreSQL
restarted once mid-run. It prints each experiment's end judged (completed, rejected by its verification, ended
by the fault, lost), the time from submission to the run's start, and the portal's and the worker's sizes.
"""
import argparse
import os
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)

from devtools import soak  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(prog="./robotarium bench soak", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=None, help="runs (default 500; --service: experiments, 200)")
    parser.add_argument("--seed", type=int, default=1, help="draws the scripts, modes, lengths and faults (default 1)")
    parser.add_argument("--minutes", type=float,
                        help="start no run after this many minutes: as many of the runs as fit (default: all)")
    parser.add_argument("--node-every", type=int, default=50, help="a node killed or frozen about every N runs (50)")
    parser.add_argument("--sample-every", type=int, default=100,
                        help="the nodes' RSS, fds and threads at run 1 and every N runs (100), and at the end")
    parser.add_argument("--real-time", type=float, default=0.3, help="share of runs in real time (0.3)")
    parser.add_argument("--long", type=float, default=0.3, help="share of long runs (0.3)")
    parser.add_argument("--client-faults", type=float, default=0.16,
                        help="share of runs with a client fault or a flood (0.16)")
    parser.add_argument("--node-faults", nargs="+", choices=soak.NODE_FAULTS, metavar="KIND:NODE",
                        help="the node faults to take in turn (default: kill and freeze in turn, the node at random): "
                             + ", ".join(soak.NODE_FAULTS))
    parser.add_argument("--no-disk", action="store_true", help="no full disk")
    parser.add_argument("--time-limit", type=int, default=150,
                        help="each run's time limit, s of testbed time (150): a goal loop that never converges stops there")
    parser.add_argument("--video", action="store_true", help="make each run's video (default: --no-video)")
    parser.add_argument("--work", help="the soak's folder (default: a new temporary one)")
    parser.add_argument("--keep", action="store_true", help="keep every run's folder")
    parser.add_argument("--verbose", action="store_true", help="a line for every run")
    parser.add_argument("--service", action="store_true",
                        help="through ./robotarium serve and a worker, with a database restart (docstring above)")
    parser.add_argument("--worker-every", type=int, default=50,
                        help="--service: the worker killed mid-run about every N experiments (50)")
    args = parser.parse_args(argv)
    runs = args.runs or (200 if args.service else 500)
    work = args.work or tempfile.mkdtemp(prefix="robotarium-soak-")
    began = time.monotonic()
    if args.service:
        from devtools import soak_service
        print("soak benchmark through the service, %s, %s" % (time.strftime("%Y-%m-%d %H:%M:%S"), soak.machine()),
              flush=True)
        print("start: %s; %d experiments%s, seed %d; work folder %s" % (
            soak.load(), runs, " or as many as fit in %g minutes" % args.minutes if args.minutes else "", args.seed,
            work), flush=True)
        soaked, lines = soak_service.run_service_soak(work, runs, args.seed, say=lambda line: print(line, flush=True),
                                                      minutes=args.minutes, worker_every=args.worker_every)
        print("\n".join(lines))
        print("end: %s, %s; %.1f min for %d experiments" % (time.strftime("%Y-%m-%d %H:%M:%S"), soak.load(),
                                                           (time.monotonic() - began) / 60.0, len(soaked.items)))
        return 0
    print("soak benchmark, %s, %s" % (time.strftime("%Y-%m-%d %H:%M:%S"), soak.machine()), flush=True)
    print("start: %s; %d runs%s, seed %d, a node fault about every %d runs; work folder %s"
          % (soak.load(), runs, " or as many as fit in %g minutes" % args.minutes if args.minutes else "", args.seed,
             args.node_every, work), flush=True)
    soaked, plans, lines = soak.run_soak(
        work, runs, args.seed, node_every=args.node_every, sample_every=args.sample_every, keep=args.keep,
        video=args.video, time_limit=args.time_limit, minutes=args.minutes, say=lambda line: print(line, flush=True),
        progress=1 if args.verbose else 25, real_time=args.real_time, long=args.long,
        client_faults=args.client_faults, disk=not args.no_disk, node_faults=args.node_faults)
    print("\n".join(lines))
    print("end: %s, %s; %.1f min for %d runs" % (time.strftime("%Y-%m-%d %H:%M:%S"), soak.load(),
                                                (time.monotonic() - began) / 60.0, len(soaked.results)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
