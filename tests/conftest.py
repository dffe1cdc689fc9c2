"""Shared test set-up.

The plain modules are imported from the source tree (so a test never runs a stale install);
robotarium_msgs comes from the colcon install tree that ./robotarium builds. The repository root
is importable for devtools (node processes, the reference simulator).
"""
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if REPO not in sys.path:
    sys.path.insert(0, REPO)

from devtools import PACKAGE_SOURCES  # noqa: E402

for path in reversed(PACKAGE_SOURCES):
    if path not in sys.path:
        sys.path.insert(0, path)
