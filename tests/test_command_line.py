"""The command line as people expect it: --help on every command, an unknown command lists them
all, `shell -c CMD` runs CMD, and `report` on the committed sample leaves nothing for git."""
import os
import shutil
import subprocess
import sys

import pytest

from devtools.rosutil import REPO

ROBOTARIUM = os.path.join(REPO, "robotarium")


def robotarium(*args, timeout=120):
    return subprocess.run([ROBOTARIUM, *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=timeout, cwd=REPO)


def listed_commands():
    usage = robotarium("help").stdout
    return [line.split()[0] for line in usage.splitlines() if line.startswith("  ") and line.split()]


def test_an_unknown_command_lists_every_command():
    completed = robotarium("frobnicate")
    assert completed.returncode == 2 and "unknown command frobnicate" in completed.stdout
    commands = listed_commands()
    assert {"run", "demo", "up", "status", "stop", "end", "replay", "report", "test", "bench", "setup",
            "shell"} <= set(commands), commands
    assert all("  %s" % command in completed.stdout for command in commands)


def test_every_command_has_help(capsys):
    from robotarium_cli import main as cli
    for command in listed_commands():
        if command in ("test", "bench", "setup", "shell", "serve", "worker", "submit"):   # not robotarium_cli's verbs
            completed = robotarium(command, "--help")
            assert completed.returncode == 0 and "usage" in completed.stdout.lower(), (command, completed.stdout)
            continue
        with pytest.raises(SystemExit) as exit_:
            cli.main([command, "--help"])
        assert exit_.value.code == 0, command
        assert "usage" in capsys.readouterr().out, command


@pytest.mark.parametrize("bench", sorted(name[len("bench_"):-len(".py")] for name in os.listdir(os.path.join(REPO, "bench"))
                                          if name.startswith("bench_") and name.endswith(".py")))
def test_every_benchmark_has_help_and_starts_nothing_with_it(bench):
    """`./robotarium bench verify --help` took --help for a script and began its runs (2026-11-30)."""
    # as ./robotarium bench runs it (the repository on the path), without its environment check each time
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [os.environ.get("PYTHONPATH"), REPO])))
    completed = subprocess.run([sys.executable, os.path.join("bench", "bench_%s.py" % bench), "--help"], env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=60, cwd=REPO)
    assert completed.returncode == 0 and completed.stdout.lower().startswith("usage:"), completed.stdout


def test_a_command_loads_its_own_verb_only():
    """`./robotarium verify ...` builds verify's parser alone: the other verbs' modules (the Foxglove view's,
    the simulated fleet's) are not imported on its way to the script (~0.1 s of every command's start)."""
    probe = ("import sys\nfrom robotarium_cli import main\ntry:\n    main.main(['verify', '--help'])\n"
             "except SystemExit:\n    pass\nprint(sorted(m for m in ('foxglove', 'robotarium_hardware.sim_fleet', "
             "'robotarium_cli.verb.view', 'robotarium_cli.verb.verify') if m in sys.modules))")
    from devtools.rosutil import node_env
    completed = subprocess.run([sys.executable, "-c", probe], env=node_env(0), capture_output=True, text=True,
                               timeout=60, cwd=REPO)
    assert completed.stdout.strip().splitlines()[-1] == "['robotarium_cli.verb.verify']", completed.stdout


@pytest.mark.parametrize("module, executable", [("robotarium_sim.simulator_node", "simulator"),
                                                ("robotarium_safety.safety_node", "safety"),
                                                ("robotarium_recording.recorder_node", "recorder")])
def test_a_node_started_with_help_prints_its_usage_and_starts_nothing(module, executable):
    """`python -m robotarium_sim.simulator_node --help` once started a simulator on domain 0 (issue 36)."""
    import sys
    completed = subprocess.run([sys.executable, "-m", module, "--help"], capture_output=True, text=True,
                               timeout=60, env=dict(os.environ, ROS_DOMAIN_ID="231"))
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.startswith("usage: ros2 run %s %s" % (module.split(".")[0], executable)), completed.stdout
    assert "testbed.yaml" in completed.stdout and "ready" not in completed.stdout + completed.stderr


def test_shell_runs_a_command_in_the_projects_environment():
    completed = robotarium("shell", "-c", "echo venv=$VIRTUAL_ENV; python -c 'import robotarium_msgs'")
    assert completed.returncode == 0, completed.stdout
    assert "venv=%s" % os.path.join(REPO, ".venv") in completed.stdout


def test_what_report_and_replay_write_beside_the_committed_sample_is_ignored_by_git():
    sample = os.path.join("bags", "sample_consensus")
    written = ["report.txt", "trajectories.png", "run.mp4", "run.gif", "index.html", "replay.mp4"]
    ignored = subprocess.run(["git", "check-ignore", *(os.path.join(sample, name) for name in written)],
                             cwd=REPO, stdout=subprocess.PIPE, text=True)
    assert sorted(ignored.stdout.split()) == sorted(os.path.join(sample, name) for name in written)
    recorded = [os.path.join(sample, name) for name in os.listdir(os.path.join(REPO, sample))
                if name == "metadata.yaml" or name.endswith(".mcap")]
    kept = subprocess.run(["git", "check-ignore", *recorded], cwd=REPO, stdout=subprocess.PIPE, text=True)
    assert recorded and kept.stdout == ""   # the recording itself stays tracked


@pytest.mark.parametrize("line, hint", [
    ("import nump", "did you mean 'numpy'?"),
    ("from rps.utilities.misk import *", "did you mean 'rps.utilities.misc'?"),
    ("import rps.utilities.barrier_certificate", "did you mean 'rps.utilities.barrier_certificates'?"),
])
def test_an_import_typo_is_named_with_what_was_meant_before_anything_runs(tmp_path, line, hint):
    """run's pre-check (robotarium_cli.folders.check_script) names a typo in a top-level module and in an rps submodule
    alike (the README promises a "did you mean" for import typos; submodules once got none)."""
    from robotarium_cli import folders as cli
    script = tmp_path / "typo.py"
    script.write_text("import numpy as np\n%s\nprint('never runs')\n" % line)
    detail, message = cli.check_script(str(script))
    assert detail.startswith("could not import ") and detail.endswith("(line 2 of typo.py; %s)" % hint), detail
    assert "ModuleNotFoundError" in message and line in message


def test_an_import_of_something_real_passes_the_pre_check(tmp_path):
    from robotarium_cli import folders as cli
    script = tmp_path / "fine.py"
    script.write_text("import rps.robotarium as robotarium\nfrom rps.utilities.misc import *\nimport numpy\n")
    assert cli.check_script(str(script)) is None


def _unwritable_results_folder(tmp_path, how):
    """A results folder ./robotarium run cannot write: under a regular file, read-only, or full."""
    if how == "under_a_file":
        (tmp_path / "a_file").write_text("not a folder")
        return str(tmp_path / "a_file" / "results"), None
    folder = tmp_path / how
    folder.mkdir()
    if os.geteuid() != 0:
        if how == "full":
            pytest.skip("a full tmpfs needs root")
        folder.chmod(0o555)   # read-only for this user
        return str(folder), None
    options = "ro,size=64k" if how == "read_only" else "size=64k"
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], stderr=subprocess.PIPE,
                             text=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here: %s" % mounted.stderr.strip())
    if how == "full":
        with open(folder / "filler", "wb") as f:
            try:
                f.write(b"\0" * 128 * 1024)
            except OSError:
                pass
    return str(folder), str(folder)


@pytest.mark.parametrize("how", ["under_a_file", "read_only", "full"])
def test_an_unwritable_results_folder_is_one_line_and_exit_2_before_anything_runs(tmp_path, how):
    """A results folder that cannot be written (a full disk, read-only) is said in one line with exit
    code 2 before a testbed starts (it used to be found after the run: a traceback, exit 1)."""
    from devtools.rosutil import node_env, unique_domain_id
    results, mount = _unwritable_results_folder(tmp_path, how)
    script = tmp_path / "moves.py"
    script.write_text("import rps.robotarium as robotarium\nr = robotarium.Robotarium(number_of_robots=1, "
                      "show_figure=False)\nr.step()\nr.call_at_scripts_end()\n")
    try:
        done = subprocess.run([ROBOTARIUM, "run", "--no-video", "--results-dir", results, "--bags-dir",
                               str(tmp_path / "bags"), str(script)], env=node_env(unique_domain_id()), cwd=str(tmp_path),
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    finally:
        if mount:
            subprocess.run(["umount", "-l", mount])
    lines = [line for line in done.stdout.splitlines() if line.strip() and "building" not in line]
    assert done.returncode == 2 and len(lines) == 1, done.stdout
    assert lines[0].startswith("[robotarium] cannot run: the run's folder would go where it cannot be written: %s"
                               % results) and "Traceback" not in done.stdout, done.stdout
    full = "is on a full disk (No space left on device)" in lines[0] or "less than results_min_free" in lines[0]
    assert full if how == "full" else "is not writable" in lines[0], lines[0]
    assert not os.path.exists(tmp_path / "bags"), done.stdout   # no testbed was started, nothing recorded


def test_setup_help_and_a_wrong_option_make_nothing(tmp_path):
    """`setup --browser` is documented in its help; --help (anywhere among the options) and an
    unknown option make nothing: the script is run from a bare copy, where setup would make .venv and
    log/. An unknown option exits 2 with one line of usage."""
    shutil.copy(ROBOTARIUM, tmp_path / "robotarium")
    bare = str(tmp_path / "robotarium")

    def run(*args):
        return subprocess.run([bare, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=60,
                              cwd=str(tmp_path))
    for args in (("--help",), ("--browser", "--help")):
        helped = run("setup", *args)
        assert helped.returncode == 0 and "usage: ./robotarium setup [--browser]" in helped.stdout, helped
        assert "Chromium" in helped.stdout, helped.stdout
    wrong = run("setup", "--frobnicate")
    assert wrong.returncode == 2, wrong
    assert wrong.stderr.splitlines() == [
        "[robotarium] error: unknown option --frobnicate; usage: ./robotarium setup [--browser] (--help says more)"]
    assert run("test", "--help").returncode == 0
    assert sorted(os.listdir(tmp_path)) == ["robotarium"]   # nothing made
