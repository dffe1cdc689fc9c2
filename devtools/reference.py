"""Run code against the Robotarium's own simulator (PyPI robotarium-python-simulator 0.0.0).

It lives in its own venv, .venv-reference, so that its `rps` never shadows ours; we talk to it
through a subprocess. `run_reference(code, **inputs)` executes `code` there with the inputs bound
as variables (numpy arrays, numbers, strings, lists) and returns the dict the code stored in
`result`. Pickle carries the data both ways (both sides run numpy 1.26).
"""
import os
import pickle
import subprocess
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REFERENCE_PYTHON = os.path.join(REPO, ".venv-reference", "bin", "python")

_PRELUDE = """
import pickle, sys
import matplotlib
matplotlib.use("Agg")
_inputs = pickle.load(sys.stdin.buffer)
globals().update(_inputs)
result = {}
"""
_EPILOGUE = """
with open(sys.argv[1], "wb") as _out:
    pickle.dump(result, _out)
"""


def reference_available():
    return os.path.exists(REFERENCE_PYTHON)


def _reference_env():
    # Our PYTHONPATH (the colcon install tree) holds our own `rps`: keep it away from the reference.
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "AMENT_PREFIX_PATH")}
    env["MPLBACKEND"] = "Agg"
    return env


def run_reference(code, timeout=600, **inputs):
    if not reference_available():
        raise RuntimeError(
            "The reference simulator venv is missing: run ./robotarium setup (it creates .venv-reference).")
    script = _PRELUDE + code + _EPILOGUE
    with tempfile.NamedTemporaryFile(suffix=".pkl") as out:
        completed = subprocess.run(
            [REFERENCE_PYTHON, "-c", script, out.name], input=pickle.dumps(inputs),
            capture_output=True, timeout=timeout, cwd=tempfile.gettempdir(), env=_reference_env())
        if completed.returncode != 0:
            raise RuntimeError("reference code failed:\n" + completed.stderr.decode(errors="replace"))
        with open(out.name, "rb") as f:
            return pickle.load(f)
