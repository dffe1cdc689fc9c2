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


def pytest_collection_modifyitems(items):
    """A test without a layer marker is a unit test (pytest.ini lists the layers)."""
    for item in items:
        if item.get_closest_marker("node") is None and item.get_closest_marker("e2e") is None:
            item.add_marker(pytest.mark.unit)
