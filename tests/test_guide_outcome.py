"""bench/guide_outcome.py: the outcome line a guide script's run prints, read back by
bench/bench_hardware.py. Plain module: no nodes."""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import guide_outcome  # noqa: E402

NUMBERS = ("3.1.1", "3.1.2", "3.2.1", "3.3.1", "3.4.1", "3.5.1", "3.5.2", "3.7.1", "3.8.1")


def _globals_for(number):
    """The script globals goal_error reads, for a 2-robot run."""
    x = np.zeros((3, 2))
    return {"x_si": x[:2], "goal_points": x, "x": x, "x_goal": x[:2], "L": np.array([[1, -1], [-1, 1]]),
            "desired_distance": 0.2, "weights": np.array([[0, 0.2], [0.2, 0]])}


def test_every_outcome_line_reads_back_whatever_its_description_holds():
    # 3.5.1 and 3.8.1 say "(the script stops below 0.05)": a reader that stopped at the first ")"
    # lost them, and bench_hardware showed both as "failed (no outcome)" in both modes.
    for number in NUMBERS:
        error, what = guide_outcome.goal_error(number, _globals_for(number), np.zeros((3, 2)))
        for finished in (True, False):
            line = guide_outcome.outcome_line(2405, error, what, finished)
            text = "##### DEBUG OUTPUT #####\n...\n" + line + "\n[robotarium] Run completed.\n"
            assert guide_outcome.parse_outcome(text) == (
                2405, "n/a" if error is None else "%.4f" % error, what, finished), number


def test_no_outcome_line_reads_as_none():
    assert guide_outcome.parse_outcome("Traceback (most recent call last):\n  ...\nKeyError: 'goal'\n") is None
