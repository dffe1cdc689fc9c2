"""./robotarium worker, and serve's own: the job slots of one machine, their heartbeats, the watch for lost slots.

A supervisor starts one django-q2 cluster per slot (robotarium_portal.jobslot), each with a testbed of its
own (a ROS_DOMAIN_ID), and beats for each slot in the Worker table every settings.WORKER_HEARTBEAT s. It
also watches every other slot of the service: one whose beats stood still for settings.WORKER_LOST_AFTER s
of its own unbroken view of the database is lost; what it held is requeued (a verification) or failed
(a run: "the testbed was lost") through the experiment's transitions. Beats are counted, not timed: no two
clocks need to agree, and a database restart makes nobody look lost. Stopped properly, it stops its jobs
and hands them back; killed outright, its slots notice (robotarium_core.lifeline) and stop.
docs/portal.md says why django-q2 and why this watch is the service's own."""
import argparse
import faulthandler
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from robotarium_portal.database import database_retry

logger = logging.getLogger("robotarium_portal")
REPOSITORY = Path(__file__).resolve().parent.parent
STOP_GRACE = 60.0        # s a slot has to stop its job (a run ends its experiment and writes its results)


class Stop(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP arrived (stop_on_signals): unwind, hand the jobs back, exit. A KeyboardInterrupt:
    raised while serve's main thread handles a connection, waitress's loop lets only those (and SystemExit) through;
    an Exception there was taken for the connection's error and the service went on serving, deaf to Ctrl-C
    (a whole suite's browser test, 2026-12-01)."""


def stop_on_signals():
    """Turn the stop signals into Stop in the main thread (serve and worker alike)."""
    def stop(signum, frame):
        raise Stop()
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, stop)


def release(worker_pks, stopped_at_last_beat=False):
    """The slots stopped (properly, now; or, found dead at a start, at their last beat): their run goes back
    to the head of the queue (queued_at kept), their verification is made again; the slots are marked
    stopped."""
    from django.db import transaction
    from django.utils import timezone

    from robotarium_portal import jobs
    from robotarium_portal.models import Experiment, TaskHold, Worker
    for experiment in Experiment.objects.filter(worker__in=worker_pks, state__in=(Experiment.RUNNING,
                                                                                  Experiment.VERIFYING)):
        running = experiment.state == Experiment.RUNNING
        when = experiment.worker.last_heartbeat if stopped_at_last_beat else None
        with transaction.atomic():   # back in line and its job, or neither
            if experiment.requeue(experiment.worker_id, jobs.SERVICE_STOPPED, when):
                jobs.enqueue_run() if running else jobs.enqueue_verification(experiment)
    Worker.objects.filter(pk__in=worker_pks, state=Worker.ALIVE).update(
        state=Worker.STOPPED, ended_at=timezone.now(), current_job="")
    TaskHold.release_tasks(worker_pks)   # what their clusters took off the queue and never finished: back now


def recorded_so_far(experiment):
    """The folder of the run's results as far as they were written (relative to the experiment's folder):
    the run folder ./robotarium made, else the job's own (its output.txt)."""
    from robotarium_portal import jobs
    root = jobs.run_folder(experiment)
    made = sorted((p for p in (root / "results").glob("*") if p.is_dir()), key=lambda p: p.stat().st_mtime)
    if made:
        return str(made[-1].relative_to(experiment.folder))
    return str(root.relative_to(experiment.folder)) if root.is_dir() else ""


def lost(worker):
    """A slot found lost: its verification again, its run failed with what was recorded so far, and the jobs its
    cluster had taken off the queue (begun or not) back on it now, not after the cluster's `retry`."""
    from django.db import transaction

    from robotarium_portal import jobs, mail
    from robotarium_portal.models import Experiment, TaskHold
    when = worker.last_heartbeat.strftime("%Y-%m-%d %H:%M:%S UTC")
    for experiment in Experiment.objects.filter(worker=worker, state=Experiment.VERIFYING):
        with transaction.atomic():   # back in line and its job, or neither
            if experiment.requeue(worker.pk, "The worker verifying it (%s) was lost (last heard of %s)" % (worker, when)):
                jobs.enqueue_verification(experiment)
    for experiment in Experiment.objects.filter(worker=worker, state=Experiment.RUNNING):
        detail = ("Failed: the testbed was lost: worker %s stopped answering during run %d (last heard of %s). "
                  "What was recorded so far is attached; you may submit the experiment again."
                  % (worker, experiment.attempts, when))
        if experiment.fail(worker.pk, detail, results=recorded_so_far(experiment)):
            mail.try_sending(mail.send_issues_found, experiment)
    TaskHold.release_tasks([worker.pk])
    logger.warning("worker %s was lost; its jobs were handed out again or failed", worker)


def _beat_stuck():
    logger.warning("heartbeat: this beat has taken two heartbeats; where every thread is:")
    faulthandler.dump_traceback(all_threads=True)


class Watcher:
    """Finds lost slots: beats that stood still for WORKER_LOST_AFTER s while this watcher saw the database
    all that time (forget() after any database error starts the watch afresh)."""

    def __init__(self, own=()):
        self.own = set(own)
        self.seen = {}   # worker pk -> (beats, monotonic time they were first seen so)

    def forget(self):
        self.seen = {}

    def sweep(self):
        from django.conf import settings
        from django.utils import timezone

        from robotarium_portal.models import Worker
        now = time.monotonic()
        beats = dict(Worker.objects.filter(state=Worker.ALIVE).exclude(pk__in=self.own).values_list("pk", "beats"))
        self.seen = {pk: (b, self.seen[pk][1] if pk in self.seen and self.seen[pk][0] == b else now)
                     for pk, b in beats.items()}
        for pk, (b, since) in self.seen.items():
            if now - since >= settings.WORKER_LOST_AFTER and Worker.objects.filter(
                    pk=pk, state=Worker.ALIVE, beats=b).update(state=Worker.LOST, ended_at=timezone.now()):
                lost(Worker.objects.get(pk=pk))


def free_domain():
    from robotarium_bringup.domains import unique_domain_id  # a file lock held while this process lives
    return unique_domain_id()


class Supervisor:
    """The slots of one machine: a django-q2 cluster each (its own process group, its jobs' processes
    included), their beats, and the watch over every other worker of the service."""

    def __init__(self, data, kinds, jobs, env, domains=None, lock=None, fleet_file=None):
        from robotarium_portal.models import Worker
        self.data, self.env, self.lock = Path(data), env, lock
        self.fleet_file, self.fleet_testbed = fleet_file, None   # a worker of robots: one arena, one run at a time
        self.logs = self.data / "logs"
        self.logs.mkdir(exist_ok=True)
        self.host = socket.gethostname()
        self.slots = []   # (Worker, Popen or None)
        for kind in kinds:
            for index in range(1 if kind == "runs" and fleet_file else jobs):
                domain = (domains or {}).get(kind) if index == 0 else None
                worker = Worker.objects.create(host=self.host, pid=os.getpid(), kind=kind,
                                               domain=domain if domain is not None else free_domain())
                self.slots.append([worker, None])
        self.watcher = Watcher(own=[w.pk for w, _ in self.slots])
        self.stopping = threading.Event()
        self.starting = threading.Lock()   # a slot started afresh (_start_afresh) is started whole before stop() looks
        self.stopped_jobs = set()

    @property
    def pks(self):
        return [w.pk for w, _ in self.slots]

    def start(self):
        for slot in self.slots:
            worker = slot[0]
            if self.fleet_file and worker.kind == "runs":
                self.fleet_testbed = start_fleet_testbed(self.fleet_file, worker.domain, self.data / "fleet-runs",
                                                         self.logs / ("fleet-%s-%d" % (self.host, worker.pk)))
            self._start_slot(slot)
        threading.Thread(target=self._beat, daemon=True, name="heartbeat").start()

    def _start_slot(self, slot):
        """The slot's cluster (python -m robotarium_portal.jobslot KIND) as its Worker slot[0]."""
        from robotarium_core import lifeline
        from robotarium_portal import jobs
        worker = slot[0]
        log = open(self.logs / ("worker-%s-%s-%d.txt" % (self.host, worker.kind, worker.pk)), "ab")
        env = dict(self.env, ROBOTARIUM_WORKER_ID=str(worker.pk), Q_CLUSTER_NAME=worker.kind,
                   ROBOTARIUM_PORTAL_RUN_DOMAIN=str(worker.domain), ROBOTARIUM_PORTAL_VERIFY_DOMAIN=str(worker.domain))
        if self.fleet_file and worker.kind == "runs":
            env[jobs.FLEET_VARIABLE] = self.fleet_file
        env, pass_fds = lifeline.for_child(env)
        if self.lock is not None:
            pass_fds = pass_fds + (self.lock.fileno(),)
        slot[1] = subprocess.Popen([sys.executable, "-m", "robotarium_portal.jobslot", worker.kind], env=env,
                                   pass_fds=pass_fds, stdout=log, stderr=subprocess.STDOUT,
                                   stdin=subprocess.DEVNULL, process_group=0, cwd=REPOSITORY)
        log.close()

    def dead(self):
        return ["%s (%s)" % (w, w.kind) for w, p in self.slots if p is not None and p.poll() is not None]

    def _beat(self):
        from django.conf import settings
        from django.db import close_old_connections
        last = time.monotonic()
        while not self.stopping.wait(settings.WORKER_HEARTBEAT):
            # A beat that takes two heartbeats: every thread's stack on stderr (the worker's log), so that a beat
            # stuck somewhere (a slot found lost without a database error, 2026-11-30) says where.
            stuck = threading.Timer(2 * settings.WORKER_HEARTBEAT, _beat_stuck)
            stuck.daemon = True
            stuck.start()
            close_old_connections()
            began = time.monotonic()
            try:
                self.beat()
                self.watcher.sweep()
            except Exception as error:   # noqa: BLE001 - the database away (a restart): beat again next time
                self.watcher.forget()
                logger.warning("heartbeat: %s: %s (%.1f s since the last beat)", type(error).__name__, error,
                               time.monotonic() - last)
                continue
            finally:
                stuck.cancel()
            now = time.monotonic()
            if now - last > 2 * settings.WORKER_HEARTBEAT:   # a gap its watchers may take for a lost slot: why?
                logger.warning("heartbeat: %.1f s since the last beat (this one took %.1f s)", now - last, now - began)
            last = now

    def beat(self):
        from django.db.models import F
        from django.utils import timezone

        from robotarium_portal.models import Experiment, Worker
        for slot in self.slots:
            worker, process = slot
            if process is None or process.poll() is not None:
                continue   # a slot that died (or is being started afresh) beats no more: its watchers find it lost
            if not Worker.objects.filter(pk=worker.pk, state=Worker.ALIVE).update(
                    last_heartbeat=timezone.now(), beats=F("beats") + 1):
                # Found lost while it could not beat (cut off from the database): its job was handed out or
                # failed meanwhile, so it must not go on; the slot works on as a new one.
                slot[1] = None
                threading.Thread(target=self._start_afresh, args=(slot, process), daemon=True,
                                 name="slot %d afresh" % worker.pk).start()
                continue
            for pk in Experiment.objects.filter(worker=worker, state=Experiment.CANCELLED).values_list("pk", flat=True):
                self._stop_job(worker.pk, "experiment %d cancelled" % pk)

    def _start_afresh(self, slot, process):
        """A slot found lost: its job and cluster stopped (the cluster kept taking jobs under the lost slot's name,
        and each was stopped again: six verifications failed so after a database restart, 2026-11-30), then the
        slot starts again as a new Worker, so that this machine goes on working for the service."""
        from robotarium_portal import jobs
        from robotarium_portal.models import Worker
        old = slot[0]
        self._stop_job(old.pk, "found lost")
        try:
            os.killpg(process.pid, signal.SIGTERM)   # the cluster lets its worker end, then exits
            process.wait(timeout=STOP_GRACE)
        except subprocess.TimeoutExpired:
            pass
        except ProcessLookupError:
            pass
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        process.wait()
        shutil.rmtree(jobs.jobs_dir(old.pk), ignore_errors=True)   # (its jobs' process groups: all stopped)
        with self.starting:
            if self.stopping.is_set():
                return
            new = database_retry(lambda: Worker.objects.create(host=self.host, pid=os.getpid(), kind=old.kind,
                                                               domain=old.domain), "making the slot afresh")
            self.watcher.own.add(new.pk)
            slot[0] = new
            self._start_slot(slot)
        logger.warning("slot %s was found lost while it could not reach the database; it works on as slot %d",
                       old, new.pk)

    def _stop_job(self, worker_pk, why):
        from robotarium_portal import jobs
        for pgid_file in jobs.jobs_dir(worker_pk).glob("*.pgid"):
            key = (pgid_file, pgid_file.stat().st_mtime if pgid_file.exists() else 0)
            if key in self.stopped_jobs:
                continue
            self.stopped_jobs.add(key)
            try:
                pgid = int(pgid_file.read_text())
            except (OSError, ValueError):
                continue
            logger.warning("stopping the job of worker %d: %s", worker_pk, why)
            threading.Thread(target=jobs.stop_group, args=(pgid,), daemon=True).start()

    def stop(self, hand_back=True):
        """Stop the jobs first (each ./robotarium ends its experiment and writes its results), then the
        clusters (SIGTERM: each lets its worker finish and exits; SIGKILL after STOP_GRACE), and hand the
        jobs back."""
        from robotarium_portal import jobs
        self.stopping.set()
        with self.starting:
            pass   # a slot being started afresh is started (or will not be) before the slots are stopped
        for pk in self.pks:
            jobs.stop_jobs(pk)
        for _, process in self.slots:
            if process is not None and process.poll() is None:
                process.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + STOP_GRACE
        for _, process in self.slots:
            if process is None:
                continue
            try:
                process.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
            try:
                os.killpg(process.pid, signal.SIGKILL)   # the cluster's own processes, whatever is left
            except ProcessLookupError:
                pass
            process.wait()
        if self.fleet_testbed is not None:
            self.fleet_testbed.stop()   # every robot gets zeros
            self.fleet_testbed = None
        if hand_back:
            database_retry(lambda: release(self.pks), "handing the jobs back")
        for pk in self.pks:
            shutil.rmtree(jobs.jobs_dir(pk), ignore_errors=True)


def start_fleet_testbed(fleet_file, domain, bags, log_dir):
    """The testbed of a worker of robots (./robotarium worker --fleet): the hardware arena of the fleet, the
    safety node and the recorder (its runs into `bags`; each run's folder then moves into its experiment's
    results), on the run slot's ROS_DOMAIN_ID, kept up while the worker runs."""
    from robotarium_bringup.testbed import LocalTestbed
    saved = os.environ.get("ROS_DOMAIN_ID")
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    try:
        return LocalTestbed(log_dir=str(log_dir), bags_dir=str(bags), fleet_file=fleet_file, looked=True).start()
    finally:
        if saved is None:
            os.environ.pop("ROS_DOMAIN_ID", None)
        else:
            os.environ["ROS_DOMAIN_ID"] = saved


def forget_dead_local_workers():
    """At serve's start: the slots of this machine whose supervisor is gone (a serve killed outright) hand
    their jobs back at once; other machines' slots are their watchers' business."""
    from robotarium_portal.models import Worker
    gone = [w.pk for w in Worker.objects.filter(state=Worker.ALIVE, host=socket.gethostname())
            if not _running(w.pid)]
    if gone:
        release(gone, stopped_at_last_beat=True)


def _running(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def database_url(value):
    """--database's value: a PostgreSQL URL without a password (a command line is every process's to read)."""
    from urllib.parse import urlsplit
    if urlsplit(value).password is not None:
        raise argparse.ArgumentTypeError(
            "no password on the command line, where any process on this machine may read it: give it in "
            "PGPASSWORD, or in a password file (PGPASSFILE, default ~/.pgpass: HOST:PORT:NAME:USER:PASSWORD, "
            "mode 0600), and --database postgresql://USER@HOST[:PORT]/NAME")
    return value


def parse(argv):
    parser = argparse.ArgumentParser(
        prog="./robotarium worker",
        description="A worker of your own Robotarium on this machine: it verifies submissions and runs "
                    "experiments from the service's queue, on testbeds of its own. Any number of workers, on any "
                    "machines that reach the service's database and its data folder (a shared path: NFS, SMB...).",
        epilog="Example, the portal on host A and a worker on host B, the data folder shared at /srv/robotarium: "
               "A: ./robotarium serve --database postgresql://robotarium@A/robotarium --data /srv/robotarium "
               "--host 0.0.0.0;  B: ./robotarium worker --database postgresql://robotarium@A/robotarium "
               "--data /srv/robotarium. Ctrl-C stops it: its running experiment goes back to the head of the "
               "queue. Killed outright (or its machine gone), the service notices within 5 heartbeats (10 s) and "
               "verifies its submission again or fails its run (\"the testbed was lost\").")
    parser.add_argument("--database", default="", type=database_url,
                        help="the service's database, postgresql://USER@HOST[:PORT]/NAME, its password from "
                             "PGPASSWORD or a password file (PGPASSFILE, ~/.pgpass) (default: the "
                             "SQLite database in the data folder, for workers beside serve on its machine)")
    parser.add_argument("--data", default=str(REPOSITORY / "service"),
                        help="the service's data folder, shared with the portal (default: service/ in the repository)")
    only = parser.add_mutually_exclusive_group()
    only.add_argument("--verify-only", action="store_true", help="only verify submissions")
    only.add_argument("--run-only", action="store_true", help="only run experiments")
    parser.add_argument("--fleet", metavar="FILE",
                        help="run experiments on your own robots: this worker's one run slot moves the robots of the "
                             "fleet file (the hardware arena, the safety node and a recorder, kept up while it runs; "
                             "one run at a time); its verifications stay in simulation (docs/own-robots.md)")
    parser.add_argument("--jobs", type=int, default=1,
                        help="how many verifications and how many runs at once (default 1 of each), each on a "
                             "testbed (ROS_DOMAIN_ID) of its own")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error("--jobs must be 1 or more")
    if args.fleet and args.verify_only:
        parser.error("--fleet runs experiments on robots: not with --verify-only")
    if args.fleet:
        from robotarium_hardware import fleet as fleets
        try:
            fleets.load(args.fleet)
        except fleets.FleetError as error:
            parser.error(str(error))
        args.fleet = str(Path(args.fleet).resolve())
    return args


def kinds_of(args):
    if args.verify_only:
        return ["verify"]
    if args.run_only:
        return ["runs"]
    return ["verify", "runs"]


def setup_django(data, database):
    """Django on the service's data folder (made with its secret key when missing) and its database."""
    from robotarium_portal.data_folder import prepare
    os.environ["ROBOTARIUM_PORTAL_DATA"] = str(prepare(data))
    if database:
        os.environ["ROBOTARIUM_PORTAL_DATABASE"] = database
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "robotarium_portal.settings")
    import django
    try:
        django.setup()
    except ValueError as error:
        sys.exit("[robotarium] error: %s" % error)


def check_database(what):
    """The database answers and has the service's tables, else a clear error."""
    from django.db import DatabaseError, connection
    from django.db.migrations.executor import MigrationExecutor
    try:
        pending = MigrationExecutor(connection).migration_plan(MigrationExecutor(connection).loader.graph.leaf_nodes())
    except DatabaseError as error:
        sys.exit("[robotarium] error: cannot reach the database %s (%s); check --database, and that the machine "
                 "reaches it" % (what, str(error).strip()))
    if pending:
        sys.exit("[robotarium] error: the database %s has not the service's tables yet: start ./robotarium serve "
                 "with it first (it makes them)" % what)


def main(argv=None):
    args = parse(argv)
    data = Path(args.data).resolve()
    if not data.is_dir():
        sys.exit("[robotarium] error: no data folder %s: give the service's data folder (shared with the portal) "
                 "with --data" % data)
    setup_django(data, args.database)
    from django.conf import settings
    shown = args.database.split("@")[-1] if args.database else str(settings.DATABASES["default"]["NAME"])
    check_database(shown)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPOSITORY), os.environ.get("PYTHONPATH", "")]))
    supervisor = Supervisor(data, kinds_of(args), args.jobs, env, fleet_file=args.fleet)
    supervisor.start()
    print("[robotarium] worker on %s: %s; database %s, data %s; heartbeat every %g s, found lost by the others "
          "after %g s without one; Ctrl-C stops it (its jobs are handed back)" % (
              supervisor.host, ", ".join("%s on ROS_DOMAIN_ID %d" % (w.kind, w.domain) for w, _ in supervisor.slots),
              shown, data, settings.WORKER_HEARTBEAT, settings.WORKER_LOST_AFTER), flush=True)

    stop_on_signals()
    code = 0
    try:
        while True:
            time.sleep(1.0)
            if supervisor.dead():
                print("[robotarium] error: the cluster of %s stopped (its log is in %s); stopping this worker"
                      % (", ".join(supervisor.dead()), supervisor.logs), flush=True)
                code = 1
                break
    except Stop:
        pass
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, signal.SIG_IGN)
        print("[robotarium] stopping this worker (its running experiment goes back to the head of the queue)",
              flush=True)
        supervisor.stop()
        print("[robotarium] stopped", flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
