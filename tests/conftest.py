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


# The modules that take longest (a -n 2 run, 2026-11-26: minutes of worker time), run first: with
# pytest-xdist's work stealing a long test begun last leaves one worker busy while the other waits;
# begun first, the short ones fill in around it. Each module keeps its tests together (module
# fixtures start a testbed, a database, a service once).
LONGEST_FIRST = ("test_soak.py", "test_service.py", "test_service_faults.py", "test_safe_scripts.py",
                 "test_own_robots.py", "test_examples.py",
                 "test_rps2_examples.py", "test_jobbox.py", "test_portal.py",
                 "test_portal_submit.py",
                 "test_run_results.py", "test_safety_guarantee.py", "test_verify.py", "test_rps2.py", "test_faults.py",
                 "test_line.py", "test_testbed_lifetime.py", "test_simulator_node.py")


def pytest_sessionstart(session):
    """Once per run (not in each xdist worker): Fast DDS's files that killed processes of earlier runs
    left in /dev/shm go (devtools.shm), so no participant of this run opens a dead port."""
    if not hasattr(session.config, "workerinput"):
        from devtools import shm
        shm.remove_unused()


def pytest_collection_modifyitems(items):
    """A test without a layer marker is a unit test (pytest.ini lists the layers); the longest
    modules first (LONGEST_FIRST), the rest in their order."""
    for item in items:
        if item.get_closest_marker("node") is None and item.get_closest_marker("e2e") is None:
            item.add_marker(pytest.mark.unit)
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))   # stable: each module's order kept


@pytest.fixture(autouse=True, scope="module")
def _no_probe_participant_left():
    """The DDS participant that in-process probes of a module's testbed keep (robotarium_bringup.testbed's
    probe contexts) goes with the module, before another module draws its ROS_DOMAIN_ID."""
    yield
    testbed = sys.modules.get("robotarium_bringup.testbed")
    if testbed is not None:
        testbed.close_probe_contexts()
