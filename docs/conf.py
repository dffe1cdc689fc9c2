"""Sphinx configuration of the project's documentation (rosdoc2's layout: docs/conf.py, Markdown
pages through MyST). Build it with the project's environment:

    ./robotarium shell -c "sphinx-build -W -b html docs docs/_build/html"

The topic, service and parameter tables are written from the code at build time
(_ext/robotarium_tables.py, into _generated/, which git ignores).
"""
import os
import re
import sys

DOCS = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(DOCS)
sys.path.insert(0, os.path.join(DOCS, "_ext"))

project = "Robotarium on ROS 2 Jazzy"
author = "Robotarium ROS team"
copyright = "2026, Robotarium ROS team"
# One version for every package: robotarium_core's package.xml says it.
with open(os.path.join(REPO, "robotarium_core", "package.xml")) as manifest:
    release = version = re.search(r"<version>([^<]+)</version>", manifest.read()).group(1)

extensions = ["myst_parser", "robotarium_tables"]
source_suffix = {".md": "markdown"}
root_doc = "index"
# _generated holds the tables the pages include; they are not pages of their own.
exclude_patterns = ["_build", "_generated", "README.md"]
# Links like [faults](faults.md#what-the-testbed-does) work here and on a code host alike.
myst_heading_anchors = 4
myst_enable_extensions = ["colon_fence"]

html_theme = "alabaster"
html_title = project
html_static_path = []
