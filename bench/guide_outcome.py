"""Run a guide script with numpy seeded and print its outcome: `guide_outcome.py SEED MAX_STEPS SCRIPT`.

Started through `./robotarium run` (so the run's mode comes from the command line), it runs the
script unchanged and then prints one line

    [outcome] steps=K goal_error=E (what E measures) finished=yes|no

(parse_outcome() reads it back; what E measures may itself hold parentheses.)

K: the step() calls the script made. E: how far the script is from its own goal at its end, in
metres, measured as the script itself measures it where it has a stopping test (the variables it
tested), else on the final poses: the largest distance of a robot from its goal point; for a
formation the largest error of an edge's length; for consensus the largest distance from the
robots' centroid. The scripts with unreachable goals (3.5.2, 3.5.3) have none (n/a). A script
that has not finished after MAX_STEPS steps is stopped there (finished=no) and ends its experiment.
"""
import os
import re
import sys

import numpy as np

from robotarium_client import session
from robotarium_client.robotarium_abc import RobotariumABC

OUTCOME_LINE = re.compile(r"^\[outcome\] steps=(\d+) goal_error=(\S+) \((.*)\) finished=(yes|no)$", re.MULTILINE)


def outcome_line(steps, error, what, finished):
    return "[outcome] steps=%d goal_error=%s (%s) finished=%s" % (
        steps, "n/a" if error is None else "%.4f" % error, what, "yes" if finished else "no")


def parse_outcome(text):
    """(steps, goal error as printed, what it measures, finished) from the last outcome line in
    text, or None. Greedy up to ") finished=": what E measures may hold parentheses itself."""
    lines = OUTCOME_LINE.findall(text)
    if not lines:
        return None
    steps, error, what, finished = lines[-1]
    return int(steps), error, what, finished == "yes"


class StepBudgetSpent(Exception):
    pass


def edge_error(x, lengths):
    """Largest |distance - wanted| over the edges (i < j) where lengths[i, j] > 0."""
    i, j = np.nonzero(np.triu(lengths))
    distances = np.hypot(x[0, i] - x[0, j], x[1, i] - x[1, j])
    return float(np.max(np.abs(distances - lengths[i, j])))


def goal_error(number, g, poses):
    """(error in m or None, what it measures) for guide script `number` ("3.1.1") from its globals."""
    if number in ("3.1.1", "3.8.3", "3.8.4"):
        return float(np.max(np.linalg.norm(g["x_si"] - g["goal_points"][:2], axis=0))), "largest point-to-goal distance"
    if number in ("3.1.2", "3.2.1", "3.2.2", "3.8.5"):
        return float(np.max(np.linalg.norm(g["x"][:2] - g["goal_points"][:2], axis=0))), "largest robot-to-goal distance"
    if number in ("3.5.1", "3.8.1"):
        return float(np.linalg.norm(g["x_goal"] - g["x_si"])), "norm of the goal errors (the script stops below 0.05)"
    if number in ("3.3.1", "3.6.1", "3.8.2"):
        links = (np.abs(g["L"]) + np.abs(g["L"]).T) > 0
        np.fill_diagonal(links, False)
        return edge_error(poses, links * g["desired_distance"]), "largest formation edge error"
    if number == "3.4.1":
        return edge_error(poses, g["weights"]), "largest formation edge error"
    if number == "3.7.1":
        return float(np.max(np.linalg.norm(poses[:2] - poses[:2].mean(axis=1, keepdims=True), axis=0))), \
            "largest distance from the centroid"
    return None, "no reachable goal"


def main():
    seed, max_steps, script = int(sys.argv[1]), int(sys.argv[2]), os.path.abspath(sys.argv[3])
    sys.argv = [script] + sys.argv[4:]
    session.options.experiment_name = session.experiment_name_of(script)
    sys.path.insert(0, os.path.dirname(script))
    made = []
    original_init, original_step = RobotariumABC.__init__, RobotariumABC.step

    def init(self, *args, **kwargs):
        original_init(self, *args, **kwargs)
        made.append(self)

    def step(self):
        if self._iterations >= max_steps:
            raise StepBudgetSpent()
        original_step(self)

    RobotariumABC.__init__, RobotariumABC.step = init, step
    np.random.seed(seed)
    # The script's globals stay readable after it ran (or was stopped), unlike runpy's.
    g = {"__name__": "__main__", "__file__": script, "__builtins__": __builtins__}
    with open(script) as f:
        code = compile(f.read(), script, "exec")
    finished = True
    try:
        exec(code, g)
    except StepBudgetSpent:
        finished = False
        made[-1].call_at_scripts_end()
    r = made[-1]
    number = ".".join(os.path.basename(script).split("_")[:3])
    error, what = goal_error(number, g, r.poses)
    print(outcome_line(r._iterations, error, what, finished), flush=True)


if __name__ == "__main__":
    main()
