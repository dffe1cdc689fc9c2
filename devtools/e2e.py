"""What the end-to-end test modules share: a testbed for a module's runs, `./robotarium run` on it,
and reading back what a run left (its folder, its bag with an independent reader)."""
import contextlib
import os
import signal
import subprocess
import sys
import time

from devtools.rosutil import node_env, unique_domain_id
from robotarium_bringup.testbed import LocalTestbed, testbed_answers

RUNNING = []   # the modules' LocalTestbeds while they run: a failure shows their nodes' logs


def logs_of_the_testbed(lines=40):
    """The end of each testbed node's log and which nodes exited: what a failed run's message
    needs to tell a testbed fault from a script's (CI keeps no temporary folders)."""
    text = []
    for tb in RUNNING:
        text.append("--- testbed nodes that exited (name: exit code): %s" % (tb.failed() or "none"))
        for name in tb.names:
            try:
                with open(os.path.join(tb.log_dir, name + ".log"), errors="replace") as f:
                    tail = f.read().splitlines()[-lines:]
            except OSError as error:
                tail = ["(no log: %s)" % error]
            text.append("--- %s.log, last %d lines:\n%s" % (name, lines, "\n".join(tail)))
    return "\n".join(text)


def run(env, script, *args, timeout=600):
    """./robotarium run [flags] SCRIPT [script args] (flags before "--", script args after it); the
    runs use the module's testbed (module_testbed), never one of their own (--no-local-testbed)."""
    flags, script_args = (args[:args.index("--")], args[args.index("--") + 1:]) if "--" in args else (args, ())
    flags = ("--no-local-testbed", *flags)
    # in the folder of the script that runs (the last .py argument: run_seeded.py runs the one after it)
    cwd = os.path.dirname(([a for a in (script, *script_args) if str(a).endswith(".py")])[-1])
    process = subprocess.Popen([sys.executable, "-m", "robotarium_cli", "run", *flags, script, *script_args],
                               env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd,
                               start_new_session=True)
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        # SIGINT first: the script's exit handler ends its experiment, which frees the shared testbed
        os.killpg(process.pid, signal.SIGINT)
        try:
            out, err = process.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            out, err = process.communicate()
        raise AssertionError("%s did not finish within %d s:\n%s%s\n%s" % (script_args or script, timeout, out, err,
                                                                        logs_of_the_testbed())) from None
    if process.returncode != 0:
        err += "\n" + logs_of_the_testbed()
    return subprocess.CompletedProcess(process.args, process.returncode, out, err)


def run_folder(bags, output):
    info = [line for line in output.splitlines() if " recorded in " in line]
    assert info, "the run was not recorded:\n" + output + "\n" + logs_of_the_testbed()
    return info[-1].split(" recorded in ")[-1].strip()


def check_bag(folder):
    """Message counts per topic as the rosbags library (an independent reader) sees the bag."""
    from rosbags.rosbag2 import Reader
    with Reader(folder) as reader:
        return {c.topic: c.msgcount for c in reader.connections}


@contextlib.contextmanager
def own_domain_testbed(tmp_path_factory, domain=None, fleet_file=None):
    """A LocalTestbed on a domain of its own (localhost discovery), bags and logs in temporary
    folders, up before anything runs on it: yields (env for processes on it, bags folder, testbed);
    stopped on leaving. fleet_file: the hardware arena of that fleet in the simulator's place (its robots run
    on `domain`, which the caller then gives)."""
    domain = domain or unique_domain_id()
    bags = tmp_path_factory.mktemp("bags")
    env = node_env(domain)
    saved = dict(os.environ)
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    tb = LocalTestbed(log_dir=str(tmp_path_factory.mktemp("logs")), bags_dir=str(bags), fleet_file=fleet_file).start()
    try:
        try:
            # up before the first run, or `run` would start a second testbed of its own
            assert testbed_answers(timeout=60), "the testbed did not come up: %s" % tb.failed()
            # and its recorder ready (a test may freeze it: frozen while it starts, it would miss the run)
            recorder_log = os.path.join(tb.log_dir, "recorder.log")
            deadline = time.monotonic() + 60
            while not _says(recorder_log, "recorder ready"):
                assert time.monotonic() < deadline and not tb.failed(), "the recorder did not come up: %s" % tb.failed()
                time.sleep(0.05)
        finally:
            os.environ.clear()
            os.environ.update(saved)
        yield env, bags, tb
    finally:
        tb.stop()   # also when it never came up


def _says(path, text):
    try:
        with open(path, errors="replace") as f:
            return text in f.read()
    except FileNotFoundError:
        return False


@contextlib.contextmanager
def module_testbed(tmp_path_factory):
    """A testbed for a test module's runs (own_domain_testbed): yields (env for ./robotarium run on
    it, bags folder). Use it as the module's fixture; a failed run shows its nodes' logs."""
    with own_domain_testbed(tmp_path_factory) as (env, bags, tb):
        RUNNING.append(tb)
        try:
            yield env, bags
        finally:
            RUNNING.remove(tb)
