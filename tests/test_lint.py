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
