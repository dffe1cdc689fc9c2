"""The jobs the workers run (django-q2 tasks): verify a submission, run the oldest queued experiment.

Each job changes its experiment only through the model's transitions (Experiment.claim_verification,
claim_next_run, queue, reject, fail, complete): conditional UPDATEs, so a job handed out twice, or two
workers, never verify or run one experiment twice, and an outcome is written only while its worker still
holds the experiment. The experiment table is the truth; the broker's queue only says that there is work
(reconcile() rebuilds it from the table). Each job's command runs in a box of its own (jobbox)."""
import dataclasses
import functools
import json
import logging
import os
import re
import shutil
import sys
import time
from pathlib import Path

from django.conf import settings
from django.db import transaction
from django.db.models import F, Q
from django_q.models import OrmQ
from django_q.tasks import async_task

from robotarium_core import run_record
from robotarium_core.config import TestbedConfig
from robotarium_core.rps2 import API as V2_API
from robotarium_portal import jobbox, mail
from robotarium_portal.database import database_retry
from robotarium_portal.files import copy_files
from robotarium_portal.jobbox import stop_group
from robotarium_portal.models import Experiment, Worker

logger = logging.getLogger("robotarium_portal")
VERIFY_CLUSTER, RUN_CLUSTER = "verify", "runs"
# ./robotarium verify's exit codes (its fixed interface)
VERIFY_ACCEPTED, VERIFY_TESTBED, VERIFY_REJECTED = 0, 4, 6
SERVICE_STOPPED = "The service stopped"   # the cause a requeue names when a worker was stopped properly
TIME_RULE = "time"   # the portal's own rule beside the verifier's: its wall-time limit (verification_limit)
BUSY_OWNER_PAUSE = 1.0   # s before a verification waiting for its owner's other one goes back in the queue
RESULTS_GRACE = 600       # s after the time limit for the start, the end and the results' video
STEP_LINE = re.compile(rb"\[robotarium\] step (\d+)")
# What a user's script must not see of the service (the environment is passed on to its run).
SECRET_VARIABLES = ("ROBOTARIUM_SMTP_PASSWORD", "ROBOTARIUM_SMTP_USER", "DJANGO_SETTINGS_MODULE",
                    "ROBOTARIUM_PORTAL_DATABASE")   # its URL may carry the database password


@functools.cache
def time_limit():
    """The testbed configuration's time limit (900 s: the Robotarium's 15-minute slot); read once."""
    return TestbedConfig.load().time_limit


def enqueue_verification(experiment):
    async_task("robotarium_portal.jobs.verify_experiment", experiment.pk, cluster=VERIFY_CLUSTER,
               task_name="verify #%d" % experiment.pk)


def me():
    """The Worker (slot) this process works for, or None outside a worker."""
    value = os.environ.get("ROBOTARIUM_WORKER_ID")
    return int(value) if value else None


def slot_lost():
    """This slot was found lost (cut off from the database for WORKER_LOST_AFTER): it takes no job, and its
    supervisor starts it afresh as a new slot at its next beat (robotarium_portal.supervisor)."""
    worker = me()
    return worker is not None and Worker.found_lost(worker).exists()


def enqueue_run():
    async_task("robotarium_portal.jobs.run_next", cluster=RUN_CLUSTER, task_name="run the next experiment")


def reconcile():
    """At the service's start, before its own workers: every job from the experiments' states. A run that a
    stop cut short goes back to the head of the queue (its queued_at is kept) and runs again. What a live
    worker (on another machine) holds stays its own."""
    OrmQ.objects.filter(key__in=[VERIFY_CLUSTER, RUN_CLUSTER]).delete()
    unheld = Q(worker__isnull=True) | ~Q(worker__state=Worker.ALIVE)
    for experiment in Experiment.objects.filter(unheld, state__in=(Experiment.RUNNING, Experiment.VERIFYING)):
        experiment.requeue(experiment.worker_id, SERVICE_STOPPED,
                           experiment.worker.last_heartbeat if experiment.worker else None)   # when it stopped
    for experiment in Experiment.objects.filter(state=Experiment.SUBMITTED).order_by("submitted_at", "pk"):
        enqueue_verification(experiment)
    for _ in range(Experiment.objects.filter(state=Experiment.QUEUED).count()):
        enqueue_run()


def job_env(domain_variable):
    """The environment of a job's ./robotarium: its own DDS domain, localhost discovery, no service secrets."""
    env = {k: v for k, v in os.environ.items() if k not in SECRET_VARIABLES}
    env["ROS_DOMAIN_ID"] = os.environ.get(domain_variable) or os.environ.get("ROS_DOMAIN_ID", "0")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["MPLBACKEND"] = "Agg"
    env["ROBOTARIUM_PROGRESS"] = "2"   # a progress line every 2 s: the page shows the step
    return env


def jobs_dir(worker=None):
    """The running jobs' process groups of one worker slot (this process's unless named)."""
    path = settings.DATA_DIR / "jobs" / str(worker or me() or "local")
    path.mkdir(parents=True, exist_ok=True)
    return path


def stopping():
    """The service is stopping (serve wrote the mark before it stopped the jobs): a job cut short now is
    not the experiment's failure; reconcile() at the next start hands it out again."""
    return (jobs_dir() / "stopping").exists()


def run_command(command, cwd, env, output_path, timeout, job, own_network=True, network=None):
    """Run command in the job's own box (jobbox: its namespaces, folder, account and limits; cwd's files are
    copied into the box's folder, where it runs), its output in a file. The box's process group is in
    jobs/<job>.pgid while it runs (serve stops it there). The exit code, or None when it ran past timeout
    (then the whole group is killed); what the box stopped or refused ends the output ('[job box]' lines)."""
    pgid_file = jobs_dir() / ("%s.pgid" % job)
    # a box per worker slot: the slots on one machine differ in their ROS_DOMAIN_ID (a bounded set of accounts)
    box = jobbox.JobBox(settings.JOB_BOXES_DIR, "%s-%s" % (job, env.get("ROS_DOMAIN_ID", "0")),
                        jobbox.Limits(**settings.JOB_LIMITS), keep=[settings.DATA_DIR], own_network=own_network,
                        network=network)
    try:
        box.prepare(cwd)
        return box.run(command, env, output_path, timeout, started=lambda pid: pgid_file.write_text(str(pid))).code
    finally:
        pgid_file.unlink(missing_ok=True)
        box.clean()


# The network namespace of this slot's warm testbed (start_warm_testbed; its jobs read it).
WARM_NETWORK_VARIABLE = "ROBOTARIUM_PORTAL_WARM_NETWORK"
WARM_START = 60   # s the slot waits for its warm testbed before it takes work without it
WARM_JOB = "job.json"   # in warm_bags(): the experiment and attempt whose run the warm testbed records now


def warm_bags():
    """Where a run slot's warm testbed records: in the data folder, which no job's script may read; one folder per
    slot of this machine (by its run domain, which a slot started afresh keeps). Each run's folder moves into its
    experiment's results when its job ends (bring_results), so the next job finds none of it."""
    return settings.DATA_DIR / "warm-runs" / job_env("ROBOTARIUM_PORTAL_RUN_DOMAIN")["ROS_DOMAIN_ID"]


def _warm_env(kind):
    """A warm testbed's environment: a job's named variables only (as JobBox.environment gives a job, with its
    transports and discovery), nothing of the slot's own, such as its lifeline, whose descriptor the testbed
    would not have (it then ends)."""
    domain = "ROBOTARIUM_PORTAL_VERIFY_DOMAIN" if kind == VERIFY_CLUSTER else "ROBOTARIUM_PORTAL_RUN_DOMAIN"
    env = dict(jobbox.scrubbed(job_env(domain)), FASTDDS_BUILTIN_TRANSPORTS="UDPv4",
               ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET")
    env.pop("ROBOTARIUM_PROGRESS", None)
    return env


def start_warm_testbed(kind):
    """The slot's warm testbed, for the slot's life, on the slot's ROS_DOMAIN_ID in a network namespace of its own
    (jobbox.start_in_network), which each of the slot's boxes joins: a verification slot's ./robotarium up
    --verification --no-record; a run slot's ./robotarium up recording into warm_bags() (not a worker of robots:
    its fleet's testbed is its supervisor's). The script still runs in its box: its own PID and mount namespaces,
    folder, account and limits; what it shares with the next job is the testbed's nodes (the service's
    processes), never a recording (docs/portal.md says how that is tested). Returns the testbed's Popen (None:
    none, as the settings, or a service that is not root, say). Called by the slot's process (jobslot) before
    its workers start."""
    verify = kind == VERIFY_CLUSTER
    wanted = settings.WARM_VERIFICATION if verify else settings.WARM_RUNS and not os.environ.get(FLEET_VARIABLE)
    if not (wanted and jobbox.isolated()):
        return None
    env = _warm_env(kind)
    if verify:
        arguments = ["--verification", "--no-record"]
    else:
        rescue_warm_recordings()   # what a slot before this one left (killed outright mid-run)
        warm_bags().mkdir(parents=True, exist_ok=True)
        arguments = ["--bags-dir", str(warm_bags())]
    logs = settings.DATA_DIR / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    with open(logs / ("warm-%s-%s.txt" % ("verification" if verify else "runs", me() or "local")), "ab") as log:
        process, network = jobbox.start_in_network(
            [str(settings.REPOSITORY / "robotarium"), "up", *arguments], env, log)
    if network is None:
        stop_group(process.pid, grace=5)
        return None
    os.environ[WARM_NETWORK_VARIABLE] = network
    # Ready before the slot takes its first job (which would otherwise start a testbed of its own).
    deadline = time.monotonic() + WARM_START
    while warm_testbed(kind, env)[0] is None and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    return process


def warm_testbed(kind, env):
    """(the registry entry of this slot's warm testbed where it runs, free of settings a job with `env` would not
    take, in the slot's network namespace; that namespace's path), or (None, None): the job then starts a testbed
    of its own in its box."""
    network = os.environ.get(WARM_NETWORK_VARIABLE)
    if not network:
        return None, None
    from robotarium_bringup import local_testbeds
    from robotarium_cli.running import VERIFY_NAMESPACE, warm_verification_testbed
    from robotarium_core.topics import DEFAULT_NAMESPACE
    try:
        netns = os.readlink(network)
    except OSError:
        return None, None
    verify = kind == VERIFY_CLUSTER
    root = env.get("ROBOTARIUM_ROOT") or str(settings.REPOSITORY)
    for _, entry in local_testbeds.registered():
        try:
            if os.readlink("/proc/%d/ns/net" % entry["owner"]["pid"]) != netns:
                continue
        except (OSError, KeyError, TypeError):
            continue
        found = warm_verification_testbed(
            [entry], env["ROS_DOMAIN_ID"], "SUBNET", root, "", not verify, "" if verify else str(warm_bags()),
            local_testbeds.running, namespace=VERIFY_NAMESPACE if verify else "/" + DEFAULT_NAMESPACE)
        if found is not None:
            return found, network
    return None, None


def rescue_warm_recordings(experiment=None):
    """Before a run on the slot's warm testbed: what an earlier job of the slot left in warm_bags() (a job killed
    outright, with its worker, before it moved its run's folder out) goes to that job's results, where a job of
    the box's own testbed would have left it; then the folder names `experiment`'s run as the one it now records.
    Nothing of one job stays for the next."""
    folder = warm_bags()
    try:
        earlier = json.loads((folder / WARM_JOB).read_text())
        results = run_folder(Experiment.objects.get(pk=earlier["experiment"]), earlier["attempt"]) / "results"
    except (OSError, ValueError, KeyError, TypeError, Experiment.DoesNotExist):
        results = None
    for path in (folder.iterdir() if folder.is_dir() else ()):
        if path.name == WARM_JOB:
            continue
        if results is not None and results.is_dir() and path.is_dir() and not (results / path.name).exists():
            shutil.move(str(path), str(results / path.name))
            logger.warning("moved %s, left by a job cut short, to its experiment's results %s", path, results)
        else:
            shutil.rmtree(path, ignore_errors=True) if path.is_dir() else path.unlink(missing_ok=True)
    if experiment is not None:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / WARM_JOB).write_text(json.dumps({"experiment": experiment.pk, "attempt": experiment.attempts}))


def box_notes(output_path):
    """What the job's box stopped or refused, for the experiment's page ('' when nothing)."""
    notes = jobbox.notes_in(output_path)
    return "".join("\nThe job's box: %s." % note for note in notes)


def stop_jobs(worker=None):
    """The worker stops: mark it (a job cut short now is not its experiment's failure) and stop every
    running job's ./robotarium."""
    (jobs_dir(worker) / "stopping").touch()
    for pgid_file in jobs_dir(worker).glob("*.pgid"):
        try:
            stop_group(int(pgid_file.read_text()))
        except (ValueError, OSError):
            pass


def _tail(path, lines=15):
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return "".join(f.readlines()[-lines:]).strip()
    except OSError:
        return ""


def rejection_text(verdict):
    """The rules the verifier found broken, one per line: the rule, its count against its limit and the first
    step where it has them, then what it says ("collisions: 168 times, limit 100 (first at step 37). ...")."""
    lines = []
    for rule in verdict.get("rules") or []:
        line = "%s:" % rule.get("rule")
        if rule.get("limit") is not None:
            line += " %s times, limit %s" % (rule.get("count"), rule.get("limit"))
        if rule.get("first_step") is not None:
            line += " (first at step %s)" % rule["first_step"]
        message = " ".join((rule.get("message") or "").split())
        if message:
            line += (". " if line.endswith(")") or rule.get("limit") is not None else " ") + message
        lines.append(line)
    return "\n".join(lines) or (verdict.get("report") or "rejected")


def failing_truthfully(job):
    """A job that breaks (a full disk, a bug) leaves its experiment failed with the error, not verifying or
    running forever; the error goes on to django-q2's failed tasks too."""
    def guarded(experiment):
        try:
            return job(experiment)
        except Exception as error:
            _finish(experiment, Experiment.FAILED, "Failed: the service's %s job broke (%s: %s); an administrator "
                    "has its trace in the admin pages (failed tasks)." % (job.__name__, type(error).__name__, error))
            raise
    return guarded


def verify_experiment(pk):
    """./robotarium verify on a copy of the experiment's files: accepted -> queued, else rejected or failed."""
    # Every database step here waits out a restart: a job that broke on one left its experiment submitted
    # with no job to verify it, for ever (a whole-suite run's PostgreSQL restart).
    experiment = database_retry(lambda: Experiment.objects.filter(pk=pk).first(), "reading experiment %d" % pk)
    if experiment is None or not database_retry(lambda: experiment.claim_verification(me()), "claiming a verification"):
        if experiment is not None and database_retry(
                lambda: Experiment.objects.filter(pk=pk, state=Experiment.SUBMITTED).exists(), "reading experiment %d" % pk):
            # Its owner's other submission is being verified in another slot (one slot a person at a time, so
            # the others' submissions go first), or this slot was found lost: it goes back in the queue.
            lost = database_retry(slot_lost, "reading this slot's state")
            time.sleep(BUSY_OWNER_PAUSE)
            database_retry(lambda: enqueue_verification(experiment), "putting experiment %d back in the queue" % pk)
            if lost:
                return "this slot was found lost: experiment %d goes back in the queue for another" % pk
            return "experiment %d waits for its owner's other verification" % pk
        return "experiment %d is not waiting for verification" % pk
    return _working_on("verify #%d" % pk, lambda: _verify(experiment))


def verification_limit(experiment):
    """(s a verification may take, the sentence that says why): the verifier's 1.5 x the declared duration,
    plus the start-up allowance."""
    limit = 1.5 * experiment.estimated_duration + settings.VERIFY_STARTUP
    return limit, ("%d s: 1.5 x its declared duration of %d s, plus %d s to start"
                   % (limit, experiment.estimated_duration, settings.VERIFY_STARTUP))


def _working_on(job, work):
    """The worker's current job while work() runs, and one more job done after it."""
    worker = me()
    if worker is not None:
        database_retry(lambda: Worker.objects.filter(pk=worker).update(current_job=job), "noting the job")
    try:
        return work()
    finally:
        if worker is not None:
            database_retry(lambda: Worker.objects.filter(pk=worker).update(current_job="", jobs_done=F("jobs_done") + 1),
                           "counting the job")


@failing_truthfully
def _verify(experiment):
    pk = experiment.pk
    work = experiment.folder / "verify"
    shutil.rmtree(work, ignore_errors=True)
    copy_files(experiment.files_dir, work)
    verdict_path = experiment.folder / "verification.json"
    verdict_path.unlink(missing_ok=True)
    output = experiment.folder / "verification-output.txt"
    # Not recorded (the verdict and its report are what the experiment keeps); its run folder beside the verdict.
    command = [str(settings.REPOSITORY / "robotarium"), "verify", experiment.main_file,
               "--robots", str(experiment.number_of_robots), "--duration", str(experiment.estimated_duration),
               "--json", str(verdict_path), "--no-record", "--results-dir", str(experiment.folder / "verification")]
    began = time.monotonic()
    limit, rule = verification_limit(experiment)
    env = job_env("ROBOTARIUM_PORTAL_VERIFY_DOMAIN")
    warm, network = warm_testbed(VERIFY_CLUSTER, env)
    if warm is not None:   # verify finds it there (robotarium_cli.running.WARM_VARIABLE), or says why not
        from robotarium_cli.running import WARM_VARIABLE
        env[WARM_VARIABLE] = json.dumps(warm)
    code = run_command(command, work, env, output, limit, VERIFY_CLUSTER, network=network)
    experiment.timings = {"verify_command": round(time.monotonic() - began, 3)}
    shutil.rmtree(work, ignore_errors=True)
    if stopping():
        return "the service stopped during the verification of experiment %d" % pk
    try:
        verdict = json.loads(verdict_path.read_text())
    except (OSError, ValueError):
        verdict = None
    if code == VERIFY_ACCEPTED and verdict and verdict.get("verdict") == "accepted":
        return _queue(experiment, verdict)
    if code == VERIFY_REJECTED and verdict:
        return _finish(experiment, Experiment.REJECTED, "Rejected by the verification:\n" + rejection_text(verdict)
                       + box_notes(output), verification=verdict, timings=experiment.timings)
    if code is None:   # it ran past its limit: rejected, the rule named
        verdict = {"verdict": "rejected", "rules": [{
            "rule": TIME_RULE, "count": None, "limit": None, "first_step": None,
            "message": "the verification did not end within its limit of %s; a script that spins or never ends "
                       "is rejected (declare a longer duration if it needs one)" % rule}]}
        return _finish(experiment, Experiment.REJECTED, "Rejected by the verification:\n" + rejection_text(verdict),
                       verification=verdict, timings=experiment.timings)
    if code == VERIFY_TESTBED:
        why = "the verification's testbed had a problem (exit code 4)"
    else:
        why = "the verification could not run (exit code %s)" % code
    return _finish(experiment, Experiment.FAILED, "Failed: %s; a person may submit it again.%s\n%s"
                   % (why, box_notes(output), _tail(output)), verification=verdict, timings=experiment.timings)


def _queue(experiment, verdict):
    def queue():
        with transaction.atomic():
            if not experiment.queue(me(), verdict, experiment.timings):
                return False
            enqueue_run()   # in the same transaction: queued and its job, or neither
            return True
    if not database_retry(queue, "queueing experiment %d" % experiment.pk):
        return "experiment %d was decided elsewhere meanwhile (cancelled, or its worker found lost)" % experiment.pk
    return "experiment %d queued" % experiment.pk


TRANSITIONS = {Experiment.REJECTED: Experiment.reject, Experiment.FAILED: Experiment.fail,
               Experiment.COMPLETED: Experiment.complete}


def _finish(experiment, state, detail, **fields):
    """The job's outcome (rejected, failed, completed) and its mail, unless the experiment was decided elsewhere
    meanwhile (an administrator cancelled it, or this worker was found lost): that stays, and a cancelled run
    keeps what it recorded."""
    def write():
        if TRANSITIONS[state](experiment, me(), detail, **fields):
            return True
        if fields.get("results"):
            experiment.keep_results(**{k: v for k, v in fields.items() if k in ("results", "run_outcome", "timings")})
        return False
    if not database_retry(write, "writing the outcome of experiment %d" % experiment.pk):
        return "experiment %d was decided elsewhere meanwhile (cancelled, or its worker found lost)" % experiment.pk
    if state == Experiment.COMPLETED:
        mail.try_sending(mail.send_completed, experiment)
    else:
        mail.try_sending(mail.send_issues_found, experiment)
    return "experiment %d %s" % (experiment.pk, state)


def run_next():
    """Claim the oldest queued experiment (first come, first served) and run it."""
    experiment = database_retry(lambda: Experiment.claim_next_run(me()), "claiming a run")
    if experiment is None:
        if database_retry(slot_lost, "reading this slot's state"):
            time.sleep(BUSY_OWNER_PAUSE)
            database_retry(enqueue_run, "putting the run back in the queue")
            return "this slot was found lost: the run goes back in the queue for another"
        return "the queue is empty"
    return _working_on("run #%d" % experiment.pk, lambda: run_experiment(experiment))


def run_folder(experiment, attempt=None):
    return experiment.folder / ("run-%d" % (attempt or experiment.attempts))


def live_file(experiment):
    """The running experiment's poses and drawing as they come (live_feed.py writes it, the page streams it)."""
    return run_folder(experiment) / "live.jsonl"


def current_step(experiment):
    """The last step the running experiment's progress lines named, or None."""
    try:
        with open(run_folder(experiment) / "output.txt", "rb") as f:
            f.seek(0, os.SEEK_END)
            f.seek(max(0, f.tell() - 8192))
            steps = STEP_LINE.findall(f.read())
    except OSError:
        return None
    return int(steps[-1]) if steps else None


# Set (to its fleet file) for the run slot of a worker that moves real robots (./robotarium worker --fleet).
FLEET_VARIABLE = "ROBOTARIUM_PORTAL_FLEET"


def bring_results(output_path, results):
    """A run on the robots, or on the slot's warm testbed, is recorded by that testbed in its bags folder; the run
    folder that ./robotarium run named ("results in FOLDER") moves into the experiment's results/."""
    try:
        lines = Path(output_path).read_text(errors="replace").splitlines()
    except OSError:
        return
    named = [line.split("results in ", 1)[1].split(" (open ")[0].strip() for line in lines if "] results in " in line]
    if named and Path(named[-1]).is_dir() and not Path(named[-1]).resolve().is_relative_to(Path(results).resolve()):
        shutil.move(named[-1], Path(results) / Path(named[-1]).name)


@dataclasses.dataclass(frozen=True)
class RunMode:
    """How the service runs an experiment on its simulator, and what the experiment's page then says of it."""
    hardware_like: bool   # ./robotarium run --hardware: latency, pose noise, wheel dynamics
    note: str = ""        # said on the page (and in the mail) below the run's outcome; "" when nothing


V2_NOTE = ("It ran in real time on the simulator's 2.x model, not hardware-like: the hardware-like mode covers the "
           "guide's API only, not the 2.x sensors and drive-on phase.")


def run_mode(experiment, fleet=None):
    """The one place that decides how an experiment runs: hardware-like, in real time, as the Robotarium's
    robots would move it; but a 2.x script (its verification ran it with the 2.x API) in real time on the
    simulator's 2.x model, since the hardware-like mode models the guide's API only (the simulator refuses
    it for a 2.x script). A worker of robots (`fleet`): its arena moves them, nothing to choose."""
    if fleet:
        return RunMode(hardware_like=False)
    if experiment.verified_api == V2_API:
        return RunMode(hardware_like=False, note=V2_NOTE)
    return RunMode(hardware_like=True)


@failing_truthfully
def run_experiment(experiment):
    """./robotarium run in real time (hardware-like as run_mode says) in the experiment's own working folder;
    then the results."""
    root = run_folder(experiment)
    shutil.rmtree(root, ignore_errors=True)
    work, results = root / "work", root / "results"
    copy_files(experiment.files_dir, work)
    results.mkdir(parents=True)
    limit = time_limit()
    fleet = os.environ.get(FLEET_VARIABLE)
    mode = run_mode(experiment, fleet)
    env = job_env("ROBOTARIUM_PORTAL_RUN_DOMAIN")
    warm, network = (None, None) if fleet else warm_testbed(RUN_CLUSTER, env)
    # The worker's testbed (its robots' hardware arena, or the slot's warm one) records the run; else a testbed of
    # its own in its box, recording into the results.
    testbed = ["--no-local-testbed"] if fleet or warm else ["--bags-dir", str(results)]
    run = [str(settings.REPOSITORY / "robotarium"), "run", "--real-time", *(["--hardware"] * mode.hardware_like),
           *testbed, "--no-verdict", "--time-limit", "%g" % limit, "--results-dir", str(results), experiment.main_file]
    if warm:
        rescue_warm_recordings(experiment)
    # The live view's feed beside the run, on its testbed (live_feed.py); the job's end ends it.
    command = ["sh", "-c", '"$0" -m robotarium_portal.live_feed "$1" & shift; exec "$@"', sys.executable,
               str(live_file(experiment)), *run]
    began = time.monotonic()
    code = run_command(command, work, env, root / "output.txt", limit + RESULTS_GRACE, RUN_CLUSTER,
                       own_network=not fleet, network=network)
    if fleet or warm:
        bring_results(root / "output.txt", results)
    experiment.timings = dict(experiment.timings or {}, run_command=round(time.monotonic() - began, 3))
    if stopping():
        return "the service stopped during the run of experiment %d" % experiment.pk
    folders = sorted((p for p in results.iterdir() if (p / run_record.FILE).exists()), key=lambda p: p.stat().st_mtime)
    run = (run_record.read(str(folders[-1])) if folders else None) or run_record.RunRecord()
    outcome = run.outcome
    how = "\n" + mode.note if mode.note else ""   # how it ran, where that needs saying (run_mode)
    # What the page said before the run (not verified; an earlier run cut short by a stop) stays said.
    earlier = "\n\n" + experiment.detail if experiment.detail else ""
    experiment.results = str(folders[-1].relative_to(experiment.folder)) if folders else ""
    experiment.run_outcome = outcome
    if outcome in ("completed", "time_limit"):
        detail = run.detail or "Run completed."
        differs = experiment.differs_from_verification()
        if differs is not None:
            mail.try_sending(mail.tell_administrators_of_a_difference, experiment, *differs)
        return _finish(experiment, Experiment.COMPLETED, detail + how + earlier, results=experiment.results,
                       run_outcome=outcome, timings=experiment.timings)
    if code is None:
        why = "the run did not end within %d s of its start" % (limit + RESULTS_GRACE)
    elif run.detail:
        why = run.detail
    else:
        why = "./robotarium run ended with exit code %s and no results:\n%s" % (code, _tail(root / "output.txt"))
    return _finish(experiment, Experiment.FAILED, "Failed: " + why + box_notes(root / "output.txt") + how + earlier,
                   results=experiment.results,
                   run_outcome=outcome, timings=experiment.timings)
