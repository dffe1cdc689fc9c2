"""Running a script for `run`, `verify` and `demo`: a Run finds or starts a testbed, runs the script
in a process of its own (robotarium_cli.runner), and collects the run folder from what that process
kept (run.json: robotarium_core.run_record) and what the testbed recorded. Its scratch folder (the
script's log and run.json, pending.json: what finishing the folder needs) lives in
<results dir>/.unfinished/ until the folder is finished: should ./robotarium run be killed outright,
the next run, status or report finishes it from there (finish_unfinished), as run would have.
"""
import contextlib
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

import robotarium_recording as recording
from robotarium_bringup import local_testbeds
from robotarium_bringup.testbed import (
    RECORDING_LOOKUP_WAIT,
    LocalTestbed,
    announced_recording,
    nodes_seen,
    probe_context,
    repository_root,
    testbed_answers,
)
from robotarium_cli import verification
from robotarium_cli.console import Interruption, say, shown
from robotarium_cli.folders import (
    check_run_folders,
    check_script,
    finish_run_folder,
    modified_time,
    new_run_folder,
    print_summary,
    snapshot_files,
    tee,
    wait_until_recorded,
    write_unrecorded_results,
)
from robotarium_cli.runner import STARTED
from robotarium_client import session
from robotarium_core import lifeline, outcomes, run_record, script_box
from robotarium_core.config import DEFAULT, TestbedConfig
from robotarium_core.topics import namespace_from_environment as namespace

UNFINISHED = ".unfinished"


@dataclasses.dataclass
class RunRequest:
    """What a command (run, verify, demo) asks of one run of a script: where its testbed and results
    come from and go, and `options`, what the script's Robotarium is told (session.RunOptions: the
    mode, --config, --time-limit, --hardware, --seed, --rps, audit, waiting in line), carried to the
    script's process as they are, with the testbed's namespace and the run's name filled in."""
    script: str
    script_args: tuple = ()
    options: session.RunOptions = dataclasses.field(default_factory=session.RunOptions)
    record: bool = True          # a testbed started here records the run (bags_dir)
    bags_dir: object = None      # None: <repository>/bags
    results: bool = True         # the results from the recording (report, plot, page)
    video: bool = True
    local_testbed: bool = True   # start a testbed here when none answers (False: wait for one)
    own_testbed: bool = False    # start one here without looking (verify: a namespace of its own)
    warm_testbed: bool = False   # one runs in `namespace`, known from this machine's registry (verify's warm
                                 # verification testbed): use it, never look for or start one
    results_dir: object = None   # None: <repository>/results
    namespace: object = None     # the testbed's namespace; None: $ROBOTARIUM_NAMESPACE or /robotarium
    echo: bool = True            # show what the script prints and where the results are (log.txt has the prints)
    # Where the safety layer changed the script's commands, judge the script as the Robotarium's
    # verification does (verify_script) and keep the verdict with the run (run.json).
    judge: bool = False


@dataclasses.dataclass
class PendingRun:
    """What finishing a run's folder needs, kept in its scratch folder while it goes on (pending.json;
    claimed.json once a command finishes it for a ./robotarium run that was killed)."""
    run: dict                    # ./robotarium run's process (local_testbeds.process)
    script: str
    cwd: str
    started: float               # time.time() at the script's start
    started_at: str
    bags_dir: object
    results: bool
    results_dir: str
    name: str
    video: bool
    before: dict                 # the working folder's files and their times before the run (snapshot_files)
    namespace: str = ""
    runner: dict | None = None   # the script's process, once started
    by: dict | None = None       # the process finishing the folder (claimed.json)

    PENDING, CLAIMED = "pending.json", "claimed.json"

    def write(self, work, name=PENDING):
        path = os.path.join(work, name)
        with open(path + ".tmp", "w") as f:
            json.dump(dataclasses.asdict(self), f)
        os.replace(path + ".tmp", path)

    @classmethod
    def read(cls, path):
        try:
            with open(path, encoding="utf-8") as f:
                values = json.load(f)
            return cls(**{k: v for k, v in values.items() if k in {f.name for f in dataclasses.fields(cls)}})
        except (OSError, ValueError, TypeError):
            return None


def finish_unfinished(results_dir=None, quiet=False):
    """Finish the run folder of every run in results_dir (default results/) whose ./robotarium run
    was killed before it finished it; says so, one line each. Returns the folders finished."""
    results_dir = os.path.abspath(results_dir or os.path.join(repository_root(), "results"))
    parent = os.path.join(results_dir, UNFINISHED)
    try:
        works = sorted(os.listdir(parent))
    except OSError:
        return []
    finished = []
    for entry in works:
        work = os.path.join(parent, entry)
        claimed = PendingRun.read(os.path.join(work, PendingRun.CLAIMED))
        if claimed is not None and claimed.by and not local_testbeds.running(claimed.by):
            # its finisher was killed in turn: hand the run back
            os.replace(os.path.join(work, PendingRun.CLAIMED), os.path.join(work, PendingRun.PENDING))
        pending = PendingRun.read(os.path.join(work, PendingRun.PENDING))
        if pending is None:
            if claimed is None and time.time() - modified_time(work) > 60:   # run was killed before it started the script
                shutil.rmtree(work, ignore_errors=True)
            continue
        if local_testbeds.running(pending.run):
            continue   # its ./robotarium run is still at work
        try:   # claim it: only one command finishes a run
            os.rename(os.path.join(work, PendingRun.PENDING), os.path.join(work, PendingRun.CLAIMED))
        except OSError:
            continue
        pending.by = local_testbeds.process(os.getpid())
        pending.write(work, PendingRun.CLAIMED)
        # The orphaned script ends its experiment and exits within moments (runner.ORPHAN_EXIT).
        deadline = time.monotonic() + 10.0
        while local_testbeds.running(pending.runner) and time.monotonic() < deadline:
            time.sleep(0.1)
        try:
            _, record, run_dir = Run.resume(work, pending).collect()
        except Exception as error:   # noqa: BLE001 - leave it for the next try, say why
            os.replace(os.path.join(work, PendingRun.CLAIMED), os.path.join(work, PendingRun.PENDING))
            say("could not finish the folder of a run whose ./robotarium run was killed (%s); %s keeps what it left"
                % (session.describe_exception(error), work))
            continue
        finished.append(run_dir)
        if not quiet:
            say("the run of %s (%s) lost its ./robotarium run (pid %d, killed); its folder is finished now: %s"
                % (os.path.basename(pending.script), record.run_id or "no experiment", pending.run["pid"],
                   shown(run_dir)))
    return finished


def run_script(request):
    """Run an experiment script (a RunRequest) against the testbed (starting one here if none
    answers and `local_testbed` allows it). Whatever happens, the run folder gets the log, the
    report, the results page and run.json (with the plot and the video when the run was recorded
    here); a script that cannot be compiled or imported fails before a testbed is started. SIGINT,
    SIGTERM and SIGHUP stop the script and this testbed (Interruption); the results are then made as
    for any run that did not complete.

    Returns (exit code, its run_record.RunRecord or None, run folder or None).
    """
    script = request.script = os.path.abspath(request.script)
    if not os.path.isfile(script):
        say("no such script: %s" % script)
        return outcomes.USAGE_ERROR, None, None
    request.results_dir = os.path.abspath(request.results_dir or os.path.join(repository_root(), "results"))
    folders = [request.results_dir]
    if request.record and request.local_testbed:   # a testbed started here records into bags_dir
        folders.append(os.path.abspath(request.bags_dir or os.path.join(repository_root(), "bags")))
    problem = check_run_folders(folders, request.options.config_file)
    if problem is not None:
        return problem, None, None
    problem = check_script(script)
    if problem is not None:
        return _refused_script(request, *problem)
    interruption = Interruption()
    run = Run(request, interruption)
    try:
        run.warm_up()
        if not run.start():   # no testbed, or a signal while it looked for one (128 + it, as a shell says)
            code = interruption.exit_code if interruption.signum else outcomes.EXIT_CODES[outcomes.TESTBED_LOST]
            return code, None, None
        run.wait()
        interruption.restore()   # from here on (results, video) a signal acts as usual
        return run.collect()   # the results are made as soon as the bag is closed, while the nodes exit
    finally:
        interruption.restore()
        if run.live is not None:
            run.live.close()   # (a run whose results were not made from its bag: its video is not wanted)
        run.stop_testbed()


def _refused_script(request, detail, text):
    """A script that cannot be compiled or imported: its folder says why; no testbed was started."""
    print(text, end="", file=sys.stderr, flush=True)
    record = run_record.RunRecord(outcome=outcomes.NAMES[outcomes.SCRIPT_ERROR],
                                  detail="the script %s; no testbed was started" % detail, step_calls=0,
                                  exit_code=outcomes.EXIT_CODES[outcomes.SCRIPT_ERROR], script=request.script,
                                  started=time.strftime("%Y-%m-%d %H:%M:%S"))
    run_dir = new_run_folder(request.results_dir, session.experiment_name_of(request.script))
    work = tempfile.mkdtemp(prefix="robotarium-run-")
    try:
        log_path = os.path.join(work, "log.txt")
        with open(log_path, "w") as log:
            log.write(text)
        finish_run_folder(run_dir, record, request.script, log_path, [], os.getcwd())
    finally:
        shutil.rmtree(work, ignore_errors=True)
    write_unrecorded_results(run_dir, record)
    print_summary(run_dir, record, os.getcwd())
    return record.exit_code, record, run_dir


# Seconds a testbed elsewhere on the domain has to answer before `run` starts one here: discovery
# usually takes tens of milliseconds, but now and then waits for Fast DDS's next periodic
# announcement (3 s; docs/benchmarks.md). The nodes started behind the start gate import meanwhile.
# Where discovery reaches this machine only, the process table knows every testbed: no wait.
PROBE_WAIT = 3.0
# ... and one seen running on this machine (in the process table) has as long.
LOCAL_PROBE_WAIT = 3.0


def discovery_is_local():
    """Whether DDS discovery on this shell's domain reaches only this machine (then the process
    table knows every testbed that could answer)."""
    reach = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper()
    return reach in ("LOCALHOST", "OFF") and not os.environ.get("ROS_STATIC_PEERS", "").strip()


def find_or_start_testbed(ns, record, bags_dir, config_file):
    """The testbed for a run: None when one answers in `ns` on the domain, else a LocalTestbed
    started here. Its nodes start at once behind a start gate (their imports overlap the search)
    and join DDS only once no testbed answered: never two testbeds in one namespace."""
    here = local_testbeds.matching(local_testbeds.find(), ns, local_testbeds.domain_id())
    running_here = any(any(name.startswith(("simulator", "arena")) for name in t["nodes"]) for t in here)
    if running_here:   # ./robotarium up (or ros2 run) on this machine: it answers
        if testbed_answers(ns, timeout=LOCAL_PROBE_WAIT):
            return None
    testbed = LocalTestbed(record=record, ns=ns, bags_dir=bags_dir, config_file=config_file,
                           looked=True).start(gated=True)
    try:
        if not running_here and not discovery_is_local() and testbed_answers(ns, timeout=PROBE_WAIT):
            testbed.cancel()
            return None
    except BaseException:
        testbed.cancel()
        raise
    return testbed.open()


def new_work_folder(results_dir):
    """The scratch folder of one run: in results_dir/.unfinished/, or (the portal's job box, which
    keeps its own books) a temporary folder."""
    if script_box.VARIABLE in os.environ:
        return tempfile.mkdtemp(prefix="robotarium-run-")
    parent = os.path.join(results_dir, UNFINISHED)
    os.makedirs(parent, exist_ok=True)
    return tempfile.mkdtemp(prefix="run-", dir=parent)


class Run:
    """One run of a script: its request, its testbed (found on the domain, started here, or its own),
    its scratch folder and the interruption that may stop it. start() finds or starts the testbed and
    keeps what finishing the folder needs; wait() runs the script's process to its end; collect()
    makes the run folder and the results. resume() is the collect of a run whose ./robotarium run was
    killed (finish_unfinished)."""

    def __init__(self, request, interruption=None):
        self.request = request
        self.interruption = interruption   # None: finishing a run whose ./robotarium run was killed
        self.ns = request.namespace or namespace()
        self.testbed = None   # a LocalTestbed this run started (None: one that answered, or none yet)
        self.work = None
        self.pending = None
        self.code = None      # the script's process's exit code (None: it never started)
        self.frozen = None    # FrozenScript that killed a script stopped too long, once it did
        self.unlogged = None  # folders.Unlogged: the script's output its log's full disk refused
        self.live = None      # recording.LiveVideo: the video, made while the run goes
        self.warm = None      # WarmRunner: the script's process, started before the testbed was found

    @property
    def record_path(self):
        return os.path.join(self.work, run_record.FILE)

    @property
    def log_path(self):
        return os.path.join(self.work, "log.txt")

    @property
    def quiet(self):
        return self.interruption is None or not self.request.echo

    # -- start ------------------------------------------------------------------------------------------

    def start(self):
        """Find or start the testbed and open the scratch folder. False when no testbed answers and
        none may be started here (it says so)."""
        request, interrupted = self.request, self.interruption.signum is not None
        config_file = request.options.config_file
        if request.own_testbed:
            if not interrupted:
                self.testbed = LocalTestbed(record=request.record, ns=self.ns, bags_dir=request.bags_dir,
                                            config_file=config_file, looked=True).start()
        elif request.warm_testbed:
            pass   # the script's client finds it (and says so if it does not answer)
        elif not request.local_testbed:   # a testbed is known to be up (or coming up): wait for it, never start one
            if not testbed_answers(self.ns, timeout=60.0, stop=lambda: self.interruption.signum is not None):
                if self.interruption.signum is not None:   # Ctrl-C while it waited: nothing ran, nothing to say
                    return False
                say("no testbed answers in %s on ROS_DOMAIN_ID %s (--no-local-testbed forbids starting one); "
                    "start it with ./robotarium up" % (self.ns, os.environ.get("ROS_DOMAIN_ID", "0")))
                seen = nodes_seen()
                say("the DDS graph of this domain shows %s" % (", ".join(seen) if seen else
                                                              "no node at all: discovery does not reach this process"))
                return False
            if request.options.wait:   # (--no-wait: its one line says what happened)
                say("using the testbed that answers in %s" % self.ns)
        elif not interrupted:
            self.testbed = find_or_start_testbed(self.ns, request.record, request.bags_dir, config_file)
            if self.testbed is not None:
                say("no testbed answers in %s: started one on this machine for this run (logs in %s)"
                    % (self.ns, shown(self.testbed.log_dir)))
            elif request.options.wait:   # (--no-wait: its one line says what happened)
                say("using the testbed that answers in %s" % self.ns)
        self.work = new_work_folder(request.results_dir)
        cwd = os.getcwd()
        self.pending = PendingRun(
            run=local_testbeds.process(os.getpid()), script=request.script, cwd=cwd, started=time.time(),
            started_at=time.strftime("%Y-%m-%d %H:%M:%S"), bags_dir=request.bags_dir, results=request.results,
            results_dir=request.results_dir, name=session.experiment_name_of(request.script), video=request.video,
            before=snapshot_files(cwd), namespace=self.ns)
        self.pending.write(self.work)
        return True

    # -- wait -------------------------------------------------------------------------------------------

    def wait(self):
        """Run the script in its own process, its output to the log (and the console), until it ends;
        then let the testbed this run started end its experiment and close the recording."""
        request = self.request
        if request.results and request.record:   # made while the script runs: the results' imports
            threading.Thread(target=recording.preload_results, args=(request.video,), daemon=True).start()
            if request.video and recording.live_video_enabled() and self.interruption.signum is None:
                self.live = recording.LiveVideo(self.ns, os.path.join(self.work, STARTED), probe_context).start()
        try:
            if self.interruption.signum is None:
                arguments = self._script_arguments()
                with open(self.log_path, "wb", buffering=0) as log:
                    process = self.warm.go(arguments, self.work) if self.warm is not None else None
                    if process is None:   # (none warm, or it is gone: started now, as it would have been)
                        env, pass_fds, box_options = self._script_environment([self.work])
                        process = subprocess.Popen([*RUNNER, *arguments], cwd=self.pending.cwd, env=env,
                                                   pass_fds=pass_fds, **SCRIPT_PROCESS, **box_options)
                    self.interruption.watch(process)
                    self.frozen = FrozenScript(process)
                    self.pending.runner = local_testbeds.process(process.pid)
                    self.pending.write(self.work)
                    # the log first: it never lags what was shown
                    self.unlogged = tee(process.stdout, log, sys.stdout.buffer if request.echo else None)
                    self.code = process.wait()
        finally:
            if self.testbed is not None:
                self.testbed.begin_stop()  # the simulator ends an experiment still running; the recorder closes the bag

    def warm_up(self):
        """Start the script's process now, behind a gate (WarmRunner): its Python and imports overlap the look
        for the testbed and its start; wait() hands it the run's arguments. Where the run never gets there, the
        gate closes and it ends having run nothing."""
        if self.interruption.signum is None:
            try:
                self.warm = WarmRunner(*self._script_environment([]), os.getcwd(), self.ns)
            except OSError:   # (it cannot start now: wait() starts it as it always did, and says why if it fails)
                self.warm = None

    def _script_arguments(self):
        """The runner's arguments: the run's options, its record's path, the script and its arguments."""
        request, config_file = self.request, self.request.options.config_file
        # The testbed is up (found or started): the script waits for it, never starts another.
        options = dataclasses.replace(request.options, local_testbed=False, namespace=self.ns,
                                      experiment_name=self.pending.name,
                                      progress_interval=session.progress_from_environment(10.0),
                                      config_file=os.path.abspath(config_file) if config_file else None)
        return [options.to_json(), self.record_path, request.script, *request.script_args]

    def _script_environment(self, writable):
        """The script's process's environment, inherited descriptors and job-box options; `writable`: folders
        handed to the script's account (the run's scratch folder)."""
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
            env.setdefault("MPLBACKEND", "Agg")
        # The script's lifeline: should this command be killed outright, the script stops too.
        env, pass_fds = lifeline.for_child(env)
        # In the portal's job box only the script is demoted (its account, its limits); the testbed stays the service's.
        box_options, env = script_box.popen_options(env, writable=writable)
        return env, pass_fds, box_options

    def stop_testbed(self):
        if self.testbed is not None:
            self.testbed.stop()
        if self.warm is not None:
            self.warm.cancel()   # (never let go: it ends having run nothing)

    # -- collect ----------------------------------------------------------------------------------------

    @classmethod
    def resume(cls, work, pending):
        """The Run of a ./robotarium run that was killed outright, to collect its folder."""
        request = RunRequest(pending.script, bags_dir=pending.bags_dir, results=pending.results, video=pending.video,
                             results_dir=pending.results_dir, namespace=pending.namespace or None, echo=False)
        run = cls(request)
        run.work, run.pending, run.code = work, pending, -signal.SIGKILL
        return run

    def collect(self):
        """The run folder and the results, from what the script's process kept and what the testbed
        recorded. Returns (exit code, run_record.RunRecord or None, run folder or None)."""
        pending, interruption = self.pending, self.interruption
        if self.code is None:
            say("interrupted (%s) before the script started%s" % (
                interruption.name, "; the testbed this run started was stopped" if self.testbed is not None else ""))
            shutil.rmtree(self.work, ignore_errors=True)
            return interruption.exit_code, None, None
        record, died = self._record()
        if interruption is not None and interruption.signum is not None:
            say("interrupted (%s): the script was stopped%s" % (
                interruption.name, " and the testbed this run started was stopped" if self.testbed is not None else ""))
        if record.outcome == outcomes.NAMES[outcomes.TESTBED_BUSY]:
            # Nothing ran (--no-wait on a busy testbed): the script's process said so in one line, and a run
            # that never ran gets no folder.
            shutil.rmtree(self.work, ignore_errors=True)
            return record.exit_code, record, None
        saved = [p for p, mtime in snapshot_files(pending.cwd).items()
                 if pending.before.get(p) != mtime and mtime / 1e9 >= pending.started - 1]
        run_dir, bag_dir, stopped, not_here = self._run_folder(record)
        if (self.request.judge and record.safety_interventions
                and record.outcome == outcomes.NAMES[outcomes.COMPLETED]):
            record.verdict = _judge(self.request, record)
        if bag_dir:
            run_dir = self._recorded_results(record, run_dir, bag_dir, stopped, died, saved)
        else:
            self._finish_run_folder(run_dir, record, saved)
            write_unrecorded_results(run_dir, record, record.last.report if record.last else "", not_here)
        shutil.rmtree(self.work, ignore_errors=True)   # last: a run whose folder is finished is no longer pending
        if not self.quiet:
            print_summary(run_dir, record, pending.cwd)
        return record.exit_code, record, run_dir

    def _record(self):
        """(the run's record, how the script's process died or None): what it kept, or, killed outright,
        what is known of it (started.json: the experiment it started)."""
        record, died = run_record.read(self.record_path), None
        if record is None:
            interruption, code = self.interruption, self.code
            if interruption is None:   # finishing the folder of a ./robotarium run that was killed
                died, exit_code = "./robotarium run was killed", 128 + signal.SIGKILL
            elif interruption.signum is not None:
                died, exit_code = "interrupted by %s and killed" % interruption.name, interruption.exit_code
            elif self.frozen is not None and self.frozen.killed:
                died, exit_code = self.frozen.killed, 128 - code if code < 0 else code
            elif code == -signal.SIGALRM:   # its step() stuck in its own Fast DDS (testbed_link.HUNG_STEP)
                died, exit_code = outcomes.OWN_DDS_HUNG, outcomes.EXIT_CODES[outcomes.TESTBED_LOST]
            elif code < 0:
                died, exit_code = "killed by %s" % signal.Signals(-code).name, 128 - code
            else:
                died, exit_code = "exit code %d" % code, code or 1
            started = _read_json(os.path.join(self.work, STARTED))
            if died == outcomes.OWN_DDS_HUNG:
                outcome, detail = outcomes.NAMES[outcomes.TESTBED_LOST], died
            else:
                outcome = "interrupted" if died.startswith(("./", "interrupted", "killed")) else "script_error"
                detail = ("%s, and the script's process ended before it could say how its run ended" % died
                          if interruption is None else
                          "the script's process ended (%s) before it could end its experiment" % died)
            record = run_record.RunRecord(
                outcome=outcome, detail=detail,
                exit_code=exit_code, experiments=[run_record.Experiment.from_dict(started)] if started else [])
        # The run is its (last) experiment: its fields at the top, how the script's run ended over them.
        record.take_last_experiment()
        record.script, record.started = self.pending.script, self.pending.started_at
        record.wall_time = round(time.time() - self.pending.started, 3)
        return record, died

    def _run_folder(self, record):
        """(run folder, its bag's folder or "", "recording stopped at step k: why" or "", why the results
        are not made here or ""): the bag's folder where the recorder kept the run here, else
        results/<run id>/."""
        pending, last = self.pending, record.last
        run_dir = last.recording if last else ""
        announced = bool(run_dir)
        if record.run_id and not run_dir:
            # A very short run can end before the recorder's announcement of its folder arrived.
            guess = os.path.join(pending.bags_dir or os.path.join(repository_root(), "bags"), record.run_id)
            run_dir = guess if os.path.isdir(guess) else ""
            if not run_dir and pending.results and record.outcome != outcomes.NAMES[outcomes.COMPLETED]:
                # Killed, or the testbed lost, before its client heard the announcement (a busy recorder
                # opens the bag a few steps late, after the client's "running"): ask the recorder.
                if not self.quiet:
                    say("asking the testbed's recorder where run %s is recorded (up to %.0f s)"
                        % (record.run_id, RECORDING_LOOKUP_WAIT))
                run_dir = announced_recording(record.run_id, self.ns)
                announced = bool(run_dir)
        recorded = bool(run_dir) and os.path.isdir(run_dir) and pending.results
        not_here = _not_recorded_here(announced, run_dir, pending.results) if not recorded else ""
        bag_dir = run_dir if recorded else ""
        if recorded and record.recording_stopped_because == outcomes.RECORDER_GONE and _recorded_whole(record, bag_dir):
            # The client lost sight of the recorder (frozen, or starved on a busy machine, for longer than it
            # waits to confirm a loss) and the recorder came back: it closed the bag, which holds the whole run.
            if not self.quiet:
                say("the recorder came back after the script lost sight of it at step %d: it recorded the whole run"
                    % record.recording_stopped_at_step)
            for each in [record] + record.experiments[-1:]:
                each.recording_stopped_at_step = each.recording_stopped_because = None
        stopped = outcomes.recording_stopped(record)
        if stopped and record.exit_code == 0:   # completed, but its recording is not: not a success (README)
            record.exit_code = outcomes.EXIT_CODES[outcomes.TESTBED_LOST]
        # The recorder could not write (a full disk): the bag's disk takes nothing more, so the run's
        # folder is results/<run id>/, with the results of what the bag holds.
        write_error = bool(stopped) and not outcomes.recorder_lost(record.recording_stopped_because)
        if recorded and stopped:
            stopped = self._tidy_stopped_recording(record, bag_dir, write_error)
        if not recorded or write_error:
            # Not recorded here (another machine's testbed, no recorder, or no experiment at all):
            # keep the local outputs in results/<run id>/.
            run_dir = (os.path.join(pending.results_dir, record.run_id) if record.run_id
                       else new_run_folder(pending.results_dir, pending.name))
            os.makedirs(run_dir, exist_ok=True)
        return run_dir, bag_dir, stopped, not_here

    def _tidy_stopped_recording(self, record, bag_dir, write_error):
        """Nothing will close the bag (its recorder is gone, or stopped writing it): make its metadata
        agree with its file where its disk allows; the step it stopped at is the last it holds."""
        if not write_error:   # (a recorder that could not write tidied the bag itself, as far as its disk let it)
            self.stop_testbed()
            try:
                recording.recover_bag(bag_dir)
            except OSError as error:
                say("could not tidy the recording in %s (%s); readers scan it as it is" % (bag_dir, error.strerror))
        steps = _recorded_steps(bag_dir)
        if len(steps):   # (none readable: the client's step stands)
            record.recording_stopped_at_step = int(steps[-1])
        stopped = outcomes.recording_stopped(record)
        if not self.quiet:
            say("%s: %s %s" % (stopped, bag_dir, "holds the run up to there" if len(steps) else "holds no step of it"))
        return stopped

    def _finish_run_folder(self, run_dir, record, saved):
        pending = self.pending
        finish_run_folder(run_dir, record, pending.script, self.log_path, saved, pending.cwd,
                          _data_limit(self.request.options.config_file))
        if self.unlogged is not None:
            self.unlogged.append_to(os.path.join(run_dir, "log.txt"))

    def _recorded_results(self, record, run_dir, bag_dir, stopped, died, saved):
        """The run folder finished, with its report, plot, video and page made from the recording once the
        bag is closed. Returns the run folder: the bag's, or results/<run id>/ where the bag's disk is full
        (it can fill as the recorder closes the bag, after the run: then its client heard nothing of it)."""
        if not stopped:
            # A lost testbed may never close the bag: then take what is on disk after a short wait. A
            # script killed outright has its experiment ended by the testbed (client_lease) or by
            # this command's stopping of its own testbed.
            timeout = 15.0 if record.ended or died or self.interruption is None else 3.0
            if self.testbed is None:
                wait_until_recorded(bag_dir, timeout, quiet=self.quiet)
            elif not wait_until_recorded(bag_dir, timeout, quiet=True):
                self.stop_testbed()   # its recorder closes the bag as it stops (or is gone)
                wait_until_recorded(bag_dir, timeout=1.0)
        in_the_bag = set(os.listdir(bag_dir)) if run_dir == bag_dir else None
        try:
            self._finish_run_folder(run_dir, record, saved)
            self._results(record, run_dir, bag_dir, died)
        except OSError as error:
            if in_the_bag is None or not outcomes.disk_full(error):
                raise
            run_dir = self._beside_a_full_bag_disk(record, bag_dir, in_the_bag)
            self._finish_run_folder(run_dir, record, saved)
            self._results(record, run_dir, bag_dir, died)
        return run_dir

    def _beside_a_full_bag_disk(self, record, bag_dir, in_the_bag):
        """The bag's disk refused the run folder's files: take back what this command wrote there, mark the
        recording stopped where the bag does not hold the whole run, and return results/<run id>/."""
        for name in set(os.listdir(bag_dir)) - in_the_bag:
            path = os.path.join(bag_dir, name)
            if name.endswith(".mcap") or name.startswith("metadata"):
                continue   # the recorder's, whatever it did meanwhile
            if os.path.isdir(path) and not os.path.islink(path):
                shutil.rmtree(path, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    os.remove(path)
        if not _holds_the_whole_run(record, bag_dir) and record.recording_stopped_at_step is None:
            steps = _recorded_steps(bag_dir)
            for each in [record] + record.experiments[-1:]:
                each.recording_stopped_at_step = int(steps[-1]) if len(steps) else 0
                each.recording_stopped_because = outcomes.DISK_FULL
            if record.exit_code == 0:   # completed, but its recording is not: not a success (README)
                record.exit_code = outcomes.EXIT_CODES[outcomes.TESTBED_LOST]
        run_dir = os.path.join(self.pending.results_dir, record.run_id)
        os.makedirs(run_dir, exist_ok=True)
        if not self.quiet:
            stopped = outcomes.recording_stopped(record)
            say("the disk of %s is full: the run's folder is %s%s" % (
                bag_dir, run_dir, " (%s)" % stopped if stopped else " (the recording holds the whole run)"))
        return run_dir

    def _results(self, record, run_dir, bag_dir, died):
        """Report, plot, video and page from the recording into `run_dir`. A full disk in the bag's own
        folder is raised (the caller moves the run folder); any other failure is said, the folder kept."""
        try:
            if died:   # the testbed's steps, as the report counts them (a killed script could not say)
                recorded_steps = recording.Bag(bag_dir).poses().steps
                record.steps = int(recorded_steps[-1]) if len(recorded_steps) else 0
                run_record.write(record, run_dir)
            recording.write_results(bag_dir, progress=not self.quiet, video=self.pending.video, run=record,
                                    out_dir=run_dir, live=self.live)
        except Exception as error:   # noqa: BLE001 - say so, keep the folder
            if run_dir == bag_dir and outcomes.disk_full(error):
                raise
            why = _why_no_results(bag_dir, error)
            write_unrecorded_results(run_dir, record, record.last.report if record.last else "", why)
            say("%s; see %s" % (why, run_dir))   # (after: a full disk there moves the folder first)


RUNNER = [sys.executable, "-m", "robotarium_cli.runner"]
# A process group of its own: a terminal's Ctrl-C reaches only `run`, which forwards it once (a second SIGINT
# would cut short the script's exit handler ending its experiment). Its output goes to the log (tee).
SCRIPT_PROCESS = {"process_group": 0, "stdout": subprocess.PIPE, "stderr": subprocess.STDOUT}


class WarmRunner:
    """The script's process started ahead of its run (runner --gated): a warm interpreter that imports what
    every script needs while `run` looks for the testbed or starts one, then waits at its start gate for the
    run's arguments (go), or ends having run nothing when the gate closes without them (cancel, or `run`'s
    death). Same account, limits, environment and folder as a process started at the run."""

    def __init__(self, env, pass_fds, box_options, cwd, namespace):
        self.gate = lifeline.StartGate()
        env, pass_fds = self.gate.for_child(env, pass_fds)
        try:
            self.process = subprocess.Popen([*RUNNER, "--gated", namespace], cwd=cwd, env=env, pass_fds=pass_fds,
                                            **SCRIPT_PROCESS, **box_options)
        except OSError:
            self.gate.close()
            raise
        self.gate.close_read_end()

    def go(self, arguments, work):
        """Hand it the run's arguments and `work` (the run's scratch folder, for its account); the Popen, or
        None where it already ended (then the run starts its script's process afresh)."""
        if self.process.poll() is not None:
            self.cancel()
            return None
        script_box.hand_over(os.environ, [work])
        self.gate.open(1, json.dumps(arguments).encode())
        process, self.process = self.process, None
        return process

    def cancel(self):
        self.gate.close()
        if self.process is not None:
            try:
                self.process.wait(timeout=5)   # it reads the gate closed and exits at once
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
            self.process.stdout.close()
            self.process = None


def _recorded_steps(bag_dir):
    """The steps whose poses the bag in `bag_dir` holds; none where nothing is readable (no bag, no poses topic)."""
    try:
        return recording.Bag(bag_dir).poses().steps
    except Exception:   # noqa: BLE001 - nothing readable: no step
        return ()


def _why_no_results(bag_dir, error):
    """Why the results of a run could not be made from its recording in `bag_dir` (`error` raised)."""
    # a recording that stopped (a full disk, a killed recorder) before its first part reached the disk
    if not len(_recorded_steps(bag_dir)):
        return "the recording in %s holds no step of the run, so there are no results of it" % bag_dir
    return "the results could not be made from the recording in %s (%s)" % (bag_dir, session.describe_exception(error))


def _not_recorded_here(announced, recording, results):
    """Why a run's plot and video are not made here: what is known, not a guess."""
    if not results:
        return "no results were asked for"
    if not announced:
        return ("the testbed's recorder did not say where it recorded this run (it may be busy, or the testbed "
                "runs without one); look in its bags/ folder")
    return "the run was recorded on the testbed's machine, not here (%s)" % recording


# s a script's process may stay stopped (SIGSTOP, a debugger) before `run` kills it: by then the testbed ended its
# run (client_lease) and nothing would wake it; `run` would wait for its exit for ever
FROZEN_LIMIT = 2 * DEFAULT.client_lease + 1.0


class FrozenScript:
    """Watches the script's process (started with process_group=0) from a daemon thread: stopped (state T in /proc)
    for FROZEN_LIMIT s on end, its group is killed, and `killed` says how, for run.json."""

    def __init__(self, process, limit=FROZEN_LIMIT, period=0.25):
        self.process, self.limit, self.period = process, limit, period
        self.killed = ""
        threading.Thread(target=self._watch, daemon=True).start()

    def _watch(self):
        since = None
        while self.process.poll() is None:
            stopped = _process_state(self.process.pid) in ("T", "t")
            since = (since or time.monotonic()) if stopped else None
            if since is not None and time.monotonic() - since >= self.limit:
                self.killed = ("killed by ./robotarium run after it stayed stopped (SIGSTOP) for %.0f s; the testbed had "
                               "ended its run when its client stopped answering" % self.limit)
                try:
                    os.killpg(self.process.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                return
            time.sleep(self.period)


def _process_state(pid):
    """The state letter of process `pid` (/proc/<pid>/stat: R, S, T, Z, ...), "" when unknown."""
    try:
        with open("/proc/%d/stat" % pid) as f:
            return f.read().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return ""


# s to wait for a recorder the client lost sight of to close the run's bag after all (it closes a bag half a
# second after the run's end; seconds on a loaded machine). A recorder that is really gone costs this once.
RECORDER_BACK_WAIT = 5.0


def _recorded_whole(record, bag_dir):
    """Whether the recorder closed the run's bag (its own metadata says so: a recovered bag's does not) and
    the bag holds the run whole: the poses of every step from 0 to the testbed's last and the status that
    closed the run."""
    return wait_until_recorded(bag_dir, RECORDER_BACK_WAIT, quiet=True) and _holds_the_whole_run(record, bag_dir)


def _holds_the_whole_run(record, bag_dir):
    """Whether the bag in `bag_dir` holds the run whole (_recorded_whole), as it is now."""
    try:
        bag = recording.Bag(bag_dir)
        steps = [int(k) for k in bag.poses().steps]
        closed = any(s.run_id == record.run_id and s.state == 0 for s in bag.statuses())
    except Exception:   # noqa: BLE001 - unreadable: not whole
        return False
    return closed and bool(steps) and steps == list(range(steps[-1] + 1)) and steps[-1] >= record.steps


def _read_json(path):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def _data_limit(config_file):
    """Bytes of data files a run folder takes: run_data_limit of the configuration given (--config),
    else None (the packaged one's)."""
    return TestbedConfig.load(config_file).run_data_limit * 1e6 if config_file else None


def _judge(request, run):
    """The Robotarium's verdict on a run whose commands the safety layer changed: the script judged
    as ./robotarium verify judges it (lockstep, its own commands, a testbed of its own), printed
    and returned as verification.verdict's document (None: no verdict, and why was said)."""
    say("the safety layer changed %d of your script's command arrays, so this run's counts are not the "
        "Robotarium's: judging the script as its verification does (lockstep, the script's own commands, a testbed "
        "of its own; ./robotarium verify)" % run.safety_interventions)
    scratch = tempfile.mkdtemp(prefix="robotarium-judge-")
    try:
        judged = verify_script(request.script, request.script_args, request.options.config_file,
                                            rps_api=request.options.rps_api, record=False, results_dir=scratch,
                                            echo=False)
    except verification.NoVerdict as error:
        say("no verdict: %s; for the Robotarium's verdict: ./robotarium verify %s" % (error, shown(request.script)))
        return None
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    text = judged.text()
    print(text, end="", flush=True)
    return dict(judged.document(), text=text)


# The namespace of a warm verification testbed (./robotarium up --verification): verify, on this machine
# and ROS_DOMAIN_ID, runs its script there when it is free instead of starting a testbed of its own.
VERIFY_NAMESPACE = "/robotarium_verify"


def warm_verification_testbed(entries, domain, discovery_range, root, config_file, record, bags_dir, alive,
                              namespace=VERIFY_NAMESPACE):
    """The entry, of this machine's registry `entries` (robotarium_bringup.local_testbeds.registered), of a
    warm testbed that judges as a testbed of verify's own would: in `namespace` (VERIFY_NAMESPACE; the portal's
    run slot asks for its run testbed's) on `domain` and `discovery_range`, run from the checkout `root` with
    the configuration file `config_file` ("": the packaged one), neither hardware-like nor a fleet, its owner,
    simulator and safety node alive (alive(process)), and a recorder into `bags_dir` where the run records,
    none where it does not. None when none is."""
    wanted = {"simulator", "safety"} | ({"recorder"} if record else set())
    for entry in entries:
        nodes = entry.get("nodes", {})
        if (entry.get("namespace") == namespace and entry.get("domain") == domain
                and entry.get("discovery_range", "") == discovery_range and entry.get("root") == root
                and entry.get("config_file") == config_file and entry.get("hardware") is False
                and not entry.get("fleet_file") and set(nodes) == wanted
                and (not record or (entry.get("bags_dir") or os.path.join(root, "bags")) == bags_dir)
                and alive(entry.get("owner")) and all(alive(p) for p in nodes.values())):
            return entry
    return None


# Set by the portal's verification slot for the verify it runs in a job box (robotarium_portal.jobs): the
# registry entry, as JSON, of the slot's warm verification testbed, which runs in the network namespace the box
# joined. From inside the box neither this machine's registry (its /tmp is the box's) nor the testbed's processes
# (its PID namespace is the job's) can be seen: the slot found it running with these settings just before.
WARM_VARIABLE = "ROBOTARIUM_WARM_VERIFICATION"


def find_warm_verification_testbed(config_file, record, bags_dir):
    """warm_verification_testbed of this machine (or the one WARM_VARIABLE names: taken from the environment,
    so the script never gets it), for a verification with these settings."""
    root = repository_root()
    named = os.environ.pop(WARM_VARIABLE, "")
    if named:
        try:
            entries, alive = [json.loads(named)], lambda process: True   # busy or lost: the fallback says so
        except ValueError:
            entries, alive = [], local_testbeds.running
    else:
        entries, alive = [entry for _, entry in local_testbeds.registered()], local_testbeds.running
    return warm_verification_testbed(
        entries, local_testbeds.domain_id(), os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", ""), root,
        os.path.abspath(config_file) if config_file else "", record,
        os.path.abspath(bags_dir or os.path.join(root, "bags")), alive)


def warm_testbed_failure(code, run):
    """Why a verification on the warm testbed gave no verdict through the testbed's doing (it was busy,
    did not answer, was lost, stopped or incomplete), or None: the run judges the script (or fails as
    one on verify's own testbed would). `code` and `run`: run_script's exit code and run_record.RunRecord."""
    if run is None:
        return None
    if run.outcome == outcomes.NAMES[outcomes.TESTBED_BUSY]:
        return "is busy"
    if (run.outcome == outcomes.NAMES[outcomes.SCRIPT_ERROR] and not run.run_id
            and outcomes.NO_TESTBED_ANSWERS in str(run.detail)):   # the client's error, not the script's
        return "does not answer"
    if run.outcome in ("testbed_lost", "unfinished", "testbed_incomplete") or (
            run.outcome == "interrupted" and 0 < code < 128):   # ended by the testbed, not by a signal to verify
        return "failed (%s)" % (run.detail or run.outcome)
    return None


def verify_script(script, script_args=(), config_file=None, robots=None, duration=None, rps_api=None, record=True,
                  bags_dir=None, results_dir=None, echo=True, video=False):
    """Judge `script` as the Robotarium's verification does: the static rules, then a lockstep run with
    the safety node auditing, on the warm verification testbed where one matches and is free
    (find_warm_verification_testbed), else on a testbed of its own (a namespace no other testbed uses).
    Returns a verification.Verdict; raises verification.NoVerdict where the run could not judge it."""
    config = TestbedConfig.load(config_file) if config_file else DEFAULT
    rules = verification.static_rules(script, config)
    if rules:
        return verification.Verdict(rules, None, "", None, config, robots, duration)
    options = session.RunOptions(real_time=False, config_file=config_file, audit=True,
                                 rps_api=rps_api or session.rps_api_from_environment())

    def request(options, **testbed):
        return RunRequest(script, tuple(script_args), options, record=record, bags_dir=bags_dir, video=video,
                          results_dir=results_dir, echo=echo, **testbed)
    how = "lockstep, safety node auditing (the script's own commands go through and every collision counts)"
    warm = find_warm_verification_testbed(config_file, record, bags_dir)
    if warm is not None:
        if echo:
            say("verifying %s as the Robotarium does on the warm verification testbed (%s, pid %d): %s"
                % (shown(script), VERIFY_NAMESPACE, warm["owner"]["pid"], how))
        # busy: a testbed of its own at once, rather than waiting in line
        code, run, run_dir = run_script(request(dataclasses.replace(options, wait=False), warm_testbed=True,
                                                namespace=VERIFY_NAMESPACE))
        failure = warm_testbed_failure(code, run)
        if failure is None:
            return _verdict(code, run, run_dir, config, robots, duration)
        say("the warm verification testbed %s: verifying %s on a testbed of its own" % (failure, shown(script)))
    elif echo:
        say("verifying %s as the Robotarium does: %s" % (shown(script), how))
    code, run, run_dir = run_script(request(options, own_testbed=True, namespace="/robotarium_verify_%d" % os.getpid()))
    return _verdict(code, run, run_dir, config, robots, duration)


def _verdict(code, run, run_dir, config, robots, duration):
    """verify_script's verdict on a verification run (run_script's exit code, record and folder)."""
    if run is None:
        raise verification.NoVerdict("the run did not start (exit code %d)" % code,
                                     code if code != outcomes.USAGE_ERROR else outcomes.TESTBED_PROBLEM)
    if run.outcome == "interrupted":
        raise verification.NoVerdict("the verification was interrupted", code or 130)
    if run.outcome in ("testbed_lost", "client_lost", "unfinished", "testbed_incomplete"):
        raise verification.NoVerdict("the testbed failed (%s); see the testbed's logs in log/testbed/ and run verify "
                                     "again" % (run.detail or run.outcome), outcomes.TESTBED_PROBLEM)
    report = run.last.report if run.last else ""
    return verification.Verdict(verification.judge(run, config, robots, duration), run, report, run_dir, config,
                                robots, duration)
