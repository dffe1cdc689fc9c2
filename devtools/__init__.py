"""Tools shared by the tests, the benchmarks and the scripts (never by the packages themselves):
real nodes in subprocesses on a DDS domain of their own (`rosutil`), the Robotarium's own simulator
in its venv (`reference`), a script run with numpy seeded (`run_seeded`), a flood of foreign
command arrays (`flood`).

Import them from the repository root (./robotarium puts it on PYTHONPATH for bench and scripts;
tests/conftest.py does it for pytest)."""
import os

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# The ament_python packages, in dependency order; their sources are imported directly in tests
# (never a stale install). ./robotarium's PACKAGES lists the same folders for colcon.
PACKAGE_SOURCES = [os.path.join(REPO, p) for p in (
    "robotarium_core", "robotarium_sim", "robotarium_hardware", "robotarium_safety", "robotarium_recording", "robotarium_client")]
