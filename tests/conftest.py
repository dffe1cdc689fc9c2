"""Shared test set-up.

The plain modules are imported from the source tree (so a test never runs a stale install);
robotarium_msgs comes from the colcon install tree that ./robotarium builds. The repository root
is importable for devtools (node processes, the reference simulator).
"""
import os
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if REPO not in sys.path:
    sys.path.insert(0, REPO)

from devtools import PACKAGE_SOURCES  # noqa: E402

for path in reversed(PACKAGE_SOURCES):
    if path not in sys.path:
        sys.path.insert(0, path)


# Worker seconds of the modules that take longest (a whole-suite run at -n 3, quiet, 2026-11-29), for the
# schedule (devtools.schedule): each pytest-xdist worker begins with its fair part of them. Any other module
# counts SECONDS_PER_TEST by its tests' layer.
MODULE_SECONDS = {"tests/test_soak.py": 384, "tests/test_safe_scripts.py": 339, "tests/test_rps2_examples.py": 246,
                  "tests/test_service.py": 239, "tests/test_own_robots.py": 231, "tests/test_verify.py": 170,
                  "tests/test_service_faults.py": 161, "tests/test_portal_submit.py": 147, "tests/test_jobbox.py": 141,
                  "tests/test_portal.py": 119, "tests/test_faults.py": 115, "tests/test_testbed_lifetime.py": 98,
                  "tests/test_run_results.py": 91, "tests/test_testbed_faults.py": 91, "tests/test_node_restart.py": 70,
                  "tests/test_ros2_cli.py": 59, "tests/test_examples.py": 56, "tests/test_verify_warm.py": 55,
                  "tests/test_line.py": 54, "tests/test_rps2.py": 53, "tests/test_simulator_node.py": 52}
SECONDS_PER_TEST = {"unit": 0.1, "node": 3.0, "e2e": 10.0}


def pytest_sessionstart(session):
    """Once per run (not in each xdist worker): Fast DDS's files that killed processes of earlier runs
    left in /dev/shm go (devtools.shm), so no participant of this run opens a dead port."""
    if not hasattr(session.config, "workerinput"):
        from devtools import shm
        shm.remove_unused()


def pytest_sessionfinish(session, exitstatus):
    """A process that left a participant Fast DDS deadlocked behind (dds_health.close_unless_stuck)
    leaves without DDS's teardown, with pytest's own exit status."""
    from robotarium_core import dds_health
    dds_health.exit_status = int(exitstatus)


def pytest_collection_modifyitems(items):
    """A test without a layer marker is a unit test (pytest.ini lists the layers)."""
    for item in items:
        if item.get_closest_marker("node") is None and item.get_closest_marker("e2e") is None:
            item.add_marker(pytest.mark.unit)


def pytest_configure(config):
    config.pluginmanager.register(_Schedule(), "robotarium-schedule")
    # Each worker keeps every ROS_DOMAIN_ID it drew (robotarium_bringup.domains): one that finds all 101 held
    # takes back one of its own that no process runs on any more, rather than fail.
    from robotarium_bringup import domains
    domains.reusable = _nothing_runs_on


def _nothing_runs_on(domain):
    from devtools.rosutil import processes_on_domain
    return not processes_on_domain(domain)


class _Schedule:
    @pytest.hookimpl(trylast=True)   # after -m and -k took theirs out: the shares are of what runs
    def pytest_collection_modifyitems(self, config, items):
        """The longest modules first, each pytest-xdist worker's share beginning with its fair part of them
        (devtools.schedule); every worker computes the same order from the same collection."""
        from devtools import schedule
        modules = {}
        for item in items:
            modules.setdefault(item.nodeid.split("::")[0], []).append(item)
        workers = getattr(config, "workerinput", {}).get("workercount", 1)
        items[:] = schedule.order([(tests, MODULE_SECONDS.get(name) or sum(
            SECONDS_PER_TEST[layer] for test in tests for layer in SECONDS_PER_TEST if test.get_closest_marker(layer)))
            for name, tests in modules.items()], workers)


@pytest.fixture(autouse=True, scope="module")
def _no_probe_participant_left():
    """The DDS participant that in-process probes of a module's testbed keep (robotarium_bringup.testbed's
    probe contexts) goes with the module, before another module draws its ROS_DOMAIN_ID."""
    yield
    testbed = sys.modules.get("robotarium_bringup.testbed")
    if testbed is not None:
        testbed.close_probe_contexts()
