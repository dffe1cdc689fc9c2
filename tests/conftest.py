"""Shared test set-up.

The plain modules are imported from the source tree (so a test never runs a stale install);
robotarium_msgs comes from the colcon install tree that ./robotarium builds.
"""
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for package in ("robotarium_sim", "robotarium_safety", "robotarium_client"):
    path = os.path.join(REPO, package)
    if path not in sys.path:
        sys.path.insert(0, path)
