"""The soak through the service (issue 41, `./robotarium bench soak --service`): PostgreSQL of its own, the
portal (`./robotarium serve --jobs 0`) and one `./robotarium worker`, as devtools/service.py starts them, driven
for N experiments submitted as the portal's submit makes them, a few at a time (a class's steady stream): the
guide's listings and the 2.x examples (the single-file ones), numpy seeded at their top, long loops read
shorter (devtools.soak's sets), each verified and then run in real time by the worker, hardware-like (a 2.x
script on the simulator's 2.x model: the hardware-like mode covers the guide's API only; jobs.run_mode).

Faults, logged: the worker killed outright (kill -9 of everything it started, its machine gone) while one of
its experiments runs, about every `worker_every` experiments, and a new worker started; PostgreSQL restarted
(every connection cut) while an experiment runs, once (or every `db_every`).

Each experiment's end is read from PostgreSQL (state, attempts, detail) and its run.json, and judged:
  completed   state completed, run once (attempts 1), its run.json says completed
  rejected    the verification's verdict (a listing that collides without a barrier): the service's answer
  by fault    the run its worker was killed under: failed, "the testbed was lost", with what was recorded
  lost        anything else (failed or cancelled for another cause, run twice, no results, still pending)
"""
import dataclasses
import json
import os
import random
import re
import time

from devtools import soak
from devtools.postgres import PostgreSQL, server_binaries
from devtools.service import Service, session_processes

TERMINAL = ("completed", "failed", "rejected", "cancelled")
ITERATIONS = 120        # real time: 4 s of testbed time
DEPTH = 3               # experiments submitted and not yet ended, at most
WAIT = 900.0            # s an experiment may take from its submission to its end


def scripts():
    """The single-file scripts of devtools.soak.catalog() (no image, no module of their own) with a robot count
    and an iteration count: a goal loop may never end hardware-like (pose noise keeps ten robots from all being
    within 5 cm of their goals at once: 3_5_1 ran its whole 900 s slot), and the service runs the guide's hardware-like."""
    found = []
    for script in soak.catalog():
        with open(os.path.join(soak.EXAMPLES, script.path)) as f:
            text = f.read()
        if script.robots and script.iterations and ".png" not in text and "import uni_ekf" not in text:
            found.append(script)
    return found


def shortened(script, seed):
    """The script's text as submitted: numpy seeded first, its long loop read shorter (run_seeded's --set)."""
    with open(os.path.join(soak.EXAMPLES, script.path)) as f:
        text = f.read()
    settings = [("iterations", str(ITERATIONS))] if script.iterations else [s.split("=", 1) for s in script.sets]
    for name, value in settings:
        text = re.sub(r"(?m)^%s[ \t]*=[^#\n]*" % re.escape(name), "%s = %s " % (name, value), text, count=1)
    return "import numpy as np\nnp.random.seed(%d)\n%s" % (seed, text)


@dataclasses.dataclass
class Submitted:
    n: int
    script: str
    pk: int = 0
    fault: str = ""            # "worker_kill", "db_restart" (the fault that came while it ran)
    submitted: float = 0.0
    state: str = ""
    attempts: int = 0
    detail: str = ""
    outcome: str = ""          # its run.json's
    verdict: str = ""
    why_lost: str = ""
    to_running: float | None = None   # s from its submission to its run's start (verification included)


class ServiceSoak:
    def __init__(self, work, seed=1, say=print, worker_every=50, db_every=None):
        self.work, self.seed, self.say = os.path.abspath(work), seed, say
        self.worker_every, self.db_every = worker_every, db_every
        self.service = Service(self.work)
        self.items = []
        self.worker_kills, self.db_restarts = [], []
        self.samples = []
        self.workers_started = 0

    def start(self):
        if server_binaries() is None:
            raise SystemExit("no PostgreSQL server here: apt-get install postgresql")
        self.service.postgres = PostgreSQL()
        self.service.start_portal()
        self._worker()
        return self

    def _worker(self):
        self.workers_started += 1
        self.service.start_worker("worker-%d" % self.workers_started)

    def sample(self, label):
        procs = {"portal": self.service.portal.process.pid}
        for name, worker in self.service.workers.items():
            procs[name] = worker.process.pid
        row = {}
        for name, pid in procs.items():
            tree = [soak.sizes(p) for p in session_processes(pid)]
            row[name] = (soak.sizes(pid), len([t for t in tree if t]), sum(t[0] for t in tree if t))
        self.samples.append((label, row))

    def soak(self, count, minutes=None):
        rng = random.Random(self.seed)
        pool = scripts()
        plan = [rng.choice(pool) for _ in range(count)]
        kills = {n for n in range(self.worker_every // 2, count + 1, self.worker_every)} if self.worker_every else set()
        # PostgreSQL restarted once, early (a soak cut short by `minutes` has it), or every db_every experiments
        first = min(max(2, count // 4), 10)
        restarts = set(range(first, count + 1, self.db_every)) if self.db_every else {first}
        restarts = {n + 1 if n in kills else n for n in restarts}
        started = time.monotonic()
        pending = []
        n = 0
        while True:
            more = n < count and not (minutes and time.monotonic() - started > 60.0 * minutes)
            if not more and not pending:
                break
            if more and len(pending) < DEPTH:
                n += 1
                item = Submitted(n, plan[n - 1].path, submitted=time.monotonic())
                (item.pk,) = self.service.submit([{"title": "soak %d %s" % (n, os.path.basename(item.script)),
                                                   "robots": plan[n - 1].robots,
                                                   "script": shortened(plan[n - 1], self.seed * 100003 + n)}])
                self.items.append(item)
                pending.append(item)
                if n == 1 or n % 50 == 0:
                    self.sample("experiment %d" % n)
            for item in list(pending):
                row = self.service.experiment(item.pk)
                if row["state"] == "running" and item.to_running is None:
                    item.to_running = round(time.monotonic() - item.submitted, 2)
                    if item.n in kills:
                        kills.discard(item.n)
                        self._kill_worker(item)
                    elif item.n in restarts:
                        restarts.discard(item.n)
                        self._restart_db(item)
                if row["state"] in TERMINAL:
                    pending.remove(item)
                    self._judge(item, row)
                    if item.n % 10 == 0:
                        self.say("  experiment %d: %s (%.0f s in)" % (item.n, item.verdict, time.monotonic() - started))
                elif time.monotonic() - item.submitted > WAIT:
                    pending.remove(item)
                    item.state, item.verdict, item.why_lost = row["state"], "lost", "not ended %.0f s after its " \
                        "submission (state %s)" % (WAIT, row["state"])
            time.sleep(0.3)
        if n < count:
            self.say("  %g minutes are up: %d of %d experiments submitted" % (minutes, n, count))
        self.sample("end (experiment %d)" % n)
        return self.items

    def _running_output(self, item):
        path = os.path.join(self.service.data, "experiments", str(item.pk), "run-1", "output.txt")
        deadline = time.monotonic() + 60
        while not os.path.exists(path) and time.monotonic() < deadline:
            time.sleep(0.1)
        return os.path.exists(path)

    def _kill_worker(self, item):
        if not self._running_output(item):
            return
        name = self.service.worker_of(item.pk)
        worker = self.service.workers.pop(name, None)
        if worker is None:
            return
        worker.kill()
        item.fault = "worker_kill"
        self.worker_kills.append(item.n)
        self.say("  experiment %d (%s): its worker %s killed outright mid-run; a new one started" % (
            item.n, item.script, name))
        self._worker()

    def _restart_db(self, item):
        if not self._running_output(item):
            return
        self.service.postgres.restart()
        item.fault = "db_restart"
        self.db_restarts.append(item.n)
        self.say("  experiment %d (%s): PostgreSQL restarted while it ran" % (item.n, item.script))

    def _judge(self, item, row):
        item.state, item.attempts, item.detail = row["state"], row["attempts"], row["detail"] or ""
        folder = os.path.join(self.service.data, "experiments", str(item.pk))
        records = []
        for d, _, names in os.walk(folder):
            if "run.json" in names:
                try:
                    with open(os.path.join(d, "run.json")) as f:
                        records.append(json.load(f))
                except (OSError, ValueError):
                    pass
        runs = sorted(n for n in os.listdir(folder) if n.startswith("run-")) if os.path.isdir(folder) else []
        item.outcome = ",".join(sorted({r.get("outcome", "") for r in records if not r.get("audit")}))
        if item.state == "completed" and item.attempts == 1 and runs == ["run-1"] and "completed" in item.outcome:
            item.verdict = "completed"
        elif item.state == "rejected" and item.fault != "worker_kill":
            item.verdict = "rejected"
        elif item.fault == "worker_kill" and item.state == "failed" and "the testbed was lost" in item.detail \
                and row["results"]:
            item.verdict = "by fault"
        else:
            item.verdict = "lost"
            item.why_lost = "state %s, attempts %s, runs %s, run.json outcome %r, fault %s" % (
                item.state, item.attempts, runs, item.outcome, item.fault or "none")
        if item.verdict == "lost" or item.fault:
            self.say("  experiment %d (%s): %s%s: %s" % (item.n, item.script, item.verdict,
                                                        " (%s)" % item.why_lost if item.why_lost else "",
                                                        item.detail[:200]))

    def close(self):
        self.service.close()


def summary(run):
    items = run.items
    lines = ["experiments: %d (%d guide listings, %d 2.x examples), each verified then run in real time, "
             "hardware-like (the 2.x ones on the 2.x model), by one worker"
             % (len(items), sum(i.script.startswith("guide") for i in items),
                sum(i.script.startswith("rps2") for i in items))]
    for verdict in ("completed", "rejected", "by fault", "lost"):
        chosen = [i for i in items if i.verdict == verdict]
        lines.append("  %-10s %d" % (verdict, len(chosen)))
        causes = {}
        for i in chosen if verdict != "completed" else ():
            words = " ".join(i.detail.split())[:160]   # one line: a detail may hold a traceback's
            cause = re.sub(r"\d+", "n", words) + ((" [%s]" % re.sub(r"\d+", "n", i.why_lost)) if i.why_lost else "")
            causes.setdefault(cause, []).append("%d %s" % (i.n, os.path.basename(i.script)))
        for cause, which in causes.items():
            lines.append("      %d x %s\n          (%s)" % (len(which), cause, ", ".join(which)))
    lines.append("faults: worker killed outright mid-run after experiment(s) %s; PostgreSQL restarted during "
                 "experiment(s) %s" % (run.worker_kills or "none", run.db_restarts or "none"))
    waits = [i.to_running for i in items if i.to_running is not None]
    if waits:
        lines.append("submission -> its run started (verification and the queue included): max %.1f s, p99 %.1f s, "
                     "median %.1f s" % (max(waits), soak.percentile(waits, 99), soak.percentile(waits, 50)))
    lines.append("processes (main process RSS MB / fds / threads; its session's processes and their RSS MB):")
    for label, row in run.samples:
        lines.append("  %-22s " % label + "  ".join(
            "%s %s, %d procs %.0f MB" % (name, "%.1f / %d / %d" % size if size else "-", count, total)
            for name, (size, count, total) in sorted(row.items())))
    return lines


def run_service_soak(work, count, seed, say=print, minutes=None, worker_every=50, db_every=None):
    run = ServiceSoak(work, seed=seed, say=say, worker_every=worker_every, db_every=db_every)
    try:
        run.start()
        run.soak(count, minutes=minutes)
        return run, summary(run)
    finally:
        run.close()
