"""Run folders: the checks before a run, the folder each run gets, the results made in it, and the
folders of runs whose ./robotarium run was killed."""
import ast
import difflib
import importlib.util
import os
import pkgutil
import shutil
import sys
import tempfile
import time
import traceback

import yaml

import robotarium_recording as recording
from robotarium_cli.console import say
from robotarium_cli.verification import COMPILE_ERRORS, compile_script
from robotarium_client import progress, session
from robotarium_core import model, outcomes, run_record, script_box
from robotarium_core.config import DEFAULT, SAFE_LOADER, ConfigError, TestbedConfig

# Folders never searched for data files a script saved.
SKIP_DIRS = {".git", ".venv", ".venv-reference", "build", "install", "log", "bags", "results", "__pycache__",
             "node_modules"}


def snapshot_files(directory):
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


PROGRESS = progress.LINE_START.encode()


# the script's last output kept in memory once its log's disk is full (a job that filled its quota): its
# traceback, which says why, still reaches log.txt in the run folder
UNLOGGED_TAIL = 64 * 1024


class Unlogged:
    """What of the script's output its log could not take (its disk full): the error, the bytes in all, the last
    UNLOGGED_TAIL bytes."""

    def __init__(self, error):
        self.error, self.count, self.tail = error, 0, bytearray()

    def add(self, line):
        self.count += len(line)
        self.tail += line
        del self.tail[:-UNLOGGED_TAIL]

    def append_to(self, log_path):
        """Its note and tail at the end of log.txt at log_path (the run folder's, on another disk)."""
        cut = self.count > len(self.tail)
        with open(log_path, "ab") as log:
            log.write(("\n[robotarium] the log stopped here: %s; %s of the script's output:\n" % (
                self.error, "the last %d of its %d bytes" % (len(self.tail), self.count) if cut else "the rest")
            ).encode() + bytes(self.tail))


def tee(stream, log, console=None):
    """Each line of `stream` into the log and onto the console; the testbed's progress lines onto the
    console only (log.txt holds what the script printed and what ended it, not how far it got). Returns
    an Unlogged once the log could not be written (its disk full), else None. `log` is unbuffered: a
    refused write leaves nothing to fail again as it closes."""
    unlogged = None
    for line in iter(stream.readline, b""):
        if not line.startswith(PROGRESS):
            if unlogged is not None:
                unlogged.add(line)
            else:
                try:
                    log.write(line)
                except OSError as error:
                    unlogged = Unlogged(session.describe_exception(error))
                    unlogged.add(line)
        if console is not None:
            try:
                console.write(line)
                console.flush()
            except OSError:   # our terminal is gone (SIGHUP): keep the log, keep reading
                console = None
    return unlogged


def wait_until_recorded(run_dir, timeout=15.0, quiet=False):
    """The recorder closes a run's bag shortly after the run ended (it keeps late messages for a
    moment); results made before that would miss the last chunk. Wait for metadata.yaml to say
    the bag is complete. A bag its recorder recovered (it stopped writing it: a full disk) is not waited for."""
    path = os.path.join(run_dir, "metadata.yaml")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with open(path) as f:
                info = yaml.load(f, Loader=SAFE_LOADER)["rosbag2_bagfile_information"]
            custom = info.get("custom_data") or {}
            if str(custom.get("complete")) == "true":
                return True
            if str(custom.get("recovered")) == "true":   # nobody writes it any more
                if not quiet:
                    say("the recorder stopped writing %s before its end; results are made from what it holds" % run_dir)
                return False
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
    try:
        source, tree = compile_script(script)
    except COMPILE_ERRORS as error:
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
        if outcomes.disk_full(error):
            return "%s is on a full disk (%s)" % (folder, error.strerror)
        return "%s is not writable (%s)" % (folder, error.strerror or error)
    if free < min_free_mb * 1e6:
        return "%s has %s free, less than results_min_free (%s)" % (folder, _megabytes(free), _megabytes(min_free_mb * 1e6))
    return None


def check_run_folders(folders, config_file=None):
    """One line and USAGE_ERROR when a run's folder could not be written (results_folder_problem),
    else None: said before a testbed starts or a robot moves, not as a traceback after the run."""
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


def modified_time(path):
    try:
        return os.stat(path).st_mtime
    except OSError:
        return time.time()


def write_unrecorded_results(run_dir, run, testbed_report="", not_here=""):
    """report.txt and index.html for a run (a run_record.RunRecord) with no recording here (it never
    started, or it was recorded on another machine): how it ended, the testbed's debug report if
    there is one, and `not_here`: why its recording is not here."""
    outcome = {name: value for value, name in outcomes.NAMES.items()}.get(run.outcome, outcomes.UNFINISHED)
    first = outcomes.first_line(outcome, run.detail)
    stopped = outcomes.recording_stopped(run)
    if stopped:   # as write_results says it of a recording that stopped early
        first = outcomes.with_recording_stopped(first, stopped)
        testbed_report = testbed_report.replace(model.ACCEPTANCE_LIKELY, model.RECORDING_INCOMPLETE)
    lines = [first, ""]
    if testbed_report:
        verdict = (run.verdict or {}).get("text", "")
        lines += [testbed_report.rstrip("\n")] + ([verdict.strip("\n")] if verdict else []) + [
            "", "(%s)" % (not_here or "no recording of the run is here")]
    elif run.run_id or run.experiments:
        lines.append("The testbed sent no debug report for this run.")
        if not_here:
            lines += ["", "(%s)" % not_here]
    else:
        lines.append("No experiment ran on a testbed, so there is no debug report.")
    notes = outcomes.run_notes(run)
    if notes:
        lines += [""] + notes
    with open(os.path.join(run_dir, "report.txt"), "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    recording.write_page(run_dir, run=run)


def finish_run_folder(run_dir, run, script, log_path, saved, cwd, data_limit=None):
    """Copy the script, the log and the data files into the run folder and keep `run` (a
    run_record.RunRecord) in it.

    The data files are capped at `data_limit` bytes (default: the configuration's run_data_limit):
    the newest first, each that fits; the others are left out, each named in run.json's
    data_not_saved with why, and in one line here (the report says so too: outcomes.run_notes)."""
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
                    run.data_not_saved[name] = (
                        "left out: %s over the run folder's limit for data files (run_data_limit %s)"
                        % (_megabytes(size), _megabytes(limit)))
                    continue
                shutil.copy2(path, os.path.join(data_dir, name))
                copied += size
            except OSError as error:   # gone meanwhile (a job box removes what broke its disk quota) or unreadable
                run.data_not_saved[name] = error.strerror or str(error)
                print("[robotarium] the data file %s was not saved: %s" % (name, error.strerror or error), flush=True)
        if left_out:
            print("[robotarium] %d data file(s) of %s left out of the run folder (run_data_limit %s, the newest kept): %s"
                  % (len(left_out), _megabytes(sum(size for _, size in left_out)), _megabytes(limit),
                     ", ".join(name for name, _ in left_out)), flush=True)
    run_record.write(run, run_dir)


def _megabytes(size):
    return "%.3g MB" % (size / 1e6)


def print_summary(run_dir, run, cwd):
    """The closing lines: how the run ended, a hint for a failure, and (last) where everything is."""
    with open(os.path.join(run_dir, "report.txt"), encoding="utf-8") as f:
        first = f.readline().strip()
    say(first)
    if "no testbed was started" in run.detail:
        say("hint: fix the line named above and run it again (nothing ran)")
    elif run.outcome == "interrupted" and outcomes.ENDED_BY_ITS_USER in run.detail:
        pass   # its user ended it: nothing to explain
    elif run.outcome == "interrupted" and outcomes.ENDED_BY_TESTBED in run.detail:
        say("hint: " + HINT_ENDED_BY_TESTBED)
    elif run.outcome != "completed" and run.outcome in HINTS:
        say("hint: " + HINTS[run.outcome])
    elif outcomes.recording_stopped(run):
        say("the experiment completed, but %s: its recording is incomplete (exit code %d)"
            % (outcomes.recording_stopped(run), run.exit_code))
    elif run.recording_lost_poses:
        say("the experiment completed, but %s (exit code %d)" % (outcomes.lost_poses(
            run.recording_lost_poses, run.recording_first_lost_step), run.exit_code))
    elif run.exit_code:   # completed, and then the script failed or was stopped
        say("the experiment completed, %s (exit code %d)" % (run.detail, run.exit_code))
    relative = os.path.relpath(run_dir, cwd)
    shown = run_dir if relative.startswith("..") else relative
    say("files: " + ", ".join(sorted(os.listdir(run_dir))))
    say("results in %s (open %s in a browser)" % (shown, os.path.join(shown, "index.html")))
