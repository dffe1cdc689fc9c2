"""Running a script for `run`, `verify` and `demo`: a testbed found or started, the script in a
process of its own (robotarium_cli.runner), its results collected into its run folder."""
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
from robotarium_bringup.testbed import (
    RECORDING_LOOKUP_WAIT,
    LocalTestbed,
    announced_recording,
    nodes_seen,
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
from robotarium_client import session
from robotarium_core import lifeline, outcomes, script_box
from robotarium_core.topics import namespace_from_environment as namespace

# -- runs whose ./robotarium run was killed -------------------------------------------------------------
#
# Each run keeps its scratch folder (the script's log as it runs, the runner's run.json and
# started.json, pending.json: what this command would need to finish the run folder) in
# <results dir>/.unfinished/ until its run folder is finished. Should ./robotarium run be killed
# outright (SIGKILL, or killed while it made the results), the scratch folder stays behind and the
# next ./robotarium run, status or report finishes that run's folder as run would have:
# the script's process, orphaned, ends its experiment and writes how (runner.py), the testbed closes the
# recording, and finish_unfinished makes the report, the video and the page from it.

UNFINISHED = ".unfinished"


def new_work_folder(results_dir):
    """The scratch folder of one run: in results_dir/.unfinished/, or (the portal's job box, which
    keeps its own books) a temporary folder."""
    if script_box.VARIABLE in os.environ:
        return tempfile.mkdtemp(prefix="robotarium-run-")
    parent = os.path.join(results_dir, UNFINISHED)
    os.makedirs(parent, exist_ok=True)
    return tempfile.mkdtemp(prefix="run-", dir=parent)


def local_testbeds_process(pid):
    from robotarium_bringup import local_testbeds
    return local_testbeds.process(pid)


def runner_started_file():
    from robotarium_cli.runner import STARTED
    return STARTED


def _read_json(path):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def _write_pending(work, pending, name="pending.json"):
    path = os.path.join(work, name)
    with open(path + ".tmp", "w") as f:
        json.dump(pending, f)
    os.replace(path + ".tmp", path)


def finish_unfinished(results_dir=None, quiet=False):
    """Finish the run folder of every run in results_dir (default results/) whose ./robotarium run
    was killed before it finished it; says so, one line each. Returns the folders finished."""
    from robotarium_bringup import local_testbeds
    results_dir = os.path.abspath(results_dir or os.path.join(repository_root(), "results"))
    parent = os.path.join(results_dir, UNFINISHED)
    try:
        works = sorted(os.listdir(parent))
    except OSError:
        return []
    finished = []
    for entry in works:
        work = os.path.join(parent, entry)
        claimed = _read_json(os.path.join(work, "claimed.json"))
        if claimed is not None and "by" in claimed and not local_testbeds.running(claimed["by"]):
            # its finisher was killed in turn: hand the run back
            os.replace(os.path.join(work, "claimed.json"), os.path.join(work, "pending.json"))
        pending = _read_json(os.path.join(work, "pending.json"))
        if pending is None:
            if claimed is None and time.time() - modified_time(work) > 60:   # run was killed before it started the script
                shutil.rmtree(work, ignore_errors=True)
            continue
        if local_testbeds.running(pending["run"]):
            continue   # its ./robotarium run is still at work
        try:   # claim it: only one command finishes a run
            os.rename(os.path.join(work, "pending.json"), os.path.join(work, "claimed.json"))
        except OSError:
            continue
        _write_pending(work, dict(pending, by=local_testbeds.process(os.getpid())), name="claimed.json")
        # The orphaned script ends its experiment and exits within moments (runner.ORPHAN_EXIT).
        deadline = time.monotonic() + 10.0
        while local_testbeds.running(pending.get("runner")) and time.monotonic() < deadline:
            time.sleep(0.1)
        cwd = pending["cwd"] if os.path.isdir(pending["cwd"]) else os.getcwd()
        try:
            _, run, run_dir = _collect_run(
                pending["script"], -signal.SIGKILL, None, None, work, os.path.join(work, "run.json"),
                os.path.join(work, "log.txt"), pending["started"], pending["started_at"], pending["before"], cwd,
                pending["bags_dir"], pending["results"], pending["results_dir"], pending["name"], pending["video"],
                quiet=True)
        except Exception as error:   # noqa: BLE001 - leave it for the next try, say why
            os.replace(os.path.join(work, "claimed.json"), os.path.join(work, "pending.json"))
            say("could not finish the folder of a run whose ./robotarium run was killed (%s); %s keeps what it left"
                % (session.describe_exception(error), work))
            continue
        finished.append(run_dir)
        if not quiet:
            say("the run of %s (%s) lost its ./robotarium run (pid %d, killed); its folder is finished now: %s"
                % (os.path.basename(pending["script"]), run.get("run_id") or "no experiment", pending["run"]["pid"],
                   shown(run_dir)))
    return finished


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
    results_dir: object = None   # None: <repository>/results
    namespace: object = None     # the testbed's namespace; None: $ROBOTARIUM_NAMESPACE or /robotarium
    echo: bool = True            # show what the script prints and where the results are (log.txt has the prints)
    # Where the safety layer changed the script's commands, judge the script as the Robotarium's
    # verification does (verify_script) and keep the verdict with the run (run.json).
    judge: bool = False


def run_script(request):
    """Run an experiment script (a RunRequest) against the testbed (starting one here if none
    answers and `local_testbed` allows it). Whatever happens, the run folder gets the log, the
    report, the results page and run.json (with the plot and the video when the run was recorded
    here); a script that cannot be compiled or imported fails before a testbed is started. SIGINT,
    SIGTERM and SIGHUP stop the script and this testbed (Interruption); the results are then made as
    for any run that did not complete.

    Returns (exit code, run.json dict or None, run folder or None).
    """
    from robotarium_core import outcomes
    script = request.script = os.path.abspath(request.script)
    if not os.path.isfile(script):
        say("no such script: %s" % script)
        return outcomes.USAGE_ERROR, None, None
    cwd = os.getcwd()
    results_dir = request.results_dir = os.path.abspath(request.results_dir or os.path.join(repository_root(), "results"))
    started_at = time.strftime("%Y-%m-%d %H:%M:%S")
    folders = [results_dir]
    if request.record and request.local_testbed:   # a testbed started here records into bags_dir
        folders.append(os.path.abspath(request.bags_dir or os.path.join(repository_root(), "bags")))
    problem = check_run_folders(folders, request.options.config_file)
    if problem is not None:
        return problem, None, None

    problem = check_script(script)
    if problem is not None:
        detail, text = problem
        print(text, end="", file=sys.stderr, flush=True)
        run = {"run_id": "", "outcome": "script_error", "detail": "the script %s; no testbed was started" % detail,
               "steps": 0, "step_calls": 0, "exit_code": outcomes.EXIT_CODES[outcomes.SCRIPT_ERROR], "runs": [],
               "script": script,
               "started": started_at, "wall_time": 0.0}
        run_dir = new_run_folder(results_dir, session.experiment_name_of(script))
        work = tempfile.mkdtemp(prefix="robotarium-run-")
        log_path = os.path.join(work, "log.txt")
        with open(log_path, "w") as log:
            log.write(text)
        finish_run_folder(run_dir, run, script, log_path, [], cwd)
        shutil.rmtree(work, ignore_errors=True)
        write_unrecorded_results(run_dir, run)
        print_summary(run_dir, run, cwd)
        return run["exit_code"], run, run_dir

    interruption = Interruption()
    try:
        return _run_script(request, interruption, started_at)
    finally:
        interruption.restore()


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
    from robotarium_bringup import local_testbeds
    here = local_testbeds.matching(local_testbeds.find(), ns, local_testbeds.domain_id())
    running_here = any(any(name.startswith(("simulator", "arena")) for name in t["nodes"]) for t in here)
    if running_here:   # ./robotarium up (or ros2 run) on this machine: it answers
        if testbed_answers(ns, timeout=LOCAL_PROBE_WAIT):
            return None
    testbed = LocalTestbed(record=record, bags_dir=bags_dir, config_file=config_file, looked=True).start(gated=True)
    try:
        if not running_here and not discovery_is_local() and testbed_answers(ns, timeout=PROBE_WAIT):
            testbed.cancel()
            return None
    except BaseException:
        testbed.cancel()
        raise
    return testbed.open()


def _run_script(request, interruption, started_at):
    from robotarium_core import outcomes
    script, record, bags_dir, results, video, results_dir = (
        request.script, request.record, request.bags_dir, request.results, request.video, request.results_dir)
    config_file = request.options.config_file
    ns = request.namespace or namespace()
    testbed = None
    name = session.experiment_name_of(script)
    # Without local_testbed a testbed is known to be up (or coming up): wait for it, never start one.
    if request.own_testbed:
        if interruption.signum is None:
            testbed = LocalTestbed(record=record, ns=ns, bags_dir=bags_dir, config_file=config_file,
                                   looked=True).start()
    elif not request.local_testbed:
        if testbed_answers(ns, timeout=60.0):
            if request.options.wait:   # (--no-wait: its one line says what happened)
                say("using the testbed that answers in %s" % ns)
        else:
            say("no testbed answers in %s on ROS_DOMAIN_ID %s (--no-local-testbed forbids starting one); "
                "start it with ./robotarium up" % (ns, os.environ.get("ROS_DOMAIN_ID", "0")))
            seen = nodes_seen()
            say("the DDS graph of this domain shows %s" % (", ".join(seen) if seen else
                                                          "no node at all: discovery does not reach this process"))
            return outcomes.EXIT_CODES[outcomes.TESTBED_LOST], None, None
    elif interruption.signum is None:
        testbed = find_or_start_testbed(ns, record, bags_dir, config_file)
        if testbed is None and request.options.wait:   # (--no-wait: its one line says what happened)
            say("using the testbed that answers in %s" % ns)
        else:
            say("no testbed answers in %s: started one on this machine for this run (logs in %s)"
                % (ns, shown(testbed.log_dir)))
    work = new_work_folder(results_dir)
    info_path = os.path.join(work, "run.json")
    log_path = os.path.join(work, "log.txt")
    # The testbed is up (found or started above): the script waits for it, never starts another.
    options = dataclasses.replace(request.options, local_testbed=False, namespace=ns, experiment_name=name,
                                  progress_interval=session.progress_from_environment(10.0),
                                  config_file=os.path.abspath(config_file) if config_file else None)
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        env.setdefault("MPLBACKEND", "Agg")
    # The script's lifeline: should this command be killed outright, the script stops too.
    env, pass_fds = lifeline.for_child(env)
    # In the portal's job box only the script is demoted (its account, its limits); the testbed stays the service's.
    box_options, env = script_box.popen_options(env, writable=[work])
    command = [sys.executable, "-m", "robotarium_cli.runner", options.to_json(), info_path, script,
               *request.script_args]

    cwd = os.getcwd()
    before = snapshot_files(cwd)
    started = time.time()
    code = None
    pending = {"run": local_testbeds_process(os.getpid()), "runner": None, "script": script, "cwd": cwd,
               "started": started, "started_at": started_at, "bags_dir": bags_dir, "results": results,
               "results_dir": results_dir, "name": name, "video": video, "before": before}
    _write_pending(work, pending)
    if results and record:   # made while the script runs: the results' imports
        threading.Thread(target=recording.preload_results, args=(video,), daemon=True).start()
    try:
        if interruption.signum is None:
            with open(log_path, "wb") as log:
                # A process group of its own: a terminal's Ctrl-C reaches only this command, which forwards it
                # once (a second SIGINT would cut short the script's exit handler ending its experiment).
                process = subprocess.Popen(command, cwd=cwd, env=env, pass_fds=pass_fds, process_group=0,
                                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, **box_options)
                interruption.watch(process)
                _write_pending(work, dict(pending, runner=local_testbeds_process(process.pid)))
                # the log first: it never lags what was shown
                tee(process.stdout, [log, sys.stdout.buffer] if request.echo else [log])
                code = process.wait()
    finally:
        if testbed is not None:
            testbed.begin_stop()  # the simulator ends an experiment still running; the recorder closes the bag
        interruption.restore()   # from here on (results, video) a signal acts as usual
    try:   # the results are made as soon as the bag is closed, while the nodes exit
        return _collect_run(script, code, testbed, interruption, work, info_path, log_path, started, started_at,
                            before, cwd, bags_dir, results, results_dir, name, video, quiet=not request.echo,
                            data_limit=_data_limit(config_file), ns=ns, judge=request if request.judge else None)
    finally:
        if testbed is not None:
            testbed.stop()


def _judge(request, run):
    """The Robotarium's verdict on a run whose commands the safety layer changed: the script judged
    as ./robotarium verify judges it (lockstep, its own commands, a testbed of its own), printed
    and returned as verification.verdict's document (None: no verdict, and why was said)."""
    say("the safety layer changed %d of your script's command arrays, so this run's counts are not the "
        "Robotarium's: judging the script as its verification does (lockstep, the script's own commands, a testbed "
        "of its own; ./robotarium verify)" % run["safety_interventions"])
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


def _data_limit(config_file):
    """Bytes of data files a run folder takes: run_data_limit of the configuration given (--config),
    else None (the packaged one's)."""
    if not config_file:
        return None
    from robotarium_core.config import TestbedConfig
    return TestbedConfig.load(config_file).run_data_limit * 1e6


def _collect_run(script, code, testbed, interruption, work, info_path, log_path, started, started_at, before, cwd,
                 bags_dir, results, results_dir, name, video, quiet=False, data_limit=None, ns=None, judge=None):
    """What run_script does after the script's process ended: the run folder and the results.
    interruption None: finishing the folder of a ./robotarium run that was killed (finish_unfinished).
    judge: the RunRequest, where a run the safety layer changed gets the Robotarium's verdict."""
    if code is None:
        say("interrupted (%s) before the script started%s" % (
            interruption.name, "; the testbed this run started was stopped" if testbed is not None else ""))
        shutil.rmtree(work, ignore_errors=True)
        return interruption.exit_code, None, None
    wall_time = round(time.time() - started, 3)

    died = None   # the script's process ended without saying how its run ended (killed outright)
    try:
        with open(info_path) as f:
            run = json.load(f)
    except (OSError, ValueError):
        if interruption is None:   # finishing the folder of a ./robotarium run that was killed (finish_unfinished)
            died, exit_code = "./robotarium run was killed", 128 + signal.SIGKILL
        elif interruption.signum is not None:
            died, exit_code = "interrupted by %s and killed" % interruption.name, interruption.exit_code
        elif code < 0:
            died, exit_code = "killed by %s" % signal.Signals(-code).name, 128 - code
        else:
            died, exit_code = "exit code %d" % code, code or 1
        # What the script's Robotarium said when its experiment started: the run, its recording.
        started_info = _read_json(os.path.join(work, runner_started_file()))
        run = {"outcome": "interrupted" if died.startswith(("./", "interrupted", "killed")) else "script_error",
               "detail": ("%s, and the script's process ended before it could say how its run ended" % died
                          if interruption is None else
                          "the script's process ended (%s) before it could end its experiment" % died),
               "step_calls": None, "exit_code": exit_code, "runs": [started_info] if started_info else []}
    if interruption is not None and interruption.signum is not None:
        say("interrupted (%s): the script was stopped%s" % (
            interruption.name, " and the testbed this run started was stopped" if testbed is not None else ""))
    info = run["runs"][-1] if run["runs"] else {}
    # The run is its (last) experiment: its keys at the top, how the script's run ended over them.
    run = dict({k: v for k, v in info.items() if k != "report"}, **run)
    run.update(run_id=info.get("run_id", ""), script=script, started=started_at, wall_time=wall_time)
    run.setdefault("steps", 0)
    if run.get("outcome") == outcomes.NAMES[outcomes.TESTBED_BUSY]:
        # Nothing ran (--no-wait on a busy testbed): the script's process said so in one line, and a run
        # that never ran gets no folder.
        shutil.rmtree(work, ignore_errors=True)
        return run["exit_code"], run, None
    saved = [p for p, mtime in snapshot_files(cwd).items() if before.get(p) != mtime and mtime / 1e9 >= started - 1]

    run_dir = info.get("recording") or ""
    if info.get("run_id") and not run_dir:
        # A very short run can end before the recorder's announcement of its folder arrived.
        guess = os.path.join(bags_dir or os.path.join(repository_root(), "bags"), info["run_id"])
        run_dir = guess if os.path.isdir(guess) else ""
        if not run_dir and results and run.get("outcome") != outcomes.NAMES[outcomes.COMPLETED]:
            # Killed, or the testbed lost, before its client heard the announcement (a busy recorder
            # opens the bag a few steps late, after the client's "running"): ask the recorder.
            if not quiet:
                say("asking the testbed's recorder where run %s is recorded (up to %.0f s)"
                    % (info["run_id"], RECORDING_LOOKUP_WAIT))
            run_dir = announced_recording(info["run_id"], ns or namespace())
    recorded = bool(run_dir) and os.path.isdir(run_dir) and results
    bag_dir = run_dir if recorded else ""
    stopped = outcomes.recording_stopped(run)
    if stopped and run["exit_code"] == 0:   # completed, but its recording is not: not a success (README)
        run["exit_code"] = outcomes.EXIT_CODES[outcomes.TESTBED_LOST]
    # The recorder could not write (a full disk): the bag's disk takes nothing more, so the run's
    # folder is results/<run id>/, with the results of what the bag holds.
    write_error = stopped and info.get("recording_stopped_because") != outcomes.RECORDER_GONE
    if recorded and stopped:
        # Nothing will close the bag (its recorder is gone, or stopped writing it): make its metadata
        # agree with its file where its disk allows; the step it stopped at is the last it holds.
        if not write_error:   # (a recorder that could not write tidied the bag itself, as far as its disk let it)
            if testbed is not None:
                testbed.stop()
            try:
                recording.recover_bag(bag_dir)
            except OSError as error:
                say("could not tidy the recording in %s (%s); readers scan it as it is" % (bag_dir, error.strerror))
        try:
            steps = recording.Bag(bag_dir).poses().steps
        except Exception:   # noqa: BLE001 - nothing readable: the client's step stands
            steps = ()
        if len(steps):
            run["recording_stopped_at_step"] = int(steps[-1])
            stopped = outcomes.recording_stopped(run)
        if not quiet:
            say("%s: %s holds the run up to there" % (stopped, bag_dir))
    if not recorded or write_error:
        # Not recorded here (another machine's testbed, no recorder, or no experiment at all):
        # keep the local outputs in results/<run id>/.
        run_dir = (os.path.join(results_dir, info["run_id"]) if info.get("run_id")
                   else new_run_folder(results_dir, name))
        os.makedirs(run_dir, exist_ok=True)
    if judge is not None and run.get("safety_interventions") and run.get("outcome") == outcomes.NAMES[outcomes.COMPLETED]:
        run["verdict"] = _judge(judge, run)
    finish_run_folder(run_dir, run, script, log_path, saved, cwd, data_limit)

    if recorded:
        if not stopped:
            # A lost testbed may never close the bag: then take what is on disk after a short wait. A
            # script killed outright has its experiment ended by the testbed (client_lease) or by
            # this command's stopping of its own testbed.
            timeout = 15.0 if info.get("ended") or died or interruption is None else 3.0
            if testbed is None:
                wait_until_recorded(run_dir, timeout, quiet=quiet)
            elif not wait_until_recorded(run_dir, timeout, quiet=True):
                testbed.stop()   # its recorder closes the bag as it stops (or is gone)
                wait_until_recorded(run_dir, timeout=1.0)
        try:
            if died:   # the testbed's steps, as the report counts them (a killed script could not say)
                recorded_steps = recording.Bag(bag_dir).poses().steps
                run["steps"] = int(recorded_steps[-1]) if len(recorded_steps) else 0
                with open(os.path.join(run_dir, "run.json"), "w") as f:
                    json.dump(run, f, indent=2)
            recording.write_results(bag_dir, progress=not quiet, video=video, run=run, out_dir=run_dir)
        except Exception as error:   # noqa: BLE001 - say so, keep the folder
            say("could not make the results from the recording (%s); see %s"
                % (session.describe_exception(error), run_dir))
            write_unrecorded_results(run_dir, run, info.get("report", ""))
    else:
        write_unrecorded_results(run_dir, run, info.get("report", ""))
    shutil.rmtree(work, ignore_errors=True)   # last: a run whose folder is finished is no longer pending
    if not quiet:
        print_summary(run_dir, run, cwd)
    return run["exit_code"], run, run_dir


def verify_script(script, script_args=(), config_file=None, robots=None, duration=None, rps_api=None, record=True,
                  bags_dir=None, results_dir=None, echo=True):
    """Judge `script` as the Robotarium's verification does: the static rules, then a lockstep run on
    a testbed of its own (a namespace no other testbed uses) with the safety node auditing. Returns
    a verification.Verdict; raises verification.NoVerdict where the run could not judge it."""
    from robotarium_core.config import DEFAULT, TestbedConfig
    config = TestbedConfig.load(config_file) if config_file else DEFAULT
    rules = verification.static_rules(script, config)
    if rules:
        return verification.Verdict(rules, {}, "", None, config, robots, duration)
    if echo:
        say("verifying %s as the Robotarium does: lockstep, safety node auditing (the script's own commands go "
            "through and every collision counts)" % shown(script))
    options = session.RunOptions(real_time=False, config_file=config_file, audit=True,
                                 rps_api=rps_api or session.rps_api_from_environment())
    code, run, run_dir = run_script(RunRequest(
        script, tuple(script_args), options, record=record, bags_dir=bags_dir, video=False, own_testbed=True,
        results_dir=results_dir, namespace="/robotarium_verify_%d" % os.getpid(), echo=echo))
    if run is None:
        raise verification.NoVerdict("the run did not start (exit code %d)" % code,
                                     code if code != outcomes.USAGE_ERROR else outcomes.TESTBED_PROBLEM)
    if run["outcome"] == "interrupted":
        raise verification.NoVerdict("the verification was interrupted", code or 130)
    if run["outcome"] in ("testbed_lost", "client_lost", "unfinished", "testbed_incomplete"):
        raise verification.NoVerdict("the testbed failed (%s); see the testbed's logs in log/testbed/ and run verify "
                                     "again" % run.get("detail", run["outcome"]), outcomes.TESTBED_PROBLEM)
    report = (run.get("runs") or [{}])[-1].get("report", "")
    return verification.Verdict(verification.judge(run, config, robots, duration), run, report, run_dir, config,
                                robots, duration)
