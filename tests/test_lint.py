"""The lint gate: ruff, configured in ruff.toml, finds nothing in the project's Python."""
import os
import subprocess
import sys

from devtools import REPO


def test_ruff_finds_nothing():
    completed = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "."], cwd=REPO,
                               capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stdout + completed.stderr
    assert os.path.exists(os.path.join(REPO, "ruff.toml"))


# Processes that play someone else's (a forger, a flood from another program) start as any ROS program does.
FOREIGN = {os.path.join("devtools", "flood.py"), os.path.join("devtools", "forged_end.py")}


def test_every_participant_of_ours_starts_with_the_testbeds_dds_settings():
    """rclpy.init only inside dds_settings.init_context: Fast DDS reads its profile once, at a process's
    first participant, so one plain rclpy.init first (a test, a tool) gave every later participant
    of that process Fast DDS's defaults: shared memory, and multicast discovery on the network."""
    found = []
    for top in ("robotarium_core", "robotarium_sim", "robotarium_hardware", "robotarium_safety", "robotarium_recording",
                "robotarium_bringup", "robotarium_client", "robotarium_cli",
                "robotarium_portal", "devtools", "tests", "bench", "scripts"):
        for folder, _, files in os.walk(os.path.join(REPO, top)):
            for name in files:
                path = os.path.join(folder, name)
                relative = os.path.relpath(path, REPO)
                if not name.endswith(".py") or relative in FOREIGN or relative == os.path.join("tests", "test_lint.py"):
                    continue
                with open(path, encoding="utf-8") as f:
                    for number, line in enumerate(f, 1):
                        if "rclpy.init(" in line and "def init_context" not in line:
                            found.append("%s:%d" % (relative, number))
    assert found == [os.path.join("robotarium_core", "robotarium_core", "dds_settings.py") + ":%d" % _init_line()], found


def _init_line():
    with open(os.path.join(REPO, "robotarium_core", "robotarium_core", "dds_settings.py"), encoding="utf-8") as f:
        return next(n for n, line in enumerate(f, 1) if "rclpy.init(" in line and "def " not in line)
