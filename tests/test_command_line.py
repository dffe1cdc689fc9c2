"""The command line as people expect it: --help on every command, an unknown command lists them
all, `shell -c CMD` runs CMD, and `report` on the committed sample leaves nothing for git."""
import os
import shutil
import subprocess

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
    from robotarium_client import cli
    for command in listed_commands():
        if command in ("test", "bench", "setup", "shell", "serve", "worker"):   # bash's own (test: pytest's help)
            completed = robotarium(command, "--help")
            assert completed.returncode == 0 and "usage" in completed.stdout.lower(), (command, completed.stdout)
            continue
        with pytest.raises(SystemExit) as exit_:
            cli.main([command, "--help"])
        assert exit_.value.code == 0, command
        assert "usage" in capsys.readouterr().out, command


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
    """run's pre-check (cli.check_script) names a typo in a top-level module and in an rps submodule
    alike (the README promises a "did you mean" for import typos; submodules once got none)."""
    from robotarium_client import cli
    script = tmp_path / "typo.py"
    script.write_text("import numpy as np\n%s\nprint('never runs')\n" % line)
    detail, message = cli.check_script(str(script))
    assert detail.startswith("could not import ") and detail.endswith("(line 2 of typo.py; %s)" % hint), detail
    assert "ModuleNotFoundError" in message and line in message


def test_an_import_of_something_real_passes_the_pre_check(tmp_path):
    from robotarium_client import cli
    script = tmp_path / "fine.py"
    script.write_text("import rps.robotarium as robotarium\nfrom rps.utilities.misc import *\nimport numpy\n")
    assert cli.check_script(str(script)) is None


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
