"""The docs build (Sphinx + MyST, docs/) without a warning, and their tables come from the code."""
import glob
import os
import re
import subprocess
import sys
import types

from devtools import REPO

sys.path.insert(0, os.path.join(REPO, "docs", "_ext"))
import robotarium_tables  # noqa: E402  (docs/_ext is not a package)


def test_docs_build_without_warnings_and_tables_come_from_the_code(tmp_path):
    completed = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html", "-d", str(tmp_path / "doctrees"),
         os.path.join(REPO, "docs"), str(tmp_path / "html")],
        cwd=REPO, capture_output=True, text=True, timeout=300)
    assert completed.returncode == 0, completed.stdout[-3000:] + completed.stderr[-5000:]
    with open(tmp_path / "html" / "ros-interface.html") as f:
        page = f.read()
    # A topic and its QoS from topics.py, a parameter with its default from testbed.yaml and its range
    # from config.py, all in the page as built.
    assert "cmd_requested" in page and "reliable, volatile, keep last" in page
    assert "command_timeout" in page and "stops until a new one arrives" in page
    from robotarium_core.config import DEFAULT
    with open(os.path.join(REPO, "docs", "_generated", "parameters.md")) as f:
        parameters = f.read()
    assert "| `command_timeout` | `%g` |" % DEFAULT.command_timeout in parameters
    # The proof moved from the module docstring to the safety page.
    with open(tmp_path / "html" / "safety.html") as f:
        assert "Why the guarantee holds" in f.read()


def test_a_topic_the_table_does_not_describe_is_reported():
    """A new topic name in topics.py fails the docs build (a warning under -W) until it is described."""
    modules = robotarium_tables._modules()
    assert robotarium_tables.undocumented_names(modules) == []
    topics = types.ModuleType("topics")
    vars(topics).update(vars(modules["topics"]))
    topics.WHEEL_SPEEDS = "wheel_speeds"
    assert robotarium_tables.undocumented_names(dict(modules, topics=topics)) == ["WHEEL_SPEEDS"]


def test_valid_range_says_what_config_accepts():
    from robotarium_core.config import FIELDS
    assert robotarium_tables.valid_range("time_step", FIELDS["time_step"]) == "(0, 1]"
    assert robotarium_tables.valid_range("max_robots", FIELDS["max_robots"]) == "whole number in [1, 1000]"
    assert robotarium_tables.valid_range("hardware", FIELDS["hardware"]) == "true or false"
    assert robotarium_tables.valid_range("verify_allowed_modules", FIELDS["verify_allowed_modules"]) == "a list of names"
    assert robotarium_tables.valid_range("imu_position", FIELDS["imu_position"]) == "2 numbers, each in (-0.5, 0.5]"


def _slug(heading):
    """The anchor a code host (and MyST's heading anchors) gives a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def test_readme_links_lead_somewhere():
    """The README and the package READMEs link to docs pages and headings that exist, so they work on
    a code host without building the docs."""
    broken = []
    readmes = [os.path.join(REPO, "README.md")] + glob.glob(os.path.join(REPO, "robotarium_*", "README.md"))
    for readme in readmes:
        with open(readme) as f:
            links = re.findall(r"\]\(([^)\s]+)\)", f.read())
        for link in links:
            if link.startswith(("http://", "https://", "mailto:")):
                continue
            path, _, anchor = link.partition("#")
            target = os.path.normpath(os.path.join(os.path.dirname(readme), path))
            if not os.path.exists(target):
                broken.append("%s: %s (no such file)" % (os.path.relpath(readme, REPO), link))
            elif anchor:
                with open(target) as f:
                    headings = [_slug(line.lstrip("#")) for line in f if line.startswith("#")]
                if anchor not in headings:
                    broken.append("%s: %s (no such heading)" % (os.path.relpath(readme, REPO), link))
    assert not broken, "\n".join(broken)
    assert len(readmes) >= 7
