"""The Python side of ./robotarium: up, run, verify, demo, status, stop, end, replay, report.

./robotarium (bash) makes the environment and then calls `python -m robotarium_client.cli CMD`.

Signals: SIGINT, SIGTERM and SIGHUP (Ctrl-C, `kill`, `timeout`, a closed terminal) to `run`, `demo`
or `up` stop the script if it still runs (Interruption), end its experiment, stop the testbed
nodes the command started and close the recording. SIGKILL cannot be caught: then the script and
the nodes notice through their lifeline (robotarium_core.lifeline) that the command is gone and do
the same by themselves.
"""
import argparse
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
from robotarium_client import session
from robotarium_client.testbed import (
    RECORDING_LOOKUP_WAIT,
    LocalTestbed,
    announced_recording,
    namespace,
    repository_root,
    running_testbed,
    testbed_answers,
)
from robotarium_core import lifeline, model, outcomes, script_box

DEMO_SCRIPT = os.path.join("examples", "barrier_certificates.py")  # 8 robots swap places through the middle
# Folders never searched for data files a script saved.
SKIP_DIRS = {".git", ".venv", ".venv-reference", "build", "install", "log", "bags", "results", "__pycache__",
             "node_modules"}


# Seconds a script has, after the first signal, to end its experiment before it is killed.
SCRIPT_GRACE = 5.0
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def seed_type(text):
    """--seed: a whole number 0 .. 2**32 - 1 (the StartExperiment request's uint32)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError("must be a whole number; received %r" % text) from None
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError("must be between 0 and %d; received %d" % (2**32 - 1, value))
    return value


def say(text):
    print("[robotarium] %s" % text, file=sys.stderr, flush=True)


def _signal_group(process, sig):
    """Signal the process group of a child started with process_group=0, unless it was reaped."""
    if process.poll() is None:
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            pass


class Interruption:
    """SIGINT, SIGTERM and SIGHUP, caught while installed: the first is remembered and forwarded
    to the script (watch()), once (the runner then ends its experiment saying how); a script
    still running SCRIPT_GRACE seconds later, or at a second signal, is killed. The command then
    stops what it started as after any run."""

    def __init__(self):
        self.signum = None
        self.count = 0
        self.script = None
        self._timer = None
        self._previous = {sig: signal.signal(sig, self._on_signal) for sig in STOP_SIGNALS}

    @property
    def name(self):
        return signal.Signals(self.signum).name if self.signum else ""

    @property
    def exit_code(self):
        """128 + the signal's number, as a shell reports a command a signal stopped (130: Ctrl-C)."""
        return 128 + self.signum

    def _on_signal(self, signum, frame):
        self.count += 1
        if self.signum is None:
            self.signum = signum
        self._forward()

    def watch(self, process):
        """Forward signals to this script (started with process_group=0)."""
        self.script = process
        if self.signum is not None:
            self._forward()

    def _forward(self):
        process = self.script
        if process is None or process.poll() is not None:
            return
        if self.count > 1:
            _signal_group(process, signal.SIGKILL)
        elif self._timer is None:
            _signal_group(process, self.signum)   # the runner names it in the report (SIGINT: Ctrl-C)
            self._timer = threading.Timer(SCRIPT_GRACE, _signal_group, (process, signal.SIGKILL))
            self._timer.daemon = True
            self._timer.start()

    def restore(self):
        if self._timer is not None:
            self._timer.cancel()
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)


def cmd_up(args):
    from robotarium_client import local_testbeds
    from robotarium_core import claim
    from robotarium_core.config import DEFAULT
    ns = namespace()
    domain = os.environ.get("ROS_DOMAIN_ID", "0")
    # One testbed per namespace: name the one that runs. Where discovery reaches this machine only,
    # the process table knows it at once (a look on the domain backs it up for a claim_wait); else
    # it is looked for on the domain, as run does (discovery can wait for the next announcement).
    running = local_testbeds.running_here(ns, local_testbeds.domain_id()) if discovery_is_local() else None
    if running is None:
        running = running_testbed(ns, timeout=DEFAULT.claim_wait if discovery_is_local() else PROBE_WAIT)
    if running is not None:
        say(claim.refusal(running, ns, domain))
        return claim.REFUSED
    view = None
    if args.view:   # first: a port in use is said before any node starts
        view = recording.ViewProcess(ns, args.view_host, args.view_port)
        if not view.wait_ready():
            view.stop()
            say("the Foxglove view could not start (its message is above); no testbed was started")
            return 1
    interruption = Interruption()
    testbed = LocalTestbed(record=not args.no_record, quiet=False, bags_dir=args.bags_dir,
                           config_file=args.config, hardware=args.hardware, looked=True).start()
    code = 0
    try:
        say("testbed up in namespace %s on ROS_DOMAIN_ID %s (simulator%s, safety%s%s). It runs as long as this "
            "command does: Ctrl-C (or SIGTERM, SIGHUP) stops it." % (
                ns, os.environ.get("ROS_DOMAIN_ID", "0"), " hardware-like" if args.hardware else "",
                "" if args.no_record else ", recorder", ", Foxglove view" if view else ""))
        while interruption.signum is None:
            failed = testbed.failed()
            if claim.REFUSED in failed.values():   # one started at the same moment is older: it stays
                say("an older testbed runs in %s on ROS_DOMAIN_ID %s (named above); stopping this one"
                    % (ns, domain))
                code = claim.REFUSED
                break
            if failed:
                say("node(s) exited: %s; stopping the testbed" % failed)
                break
            if view is not None and view.failed():
                say("the Foxglove view exited (its message is above); the testbed runs on")
                view = None
            time.sleep(0.2)
    finally:
        if view is not None:
            view.stop()
        testbed.stop()   # a running experiment is ended and its recording closed
        interruption.restore()
    say("testbed stopped" + (" (%s)" % interruption.name if interruption.signum else ""))
    return code


def _snapshot(directory):
    """Paths and modification times of the files under `directory` (the script's data files)."""
    seen = {}
    for root, dirs, files in os.walk(directory):
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS and not d.startswith(".")]
        for name in files:
            path = os.path.join(root, name)
            try:
                seen[path] = os.stat(path).st_mtime_ns
            except OSError:
                pass
    return seen


def _shown(path):
    """A path as short as it is clear: relative when it lies below the working folder."""
    relative = os.path.relpath(path)
    return path if relative.startswith("..") else relative


def _tee(stream, sinks):
    sinks = list(sinks)
    for line in iter(stream.readline, b""):
        for sink in list(sinks):
            try:
                sink.write(line)
                sink.flush()
            except OSError:   # our terminal is gone (SIGHUP): keep the log, keep reading
                sinks.remove(sink)


def wait_until_recorded(run_dir, timeout=15.0, quiet=False):
    """The recorder closes a run's bag shortly after the run ended (it keeps late messages for a
    moment); results made before that would miss the last chunk. Wait for metadata.yaml to say
    the bag is complete."""
    import yaml
    path = os.path.join(run_dir, "metadata.yaml")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with open(path) as f:
                info = yaml.safe_load(f)["rosbag2_bagfile_information"]
            if str(info.get("custom_data", {}).get("complete")) == "true":
                return True
        except (OSError, KeyError, TypeError, yaml.YAMLError):
            pass  # not written yet, or being replaced
        time.sleep(0.02)
    if not quiet:
        say("the recorder has not closed %s yet; results are made from what is recorded so far" % run_dir)
    return False


# -- before a testbed is started: can the script run at all? ---------------------------------------

def _close_module_name(name):
    """An importable module whose dotted name is close to `name` (an import typo: `nump` -> `numpy`,
    `rps.utilities.misk` -> `rps.utilities.misc`), or None. The first part that is missing is
    compared with its siblings: the top-level modules, or the submodules of the package above it."""
    import difflib
    import importlib.util
    import pkgutil
    parts = name.split(".")
    for depth in range(len(parts)):
        try:
            if importlib.util.find_spec(".".join(parts[:depth + 1])) is not None:
                continue
        except (ImportError, ValueError):
            pass
        if depth == 0:
            siblings = set(sys.builtin_module_names) | {m.name for m in pkgutil.iter_modules()}
        else:
            parent = importlib.util.find_spec(".".join(parts[:depth]))
            locations = parent.submodule_search_locations if parent is not None else None
            if not locations:
                return None   # the part above is a module, not a package: nothing to compare with
            siblings = {m.name for m in pkgutil.iter_modules(locations)}
        match = difflib.get_close_matches(parts[depth], sorted(siblings), n=1, cutoff=0.75)
        return ".".join(parts[:depth] + [match[0]] + parts[depth + 1:]) if match else None
    return None


def check_script(script):
    """Compile the script and find the modules its opening import statements name, as `python
    SCRIPT` would meet them (the script's folder first on sys.path), without running it. Returns
    None, or (detail, message): a syntax error or an import typo fails here, before a testbed is
    started, with the message python would print."""
    import ast
    import importlib.util

    from robotarium_client.verify import COMPILE_ERRORS, compile_script
    try:
        source, tree = compile_script(script)
    except COMPILE_ERRORS as error:
        import traceback
        text = "".join(traceback.format_exception_only(type(error), error))
        where = " (line %d of %s)" % (error.lineno, os.path.basename(script)) if getattr(error, "lineno", None) else ""
        what = "%s: %s" % (type(error).__name__, error.msg) if isinstance(error, SyntaxError) else \
            session.describe_exception(error)
        return "could not be compiled: %s%s" % (what, where), text
    lines = source.splitlines()
    sys.path.insert(0, os.path.dirname(script))
    try:
        # The imports at the top of the script, before its first other statement: those in functions
        # or try blocks may be optional, and a later one may follow a change to sys.path.
        for node in tree.body:
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module] if node.level == 0 and node.module else []
            elif isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
                continue   # the docstring
            else:
                break
            if script_box.VARIABLE in os.environ:
                # Boxed (the portal): find_spec("pkg.mod") would import pkg, the user's code, as the service.
                names = [name.split(".")[0] for name in names]
            for name in names:
                try:
                    found = importlib.util.find_spec(name) is not None
                    error = "No module named %r" % name
                except ModuleNotFoundError as missing:
                    found, error = False, str(missing)
                except Exception as failed:   # noqa: BLE001 - a parent package that fails to import
                    found, error = False, session.describe_exception(failed)
                if not found:
                    close = _close_module_name(name) if "No module named" in error else None
                    hint = "Did you mean %r?" % close if close and close != name else ""
                    text = '  File "%s", line %d\n    %s\nModuleNotFoundError: %s%s\n' % (
                        script, node.lineno, lines[node.lineno - 1].strip(), error, " " + hint if hint else "")
                    return ("could not import %s: ModuleNotFoundError: %s (line %d of %s%s)"
                            % (name, error, node.lineno, os.path.basename(script),
                               "; " + hint[0].lower() + hint[1:] if hint else "")), text
    finally:
        sys.path.remove(os.path.dirname(script))
    return None


# -- the run folder -----------------------------------------------------------------------------------

HINTS = {
    "script_error": "the traceback above (also in log.txt) shows where the script failed; fix it and run it again",
    "interrupted": "the experiment was ended where it was; the results cover the steps that ran",
    "no_end": "end the script with r.call_at_scripts_end(): the Robotarium needs it to finish an experiment",
    "testbed_lost": ("the testbed stopped answering; when ./robotarium started it, its node logs are in "
                     "log/testbed/, otherwise look at the machine running ./robotarium up"),
    "client_lost": "the testbed ended the experiment because it stopped hearing from the script",
    "time_limit": "the experiment reached its time limit",
    "ended_by_unsent_request": ("another process holding the run's token (copied off the wire: without SROS2 it is no "
                                "secret) ended the experiment: stop that process (./robotarium status lists what runs "
                                "on the domain) or use DDS Security (sros2/README.md), then run the script again"),
    "testbed_busy": ("the testbed was busy with another experiment (nothing ran): run again without --no-wait to wait in "
                     "line for it; ./robotarium status shows who holds it"),
    "testbed_incomplete": ("the testbed has no safety node (nothing ran): start one in its namespace, or stop the "
                           "testbed and start a whole one with ./robotarium up; ./robotarium status shows what runs"),
}


def results_folder_problem(folder, min_free_mb):
    """Why a run's folder cannot go into `folder` (created if missing): not writable, or less than
    `min_free_mb` MB free; None when it can. Checked with a real write, so a read-only mount, a full
    disk and missing permissions are all found before anything runs."""
    try:
        os.makedirs(folder, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".robotarium-write-check-") as probe:
            probe.write(b"\0" * 4096)
            probe.flush()
            os.fsync(probe.fileno())
        free = shutil.disk_usage(folder).free
    except OSError as error:
        import errno
        if error.errno in (errno.ENOSPC, errno.EDQUOT):
            return "%s is on a full disk (%s)" % (folder, error.strerror)
        return "%s is not writable (%s)" % (folder, error.strerror or error)
    if free < min_free_mb * 1e6:
        return "%s has %s free, less than results_min_free (%s)" % (folder, _megabytes(free), _megabytes(min_free_mb * 1e6))
    return None


def check_run_folders(folders, config_file=None):
    """One line and USAGE_ERROR when a run's folder could not be written (results_folder_problem),
    else None: said before a testbed starts or a robot moves, not as a traceback after the run."""
    from robotarium_core import outcomes
    from robotarium_core.config import DEFAULT, ConfigError, TestbedConfig
    try:
        min_free = (TestbedConfig.load(config_file) if config_file else DEFAULT).results_min_free
    except (OSError, ConfigError):
        min_free = DEFAULT.results_min_free   # (the run itself says what is wrong with the file)
    for folder in folders:
        problem = results_folder_problem(folder, min_free)
        if problem is not None:
            say("cannot run: the run's folder would go where it cannot be written: %s. Free some space, or choose "
                "another folder (--results-dir, --bags-dir)." % problem)
            return outcomes.USAGE_ERROR
    return None


# A run the testbed ended (it was stopped, or an operator's end --force: outcomes.ENDED_BY_TESTBED in its detail).
HINT_ENDED_BY_TESTBED = ("the testbed ended the experiment (it was stopped, or an operator ran ./robotarium end "
                         "--force); the results cover the steps that ran; ./robotarium status shows whether a testbed "
                         "answers now")


def new_run_folder(results_dir, name):
    """results/<name>_<YYYYmmdd-HHMMSS>[_k]: a fresh folder for a run that has no recording here."""
    os.makedirs(results_dir, exist_ok=True)
    base = os.path.join(results_dir, "%s_%s" % (name, time.strftime("%Y%m%d-%H%M%S")))
    for k in range(1000):
        path = base if k == 0 else "%s_%d" % (base, k)
        try:
            os.makedirs(path)
            return path
        except FileExistsError:
            continue
    raise RuntimeError("no free folder name for %s" % base)


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
    from robotarium_client import local_testbeds
    return local_testbeds.process(pid)


def runner_started_file():
    from robotarium_client.runner import STARTED
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
    from robotarium_client import local_testbeds
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
            if claimed is None and time.time() - _mtime(work) > 60:   # run was killed before it started the script
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
                   _shown(run_dir)))
    return finished


def _mtime(path):
    try:
        return os.stat(path).st_mtime
    except OSError:
        return time.time()


def write_unrecorded_results(run_dir, run, testbed_report=""):
    """report.txt and index.html for a run with no recording here (it never started, or it was
    recorded on another machine): how it ended, and the testbed's debug report if there is one."""
    from robotarium_core import outcomes
    outcome = {name: value for value, name in outcomes.NAMES.items()}.get(run["outcome"], outcomes.UNFINISHED)
    lines = [outcomes.first_line(outcome, run.get("detail", "")), ""]
    if testbed_report:
        lines += [testbed_report.rstrip("\n"), "", "(the run was recorded on the testbed's machine, not here)"]
    else:
        lines.append("No experiment ran on a testbed, so there is no debug report.")
    notes = outcomes.run_notes(run)
    if notes:
        lines += [""] + notes
    with open(os.path.join(run_dir, "report.txt"), "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    recording.write_page(run_dir, run=run)


def finish_run_folder(run_dir, run, script, log_path, saved, cwd, data_limit=None):
    """Copy the script, the log and the data files into the run folder and write run.json.

    The data files are capped at `data_limit` bytes (default: the configuration's run_data_limit):
    the newest first, each that fits; the others are left out, each named in run.json's
    data_not_saved with why, and in one line here (the report says so too: outcomes.run_notes)."""
    from robotarium_core.config import DEFAULT
    shutil.copy2(script, os.path.join(run_dir, os.path.basename(script)))
    shutil.copy2(log_path, os.path.join(run_dir, "log.txt"))
    limit = DEFAULT.run_data_limit * 1e6 if data_limit is None else data_limit
    if saved:
        data_dir = os.path.join(run_dir, "data")
        os.makedirs(data_dir, exist_ok=True)
        copied, left_out = 0, []

        def newest_first(path):
            try:
                return -os.stat(path).st_mtime_ns
            except OSError:
                return 0
        for path in sorted(saved, key=newest_first):
            name = os.path.relpath(path, cwd).replace(os.sep, "__")
            try:
                size = os.stat(path).st_size
                if copied + size > limit:
                    left_out.append((name, size))
                    run.setdefault("data_not_saved", {})[name] = (
                        "left out: %s over the run folder's limit for data files (run_data_limit %s)"
                        % (_megabytes(size), _megabytes(limit)))
                    continue
                shutil.copy2(path, os.path.join(data_dir, name))
                copied += size
            except OSError as error:   # gone meanwhile (a job box removes what broke its disk quota) or unreadable
                run.setdefault("data_not_saved", {})[name] = error.strerror or str(error)
                print("[robotarium] the data file %s was not saved: %s" % (name, error.strerror or error), flush=True)
        if left_out:
            print("[robotarium] %d data file(s) of %s left out of the run folder (run_data_limit %s, the newest kept): %s"
                  % (len(left_out), _megabytes(sum(size for _, size in left_out)), _megabytes(limit),
                     ", ".join(name for name, _ in left_out)), flush=True)
    with open(os.path.join(run_dir, "run.json"), "w") as f:
        json.dump(run, f, indent=2)


def _megabytes(size):
    return "%.3g MB" % (size / 1e6)


def print_summary(run_dir, run, cwd):
    """The closing lines: how the run ended, a hint for a failure, and (last) where everything is."""
    with open(os.path.join(run_dir, "report.txt"), encoding="utf-8") as f:
        first = f.readline().strip()
    say(first)
    if "no testbed was started" in run.get("detail", ""):
        say("hint: fix the line named above and run it again (nothing ran)")
    elif run["outcome"] == "interrupted" and outcomes.ENDED_BY_TESTBED in run.get("detail", ""):
        say("hint: " + HINT_ENDED_BY_TESTBED)
    elif run["outcome"] != "completed" and run["outcome"] in HINTS:
        say("hint: " + HINTS[run["outcome"]])
    elif outcomes.recording_stopped(run):
        say("the experiment completed, but %s: its recording is incomplete (exit code %d)"
            % (outcomes.recording_stopped(run), run["exit_code"]))
    elif run.get("recording_lost_poses"):
        say("the experiment completed, but %s (exit code %d)" % (outcomes.lost_poses(
            run["recording_lost_poses"], run["recording_first_lost_step"]), run["exit_code"]))
    elif run["exit_code"]:   # completed, and then the script failed or was stopped
        say("the experiment completed, %s (exit code %d)" % (run["detail"], run["exit_code"]))
    relative = os.path.relpath(run_dir, cwd)
    shown = run_dir if relative.startswith("..") else relative
    say("files: " + ", ".join(sorted(os.listdir(run_dir))))
    say("results in %s (open %s in a browser)" % (shown, os.path.join(shown, "index.html")))


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
    from robotarium_client import local_testbeds
    here = local_testbeds.matching(local_testbeds.find(), ns, local_testbeds.domain_id())
    running_here = any(any(name.startswith("simulator") for name in t["nodes"]) for t in here)
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
    ns = namespace()
    testbed = None
    name = session.experiment_name_of(script)
    # Without local_testbed a testbed is known to be up (or coming up): wait for it, never start one.
    if request.own_testbed:
        if interruption.signum is None:
            testbed = LocalTestbed(record=record, bags_dir=bags_dir, config_file=config_file, looked=True).start()
    elif not request.local_testbed:
        if testbed_answers(ns, timeout=60.0):
            say("using the testbed that answers in %s" % ns)
        else:
            say("no testbed answers in %s on ROS_DOMAIN_ID %s (--no-local-testbed forbids starting one); "
                "start it with ./robotarium up" % (ns, os.environ.get("ROS_DOMAIN_ID", "0")))
            return outcomes.EXIT_CODES[outcomes.TESTBED_LOST], None, None
    elif interruption.signum is None:
        testbed = find_or_start_testbed(ns, record, bags_dir, config_file)
        if testbed is None:
            say("using the testbed that answers in %s" % ns)
        else:
            say("no testbed answers in %s: started one on this machine for this run (logs in %s)"
                % (ns, _shown(testbed.log_dir)))
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
    command = [sys.executable, "-m", "robotarium_client.runner", options.to_json(), info_path, script,
               *request.script_args]

    cwd = os.getcwd()
    before = _snapshot(cwd)
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
                _tee(process.stdout, [log, sys.stdout.buffer])   # the log first: it never lags what was shown
                code = process.wait()
    finally:
        if testbed is not None:
            testbed.begin_stop()  # the simulator ends an experiment still running; the recorder closes the bag
        interruption.restore()   # from here on (results, video) a signal acts as usual
    try:   # the results are made as soon as the bag is closed, while the nodes exit
        return _collect_run(script, code, testbed, interruption, work, info_path, log_path, started, started_at,
                            before, cwd, bags_dir, results, results_dir, name, video,
                            data_limit=_data_limit(config_file))
    finally:
        if testbed is not None:
            testbed.stop()


def _data_limit(config_file):
    """Bytes of data files a run folder takes: run_data_limit of the configuration given (--config),
    else None (the packaged one's)."""
    if not config_file:
        return None
    from robotarium_core.config import TestbedConfig
    return TestbedConfig.load(config_file).run_data_limit * 1e6


def _collect_run(script, code, testbed, interruption, work, info_path, log_path, started, started_at, before, cwd,
                 bags_dir, results, results_dir, name, video, quiet=False, data_limit=None):
    """What run_script does after the script's process ended: the run folder and the results.
    interruption None: finishing the folder of a ./robotarium run that was killed (finish_unfinished)."""
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
    saved = [p for p, mtime in _snapshot(cwd).items() if before.get(p) != mtime and mtime / 1e9 >= started - 1]

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
            run_dir = announced_recording(info["run_id"], namespace())
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


def cmd_run(args):
    finish_unfinished(args.results_dir)
    options = session.RunOptions(real_time={"lockstep": False, "real-time": True}.get(args.mode),
                                 config_file=args.config, time_limit=args.time_limit, hardware=args.hardware,
                                 seed=args.seed, rps_api=args.rps or session.rps_api_from_environment(),
                                 wait=not args.no_wait)
    code, _, _ = run_script(RunRequest(args.script, args.script_args, options, record=not args.no_record,
                                       bags_dir=args.bags_dir, video=not args.no_video,
                                       local_testbed=not args.no_local_testbed, results_dir=args.results_dir))
    return code


def cmd_verify(args):
    """./robotarium verify: see robotarium_client.verify."""
    from robotarium_client import verify
    from robotarium_core import outcomes
    from robotarium_core.config import DEFAULT, ConfigError, TestbedConfig
    try:
        config = TestbedConfig.load(args.config) if args.config else DEFAULT
    except (OSError, ConfigError) as error:
        say("cannot read the testbed configuration: %s" % error)
        return outcomes.USAGE_ERROR
    script = os.path.abspath(args.script)
    if not os.path.isfile(script):
        say("no such script: %s" % script)
        return outcomes.USAGE_ERROR
    rules = verify.static_rules(script, config)
    run, report, run_dir = {}, "", None
    if not rules:
        # A testbed of its own, in a namespace no other testbed or verification uses.
        os.environ["ROBOTARIUM_NAMESPACE"] = "/robotarium_verify_%d" % os.getpid()
        say("verifying %s as the Robotarium does: lockstep, safety node auditing (the script's own commands go "
            "through and every collision counts)" % _shown(script))
        options = session.RunOptions(real_time=False, config_file=args.config, audit=True,
                                     rps_api={"1": "guide"}.get(args.rps, args.rps) or session.rps_api_from_environment())
        code, run, run_dir = run_script(RunRequest(script, args.script_args, options, record=not args.no_record,
                                                   bags_dir=args.bags_dir, video=False, own_testbed=True,
                                                   results_dir=args.results_dir))
        if run is None:
            say("no verdict: the run did not start (exit code %d)" % code)
            return code if code != outcomes.USAGE_ERROR else outcomes.TESTBED_PROBLEM
        if run["outcome"] in ("interrupted",):
            say("no verdict: the verification was interrupted")
            return code or 130
        if run["outcome"] in ("testbed_lost", "client_lost", "unfinished", "testbed_incomplete"):
            say("no verdict: the testbed failed (%s); see the testbed's logs in log/testbed/ and run verify again"
                % run.get("detail", run["outcome"]))
            return outcomes.TESTBED_PROBLEM
        report = (run.get("runs") or [{}])[-1].get("report", "")
        rules = verify.judge(run, config, args.robots, args.duration)
    document = verify.verdict(rules, run, report, run_dir)
    if args.json:
        verify.write_json(args.json, document)
    print("\n##### VERIFICATION (the Robotarium's rules) #####")
    if report:
        print(report, end="" if report.endswith("\n") else "\n")
    for line in verify.verdict_lines(rules, run, config, args.robots, args.duration):
        print(line)
    return outcomes.VERIFY_REJECTED if rules else outcomes.VERIFY_ACCEPTED


def cmd_demo(args):
    script = os.path.join(repository_root(), DEMO_SCRIPT)
    say("demo: %s, headless, lockstep" % DEMO_SCRIPT)
    code, info, run_dir = run_script(RunRequest(script, options=session.RunOptions(real_time=False),
                                                video=not args.no_video))
    if code == 0 and run_dir:
        say("demo done: the results page, the report, trajectories.png and the video of the run are in %s"
            % run_dir)
    return code


def _since(run_id):
    """When an experiment started, from its run id (<name>_<YYYYmmdd-HHMMSS>), as a local time."""
    try:
        return time.strptime(run_id.rsplit("_", 1)[-1], "%Y%m%d-%H%M%S")
    except ValueError:
        return None


def _ago(seconds):
    seconds = int(max(0, seconds))
    if seconds < 120:
        return "%d s ago" % seconds
    if seconds < 7200:
        return "%d min ago" % (seconds // 60)
    return "%.1f h ago" % (seconds / 3600)


INCOMPLETE = "incomplete: no safety node"   # what status says of a testbed whose safety node does not answer


def _describe_status(msg, safety=True):
    """One line on what a testbed's status says, and the same as a dict (--json); safety: whether
    its safety node answers (without it nothing can run there)."""
    from robotarium_msgs.msg import TestbedStatus
    if msg is None:
        return "no testbed answers", None
    if not safety and msg.state != TestbedStatus.STATE_RUNNING:
        return ("a testbed answers, %s (no experiment can run: start one there, or ./robotarium stop it and "
                "./robotarium up a whole one)" % INCOMPLETE,
                {"running": False, "incomplete": INCOMPLETE, "last_run_id": msg.run_id,
                 "last_end_reason": msg.end_reason})
    if msg.state != TestbedStatus.STATE_RUNNING:
        last = " (the last, %s, %s)" % (msg.run_id, msg.end_reason) if msg.run_id and msg.end_reason else ""
        return ("a testbed answers: no experiment is running%s" % last,
                {"running": False, "last_run_id": msg.run_id, "last_end_reason": msg.end_reason})
    since = _since(msg.run_id)
    dropped = {name: {reason: int(getattr(counts, reason)) for reason in model.DROP_REASONS if getattr(counts, reason)}
               for name, counts in (("cmd_requested", msg.dropped_cmd_requested), ("cmd_safe", msg.dropped_cmd_safe))}
    info = {"running": True, "experiment": msg.experiment, "run_id": msg.run_id, "mode": msg.mode,
            "number_of_robots": msg.number_of_robots, "step": msg.step, "sim_time": msg.sim_time,
            "since": time.strftime("%Y-%m-%d %H:%M:%S", since) if since else None, "dropped": dropped}
    info.update(holder=msg.holder, waiting=list(msg.waiting))
    text = "experiment %s running since %s: %d robots, %s, step %d (%.1f s of testbed time)%s%s" % (
        msg.run_id, time.strftime("%H:%M:%S", since) + " (%s)" % _ago(time.time() - time.mktime(since))
        if since else "?", msg.number_of_robots, msg.mode, msg.step, msg.sim_time,
        ", held by %s" % msg.holder if msg.holder else "",
        "; waiting in line: %s" % "; ".join("%d. %s" % (k, who) for k, who in enumerate(msg.waiting, start=1))
        if msg.waiting else "")
    foreign = ["%s: %s" % (name, ", ".join("%d %s" % (n, reason) for reason, n in counts.items()))
               for name, counts in dropped.items() if counts]
    if foreign:
        text += "; arrays dropped on %s" % "; ".join(foreign)
    return text, info


def cmd_status(args):
    from robotarium_client import local_testbeds
    from robotarium_client.testbed import testbed_status
    finish_unfinished(quiet=args.json)
    found = local_testbeds.find()
    here = (local_testbeds.domain_id(), namespace())
    # only where a simulator runs can a testbed answer (a probe that gets no answer waits the whole timeout)
    targets = [(t["domain"], t["namespace"], t.get("discovery_range")) for t in found
               if t["domain"] != "?" and any(name.startswith("simulator") for name in t["nodes"])]
    # A safety node in this machine's process table is there; for the others its presence decides.
    safety = {(t["domain"], t["namespace"]): True for t in found if any(name.startswith("safety") for name in t["nodes"])}
    statuses = testbed_status(targets + [(here[0], here[1], None)], timeout=args.timeout, safety=safety)

    def described(key):
        return _describe_status(statuses.get(key), safety.get(key, True))
    if args.json:
        listed = [{k: v for k, v in t.items() if not k.startswith("_")} for t in found]
        for t in listed:
            t["experiment"] = described((t["domain"], t["namespace"]))[1]
        print(json.dumps({"local_testbeds": listed, "here": {
            "domain": here[0], "namespace": here[1], "answers": statuses.get(here) is not None,
            "experiment": described(here)[1]}}, indent=2))
        return 0
    if not found:
        print("No testbed runs on this machine.")
    else:
        print("Testbeds on this machine:")
    for t in found:
        started = ("started %s (%s)" % (time.strftime("%H:%M:%S", time.localtime(t["started"])),
                                        _ago(time.time() - t["started"])) if t["started"] else "started ?")
        owner = t.get("owner")
        if owner:
            by = "by %s (pid %d%s)" % (owner["command"], owner["pid"], "" if owner["running"] else
                                       ", gone: its nodes should follow within seconds")
        else:
            by = "not by ./robotarium (ros2 run or a launch file, or left behind by an older version)"
        print("  %s on ROS_DOMAIN_ID %s: %s %s" % (t["namespace"], t["domain"], started, by))
        print("      nodes: %s" % (", ".join("%s %d" % item for item in sorted(t["nodes"].items())) or "none left"))
        if t.get("log_dir"):
            print("      logs:  %s" % t["log_dir"])
        print("      %s" % (described((t["domain"], t["namespace"]))[0]
                             if "simulator" in t["nodes"] else "no simulator: nothing can run here"))
        print("      stop it: ./robotarium stop --domain %s --namespace %s" % (t["domain"], t["namespace"]))
    local_here = local_testbeds.matching(found, here[1], here[0])
    print("On ROS_DOMAIN_ID %s, namespace %s (this shell's, where ./robotarium run goes): %s%s" % (
        here[0], here[1], described(here)[0],
        "" if local_here or statuses.get(here) is None else " (not started on this machine)"))
    return 0


def cmd_stop(args):
    from robotarium_client import local_testbeds
    found = local_testbeds.find()
    if args.all:
        targets = found
        where = "on this machine"
    else:
        ns = "/" + args.namespace.strip("/") if args.namespace else namespace()
        domain = str(args.domain) if args.domain is not None else local_testbeds.domain_id()
        targets = local_testbeds.matching(found, ns, domain)
        where = "in %s on ROS_DOMAIN_ID %s on this machine" % (ns, domain)
    if not targets:
        say("no testbed runs %s; nothing to stop%s" % (where, " (./robotarium status lists them)" if found else ""))
        return 1
    for t in targets:
        owner = t.get("owner")
        say("stopping the testbed in %s on ROS_DOMAIN_ID %s (%s)" % (
            t["namespace"], t["domain"], "via its owner, pid %d: %s" % (owner["pid"], owner["command"])
            if owner and owner["running"] else "nodes %s" % ", ".join(str(p) for p in t["nodes"].values())))
        how = local_testbeds.stop(t)
        say("stopped: experiment ended, recording closed" if how == "stopped" else
            "killed: it did not stop within the grace period (its recording may need ./robotarium report)")
    return 0


def _holder_parts(holder):
    """("user@host", "pid N", "script") of a StartExperiment.holder ("user@host pid N script.py")."""
    words = holder.split(None, 3)
    if len(words) == 4 and words[1] == "pid":
        return words[0], "pid " + words[2], words[3]
    return holder, "", ""


def cmd_end(args):
    """Ends your own experiment: the one whose client runs as this user on this host (its holder,
    robotarium_client.robotarium.holder_of_this_process). Another's is refused here, naming whose it is,
    unless --force (the operator's override). The check is a courtesy, not a lock: the testbed
    itself refuses only requests without the client's token and without force."""
    from robotarium_client.robotarium import holder_of_this_process
    from robotarium_client.testbed import end_experiment, testbed_status
    from robotarium_core import outcomes
    from robotarium_msgs.msg import TestbedStatus
    ns = namespace()
    force, outcome, detail = args.force, outcomes.NONE, ""
    if not force:
        here = (os.environ.get("ROS_DOMAIN_ID", "0").strip() or "0", ns)
        msg = testbed_status([(here[0], ns, None)], timeout=args.timeout).get(here)
        if msg is None:
            say("no testbed answers in %s on ROS_DOMAIN_ID %s; ./robotarium status shows what runs where" % here[::-1])
            return 1
        if msg.state != TestbedStatus.STATE_RUNNING:
            say("no experiment is running in %s: nothing to end" % ns)
            return 1
        me = _holder_parts(holder_of_this_process())[0]
        who, pid, script = _holder_parts(msg.holder)
        since = _since(msg.run_id)
        if who != me:
            say("experiment %s is not yours: it is held by %s (%s%s), run %s since %s, step %d. It ends when its "
                "client ends it or is gone; ./robotarium end --force ends it anyway (the operator's override)." % (
                    msg.run_id, who or "a client that did not say who it is", pid or "pid ?",
                    ", script %s" % script if script else "", msg.run_id,
                    time.strftime("%H:%M:%S", since) + " (%s)" % _ago(time.time() - time.mktime(since))
                    if since else "?", msg.step))
            return 1
        # Yours (this user on this host): ended as an operator would, saying by whom.
        force, outcome = True, outcomes.INTERRUPTED
        detail = "interrupted at step %d: ended by its user (%s) with ./robotarium end" % (msg.step, me)
    try:
        response = end_experiment(ns, timeout=args.timeout, force=force, outcome=outcome, detail=detail)
    except TimeoutError as error:
        say("%s; ./robotarium status shows what runs where" % error)
        return 1
    if not response.success:
        say("could not end the experiment in %s: %s" % (ns, response.message))
        return 1
    print(response.report, end="")
    print("Run %s %s; %s" % (
        response.run_id, response.end_reason, "recorded in %s" % response.recording if response.recording
        else "not recorded (no recorder was running)"))
    return 0


def cmd_replay(argv):
    return recording.replay_main(argv)


def cmd_view(argv):
    return recording.view_main(argv)


def cmd_report(argv):
    if "-h" not in argv and "--help" not in argv:
        finish_unfinished()
    return recording.report_main(argv)


# Commands whose own parser (shared with `ros2 run`) reads all their arguments, --help included.
DELEGATED = {"replay": (cmd_replay, "republish a recorded run (in experiment time; --figure draws it)"),
             "report": (cmd_report, "recompute the results of a recorded run (report, plot, video, page)"),
             "view": (cmd_view, "serve the testbed live to Foxglove: the scene, status, commands and poses")}

RUN_EPILOG = """\
whatever happens, the run folder (the last line printed names it) gets log.txt, report.txt (its first
line says how the run ended), run.json, index.html, and from a recording made here trajectories.png and
run.mp4 (a script killed outright included; should run itself be killed outright, the next run, status or
report finishes the folder). Exit codes: 0 the run completed (call_at_scripts_end); 1 the script raised an exception or
could not be compiled or imported (then no testbed is started); 2 a bad command line; 3 the script
ended without call_at_scripts_end(); 4 no testbed, it was busy and --no-wait said not to wait, or it was lost
or ended the experiment; 5 the time limit;
128 + N interrupted by signal N (130: Ctrl-C, 143: SIGTERM, 129: SIGHUP)."""


VERIFY_EPILOG = """\
before anything runs the script must compile and import only modules the Robotarium provides
(verify_allowed_modules in testbed.yaml, and modules beside the script). It then runs in lockstep on a
testbed of its own with the safety node auditing: it lets the script's own commands through, so
collisions and robots leaving the arena happen and are counted as on the Robotarium. Rejected when
it has more than verify_max_collision_iterations (100) collision iterations or verify_max_boundary_iterations
(100) iterations with robots outside the arena, uses another robot count than --robots, runs longer than
verify_duration_factor (1.5) x --duration, raises, or never calls call_at_scripts_end().
Exit codes: 0 accepted; 6 rejected (each broken rule is printed, and listed in --json); 2 a bad command
line; 4 the testbed failed (no verdict); 128 + N interrupted by signal N."""


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError("expected a whole number >= 1, got %r" % text)
    return value


def _seconds(text):
    """A command-line number of seconds: finite and not negative."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError("expected a number of seconds >= 0, got %r" % text)
    return value


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in DELEGATED:
        return DELEGATED[argv[0]][0](argv[1:]) or 0
    parser = argparse.ArgumentParser(prog="./robotarium", description="The Robotarium testbed on ROS 2.")
    sub = parser.add_subparsers(dest="command", required=True)

    up = sub.add_parser("up", help="start the testbed nodes; they run as long as this command does (Ctrl-C stops)")
    up.add_argument("--no-record", action="store_true", help="do not start the recorder")
    up.add_argument("--bags-dir", help="where runs are recorded (default: bags/)")
    up.add_argument("--config", help="the testbed configuration file (default: robotarium_core's testbed.yaml)")
    up.add_argument("--hardware", action="store_true",
                    help="run every experiment hardware-like: tracking and command latency, pose noise, wheel "
                         "dynamics (the numbers: hardware section of testbed.yaml)")
    up.add_argument("--view", action="store_true",
                    help="also serve the testbed to Foxglove, as ./robotarium view does (--view-host, --view-port)")
    recording.add_view_arguments(up, prefix="view-")
    up.set_defaults(func=cmd_up)

    run = sub.add_parser("run", help="run a Robotarium script against the testbed", epilog=RUN_EPILOG,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("script")
    run.add_argument("script_args", nargs=argparse.REMAINDER, help="arguments passed to the script")
    mode = run.add_mutually_exclusive_group()
    mode.add_argument("--lockstep", dest="mode", action="store_const", const="lockstep",
                      help="one step per step() call, as fast as possible (overrides sim_in_real_time)")
    mode.add_argument("--real-time", dest="mode", action="store_const", const="real-time",
                      help="30 Hz like the real testbed (overrides sim_in_real_time)")
    run.add_argument("--time-limit", type=_seconds, metavar="S",
                     help="end the experiment after S seconds of testbed time, in real time and lockstep alike "
                          "(default: the testbed's time_limit, 900 s: the real Robotarium's 15-minute slot; 0: none)")
    run.add_argument("--hardware", action="store_true",
                     help="hardware-like: the real testbed's tracking and command latency, pose noise, wheel "
                          "dynamics (the numbers: hardware section of testbed.yaml)")
    run.add_argument("--seed", type=seed_type, default=0,
                     help="seed of the hardware-like model (default: the testbed draws one; the report names it)")
    run.add_argument("--no-record", action="store_true", help="(local testbed only) do not record the run")
    run.add_argument("--no-video", action="store_true", help="skip rendering the video of the run")
    run.add_argument("--bags-dir", help="(local testbed only) where runs are recorded (default: bags/)")
    run.add_argument("--config", help="(local testbed only) the testbed configuration file "
                                      "(default: robotarium_core's testbed.yaml)")
    run.add_argument("--results-dir", help="where runs not recorded here keep their results "
                                           "(default: results/)")
    run.add_argument("--no-wait", action="store_true",
                     help="when the testbed is busy with another experiment, exit at once (code 4) instead of waiting "
                          "in line for it (first come, first served)")
    run.add_argument("--no-local-testbed", action="store_true",
                     help="never start a testbed here: wait up to 60 s for one to answer (./robotarium up)")
    run.add_argument("--rps", choices=session.RPS_APIS, default=None,
                     help="the Robotarium API the script is written against: guide (rps 0.0.0, the user's guide), "
                          "2 (the Robotarium simulator 2.x: sensors, obstacles, the drive-on phase, debug()) or auto "
                          "(default, or ROBOTARIUM_RPS: 2 when the script uses something only 2.x has)")
    run.set_defaults(func=cmd_run)

    verify = sub.add_parser("verify", help="judge a script as the Robotarium's verification does: accept or reject",
                            description="Run SCRIPT in lockstep on a testbed of its own with the safety node "
                                        "auditing, and accept or reject it by the Robotarium's rules (their limits: "
                                        "testbed.yaml, verify_*).",
                            epilog=VERIFY_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    verify.add_argument("script")
    verify.add_argument("script_args", nargs=argparse.REMAINDER, help="arguments passed to the script")
    verify.add_argument("--robots", type=_positive_int, metavar="N",
                        help="the number of robots declared for the experiment (omitted: not checked)")
    verify.add_argument("--duration", type=_seconds, metavar="S",
                        help="the experiment's declared duration in seconds (omitted: not checked)")
    verify.add_argument("--json", metavar="FILE", help="also write the verdict as JSON to FILE (exit codes 0 and 6)")
    verify.add_argument("--rps", choices=session.RPS_APIS + ("1",), default=None,
                        help="the Robotarium API the script is written against, as for run (1: the guide's)")
    verify.add_argument("--config", help="the testbed configuration file (default: robotarium_core's testbed.yaml)")
    verify.add_argument("--no-record", action="store_true", help="do not record the run")
    verify.add_argument("--bags-dir", help="where the run is recorded (default: bags/)")
    verify.add_argument("--results-dir", help="where a run not recorded keeps its results (default: results/)")
    verify.set_defaults(func=cmd_verify)

    status = sub.add_parser("status", help="the testbeds on this machine, and the experiment running on this domain",
                            description="List the testbeds running on this machine (namespace, ROS_DOMAIN_ID, who "
                                        "started them and when, process ids, logs) and, where a testbed answers, "
                                        "which experiment runs and since when; also for ROS_DOMAIN_ID and "
                                        "ROBOTARIUM_NAMESPACE of this shell.")
    status.add_argument("--json", action="store_true", help="print the same as JSON")
    status.add_argument("--timeout", type=_seconds, default=3.0, metavar="S",
                        help="seconds to wait for testbeds to answer (default 3)")
    status.set_defaults(func=cmd_status)

    stop = sub.add_parser("stop", help="stop a testbed running on this machine (e.g. one left behind)",
                          description="Stop the testbed running on this machine in a namespace and domain (default: "
                                      "ROBOTARIUM_NAMESPACE and ROS_DOMAIN_ID of this shell): its owner "
                                      "(./robotarium run or up) is asked to stop, else its nodes are; each ends its "
                                      "experiment and closes its recording. Whatever is left after 15 s is killed.")
    stop.add_argument("--namespace", help="the testbed's namespace (default: $ROBOTARIUM_NAMESPACE or /robotarium)")
    stop.add_argument("--domain", type=int, help="the testbed's ROS_DOMAIN_ID (default: $ROS_DOMAIN_ID or 0)")
    stop.add_argument("--all", action="store_true", help="every testbed on this machine")
    stop.set_defaults(func=cmd_stop)

    end = sub.add_parser("end", help="end your experiment running on the testbed and print its report",
                         description="End your experiment running in ROBOTARIUM_NAMESPACE on ROS_DOMAIN_ID (on any "
                                     "machine of the domain: yours when its client runs as your user on this host) "
                                     "and print its debug report and where it was recorded; its script stops with "
                                     "exit code 4. Someone else's is not ended: end says whose it is (user@host, pid, "
                                     "script, run, since when) and that --force ends it anyway. The testbed keeps "
                                     "running for the next experiment.")
    end.add_argument("--force", action="store_true",
                     help="end it whoever's it is (the operator's override)")
    end.add_argument("--timeout", type=_seconds, default=10.0, metavar="S",
                     help="seconds to wait for the testbed (default 10)")
    end.set_defaults(func=cmd_end)

    demo = sub.add_parser("demo", help="run a bundled multi-robot example headless, recorded")
    demo.add_argument("--no-video", action="store_true", help="skip rendering the video of the run")
    demo.set_defaults(func=cmd_demo)

    for name, (_, text) in DELEGATED.items():
        sub.add_parser(name, help=text + " (see ./robotarium %s --help)" % name)

    args = parser.parse_args(argv)
    if args.command == "verify":
        # our own options may follow the script too
        rest, given = [], iter(args.script_args)
        for arg in given:
            name, _, value = arg.partition("=")
            if name in ("--robots", "--duration", "--json", "--rps", "--config", "--results-dir"):
                value = value or next(given, "")
                try:
                    value = {"--robots": _positive_int, "--duration": _seconds}.get(name, str)(value)
                except argparse.ArgumentTypeError as error:
                    verify.error("argument %s: %s" % (name, error))
                if name == "--rps" and value not in session.RPS_APIS + ("1",):
                    verify.error("argument --rps: invalid choice %r" % value)
                setattr(args, name[2:].replace("-", "_"), value)
            elif arg == "--no-record":
                args.no_record = True
            else:
                rest.append(arg)
        args.script_args = rest
    if args.command == "run":
        # `./robotarium run script.py --lockstep` works too: our own flags may follow the script.
        own = {"--lockstep": ("mode", "lockstep"), "--real-time": ("mode", "real-time"),
               "--no-record": ("no_record", True), "--no-video": ("no_video", True),
               "--no-local-testbed": ("no_local_testbed", True), "--hardware": ("hardware", True),
               "--no-wait": ("no_wait", True)}
        rest, given = [], iter(args.script_args)
        for arg in given:
            if arg in own:
                setattr(args, *own[arg])
            elif arg == "--time-limit" or arg.startswith("--time-limit="):
                value = arg.partition("=")[2] or next(given, "")
                try:
                    args.time_limit = _seconds(value)
                except argparse.ArgumentTypeError as error:
                    run.error("argument --time-limit: %s" % error)
            else:
                rest.append(arg)
        args.script_args = rest
    return args.func(args) or 0


if __name__ == "__main__":
    code = main()
    # Leave without tearing down the DDS participant the probes kept (testbed._probe_context): Fast DDS
    # can deadlock destroying one while discovery callbacks run. Everything of ours is closed by now.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code if isinstance(code, int) else 0 if code is None else 1)
