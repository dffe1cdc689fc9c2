"""The Python side of ./robotarium: up, run, demo, replay, report.

./robotarium (bash) makes the environment and then calls `python -m robotarium_client.cli CMD`.
"""
import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

from robotarium_client import session
from robotarium_client.testbed import LocalTestbed, namespace, repository_root, testbed_answers

DEMO_SCRIPT = os.path.join("examples", "barrier_certificates.py")  # 8 robots swap places through the middle
# Folders never searched for data files a script saved.
SKIP_DIRS = {".git", ".venv", ".venv-reference", "build", "install", "log", "bags", "results", "__pycache__",
             "node_modules"}


def say(text):
    print("[robotarium] %s" % text, file=sys.stderr, flush=True)


def cmd_up(args):
    ns = namespace()
    if testbed_answers(ns, timeout=2.0):
        say("a testbed already answers in %s on ROS_DOMAIN_ID %s; not starting a second one"
            % (ns, os.environ.get("ROS_DOMAIN_ID", "0")))
        return 1
    testbed = LocalTestbed(record=not args.no_record, quiet=False, bags_dir=args.bags_dir,
                           config_file=args.config).start()
    say("testbed up in namespace %s on ROS_DOMAIN_ID %s (simulator, safety%s). Ctrl-C stops it."
        % (ns, os.environ.get("ROS_DOMAIN_ID", "0"), "" if args.no_record else ", recorder"))
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    while not stop.wait(0.5):
        failed = testbed.failed()
        if failed:
            say("node(s) exited: %s; stopping the testbed" % failed)
            break
    testbed.stop()
    say("testbed stopped")
    return 0


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


def _tee(stream, sinks):
    for line in iter(stream.readline, b""):
        for sink in sinks:
            sink.write(line)
            sink.flush()


def wait_until_recorded(run_dir, timeout=15.0):
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
        time.sleep(0.1)
    say("the recorder has not closed %s yet; results are made from what is recorded so far" % run_dir)
    return False


def run_script(script, script_args=(), real_time=None, record=True, bags_dir=None, results=True, video=True,
               local_testbed=True, config_file=None):
    """Run an experiment script against the testbed (starting one here if none answers and
    `local_testbed` allows it).

    Returns (exit code, run info dict or None, run folder or None).
    """
    script = os.path.abspath(script)
    if not os.path.isfile(script):
        say("no such script: %s" % script)
        return 2, None, None
    ns = namespace()
    testbed = None
    # Without local_testbed a testbed is known to be up (or coming up): wait for it, never start one.
    if testbed_answers(ns, timeout=3.0 if local_testbed else 60.0):
        say("using the testbed that answers in %s" % ns)
    elif not local_testbed:
        say("no testbed answers in %s on ROS_DOMAIN_ID %s (--no-local-testbed forbids starting one); "
            "start it with ./robotarium up" % (ns, os.environ.get("ROS_DOMAIN_ID", "0")))
        return 2, None, None
    else:
        say("no testbed answers in %s: starting one on this machine for this run" % ns)
        testbed = LocalTestbed(record=record, bags_dir=bags_dir, config_file=config_file).start()

    work = tempfile.mkdtemp(prefix="robotarium-run-")
    info_path = os.path.join(work, "run.json")
    log_path = os.path.join(work, "log.txt")
    # The testbed is up (found or started above): the script waits for it, never starts another.
    options = session.RunOptions(real_time=real_time, local_testbed=False, namespace=ns,
                                 experiment_name=session.experiment_name_of(script),
                                 progress_interval=session.progress_from_environment(10.0))
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        env.setdefault("MPLBACKEND", "Agg")
    command = [sys.executable, "-m", "robotarium_client.runner", options.to_json(), info_path, script, *script_args]

    cwd = os.getcwd()
    before = _snapshot(cwd)
    started = time.time()
    with open(log_path, "wb") as log:
        process = subprocess.Popen(command, cwd=cwd, env=env,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        try:
            _tee(process.stdout, [sys.stdout.buffer, log])
            code = process.wait()
        except KeyboardInterrupt:
            process.send_signal(signal.SIGINT)
            code = process.wait()
    if testbed is not None:
        testbed.stop()  # the recorder closes the bag

    info = None
    if os.path.exists(info_path):
        with open(info_path) as f:
            info = json.load(f)
    if info is None:
        say("the script did not end its experiment (no call_at_scripts_end?); exit code %d" % code)
        shutil.rmtree(work, ignore_errors=True)
        return code or 1, None, None

    run_dir = info.get("recording") or ""
    if not run_dir:
        # A very short run can end before the recorder's announcement of its folder arrived.
        guess = os.path.join(bags_dir or os.path.join(repository_root(), "bags"), info["run_id"])
        run_dir = guess if os.path.isdir(guess) else ""
    if not run_dir or not os.path.isdir(run_dir):
        # Recorded on another machine (or not at all): keep the local outputs in results/<run id>/.
        run_dir = os.path.join(repository_root(), "results", info["run_id"])
        os.makedirs(run_dir, exist_ok=True)
        results = False
    shutil.copy2(script, os.path.join(run_dir, os.path.basename(script)))
    shutil.copy2(log_path, os.path.join(run_dir, "log.txt"))
    with open(os.path.join(run_dir, "run.json"), "w") as f:
        json.dump(dict(info, script=script, exit_code=code, wall_time=round(time.time() - started, 3)), f, indent=2)
    saved = [p for p, mtime in _snapshot(cwd).items() if before.get(p) != mtime and mtime / 1e9 >= started - 1]
    if saved:
        data_dir = os.path.join(run_dir, "data")
        os.makedirs(data_dir, exist_ok=True)
        for path in saved:
            shutil.copy2(path, os.path.join(data_dir, os.path.relpath(path, cwd).replace(os.sep, "__")))
    shutil.rmtree(work, ignore_errors=True)

    if results:
        wait_until_recorded(run_dir)
        from robotarium_recording.results import write_results
        write_results(run_dir, progress=True, video=video)
    say("run %s: outputs in %s" % (info["run_id"], os.path.relpath(run_dir, cwd)))
    for name in sorted(os.listdir(run_dir)):
        print("    %s" % name, file=sys.stderr)
    return code, info, run_dir


def cmd_run(args):
    real_time = {"lockstep": False, "real-time": True}.get(args.mode)
    code, _, _ = run_script(args.script, args.script_args, real_time=real_time, record=not args.no_record,
                            bags_dir=args.bags_dir, video=not args.no_video,
                            local_testbed=not args.no_local_testbed, config_file=args.config)
    return code


def cmd_demo(args):
    script = os.path.join(repository_root(), DEMO_SCRIPT)
    say("demo: %s, headless, lockstep" % DEMO_SCRIPT)
    code, info, run_dir = run_script(script, real_time=False, video=not args.no_video)
    if code == 0 and run_dir:
        say("demo done: the report, trajectories.png and the video of the run are in %s" % run_dir)
    return code


def cmd_replay(args):
    from robotarium_recording.replay_node import main as replay_main
    return replay_main(args.rest)


def cmd_report(args):
    from robotarium_recording.results import main as report_main
    return report_main(args.rest)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="./robotarium", description="The Robotarium testbed on ROS 2.")
    sub = parser.add_subparsers(dest="command", required=True)

    up = sub.add_parser("up", help="start the testbed nodes until Ctrl-C")
    up.add_argument("--no-record", action="store_true", help="do not start the recorder")
    up.add_argument("--bags-dir", help="where runs are recorded (default: bags/)")
    up.add_argument("--config", help="the testbed configuration file (default: robotarium_core's testbed.yaml)")
    up.set_defaults(func=cmd_up)

    run = sub.add_parser("run", help="run a Robotarium script against the testbed")
    run.add_argument("script")
    run.add_argument("script_args", nargs=argparse.REMAINDER, help="arguments passed to the script")
    mode = run.add_mutually_exclusive_group()
    mode.add_argument("--lockstep", dest="mode", action="store_const", const="lockstep",
                      help="one step per step() call, as fast as possible (overrides sim_in_real_time)")
    mode.add_argument("--real-time", dest="mode", action="store_const", const="real-time",
                      help="30 Hz like the real testbed (overrides sim_in_real_time)")
    run.add_argument("--no-record", action="store_true", help="(local testbed only) do not record the run")
    run.add_argument("--no-video", action="store_true", help="skip rendering the video of the run")
    run.add_argument("--bags-dir", help="(local testbed only) where runs are recorded (default: bags/)")
    run.add_argument("--config", help="(local testbed only) the testbed configuration file "
                                      "(default: robotarium_core's testbed.yaml)")
    run.add_argument("--no-local-testbed", action="store_true",
                     help="never start a testbed here: wait up to 60 s for one to answer (./robotarium up)")
    run.set_defaults(func=cmd_run)

    demo = sub.add_parser("demo", help="run a bundled multi-robot example headless, recorded")
    demo.add_argument("--no-video", action="store_true", help="skip rendering the video of the run")
    demo.set_defaults(func=cmd_demo)

    for name, func, text in (("replay", cmd_replay, "republish a recorded run"),
                             ("report", cmd_report, "recompute the results of a recorded run")):
        p = sub.add_parser(name, help=text, add_help=False)
        p.add_argument("rest", nargs=argparse.REMAINDER)
        p.set_defaults(func=func)

    args = parser.parse_args(argv)
    if args.command == "run":
        # `./robotarium run script.py --lockstep` works too: our own flags may follow the script.
        own = {"--lockstep": ("mode", "lockstep"), "--real-time": ("mode", "real-time"),
               "--no-record": ("no_record", True), "--no-video": ("no_video", True),
               "--no-local-testbed": ("no_local_testbed", True)}
        rest = []
        for arg in args.script_args:
            if arg in own:
                setattr(args, *own[arg])
            else:
                rest.append(arg)
        args.script_args = rest
    return args.func(args) or 0


if __name__ == "__main__":
    sys.exit(main())
