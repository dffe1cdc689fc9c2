"""`./robotarium verify SCRIPT`: the Robotarium's verdict on a script, before it is submitted.

As the Robotarium's verification: the script must compile and import only modules the Robotarium
provides (`verify_allowed_modules`), then runs in lockstep on a testbed of its own with the safety
node auditing (the script's own commands go through and are counted), and is rejected for too many
collision or boundary iterations, another robot count than declared, too long a run, an exception
or no call_at_scripts_end(). Exit codes: 0 accepted, 6 rejected, 2 a bad command line, 4 no
verdict (the web portal depends on them); `--json FILE` writes the verdict.

The rules are plain functions (static_rules, judge) that tests drive without ROS;
robotarium_cli.running.verify_script runs a script and judges it. Rules, limits and the JSON:
docs/user-guide.md#verifying-a-script-as-the-robotarium-does.
"""
import ast
import dataclasses
import json
import math
import os
import sys
import tokenize

RULES = ("collisions", "boundary", "robots", "duration", "compile", "imports", "script_error", "no_end")
STDLIB = "stdlib"   # the entry of verify_allowed_modules that stands for Python's standard library


def rule(name, message, count=None, limit=None, first_step=None):
    assert name in RULES, name
    return {"rule": name, "count": count, "limit": limit, "first_step": first_step, "message": message}


def _is_allowed(name, allowed, folder):
    if name in allowed or (STDLIB in allowed and (name in sys.stdlib_module_names or name == "__future__")):
        return True
    # the script's own modules, beside it (the Robotarium takes them with the script)
    return os.path.isfile(os.path.join(folder, name + ".py")) or os.path.isdir(os.path.join(folder, name))


COMPILE_ERRORS = (SyntaxError, ValueError, UnicodeDecodeError)


def compile_script(script):
    """The script's source and syntax tree, compiled as `python SCRIPT` would (its encoding
    line honoured); raises one of COMPILE_ERRORS where python would refuse it."""
    with tokenize.open(script) as f:
        source = f.read()
    tree = ast.parse(source, filename=script)
    compile(tree, script, "exec", dont_inherit=True)
    return source, tree


def static_rules(script, config):
    """The rules judged before anything runs: the script compiles ('compile', with the line) and
    imports only allowed modules ('imports', one rule naming every such import). [] when both hold."""
    try:
        _, tree = compile_script(script)
    except COMPILE_ERRORS as error:
        line = getattr(error, "lineno", None)
        what = ("%s: %s" % (type(error).__name__, error.msg) if isinstance(error, SyntaxError)
                else "%s: %s" % (type(error).__name__, error))
        return [rule("compile", "The script does not compile: %s%s." % (
            what, " (line %d of %s)" % (line, os.path.basename(script)) if line else ""), first_step=None)]
    allowed = set(config.verify_allowed_modules)
    folder = os.path.dirname(os.path.abspath(script))
    refused = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue   # relative imports are the script's own package
        for name in names:
            top = name.split(".")[0]
            if not _is_allowed(top, allowed, folder):
                refused.append((node.lineno, name))
    if not refused:
        return []
    refused.sort()
    listed = ", ".join("%s (line %d)" % (name, line) for line, name in refused)
    return [rule("imports", "The script imports %s, which the Robotarium does not provide: use the libraries it has "
                 "(verify_allowed_modules in testbed.yaml) or modules of your own beside the script."
                 % listed, count=len(refused))]


def judge(run, config, robots=None, duration=None):
    """The broken rules of a verification run. `run`: its run_record.RunRecord (outcome, detail,
    steps, step calls, robots, counts, first error steps); `robots` and `duration` (s) as declared,
    None: that rule is not judged."""
    broken = []
    outcome, detail = run.outcome, run.detail
    iterations = int(run.steps or 0)
    step_of_end = int(run.step_calls or iterations)
    if outcome == "script_error" or (outcome == "completed" and str(detail).startswith("then the script raised")):
        broken.append(rule("script_error", "The script failed: %s." % str(detail).rstrip("."),
                           first_step=step_of_end))
    elif outcome == "no_end":
        broken.append(rule("no_end", "The script ended without calling r.call_at_scripts_end() (%s): the Robotarium "
                                     "needs it to end an experiment." % str(detail).rstrip(".")))
    elif outcome == "time_limit":
        limit = int(math.floor(config.time_limit / config.time_step + 1e-9))
        broken.append(rule("duration", "The script ran into the testbed's time limit of %g s (%d iterations) without "
                                       "ending." % (config.time_limit, limit), count=iterations, limit=limit))
    collisions = int(run.collisions or 0)
    if collisions > config.verify_max_collision_iterations:
        first = run.first_collision_step
        broken.append(rule("collisions", "Robots collided in %d iterations, more than the %d the Robotarium allows%s."
                           % (collisions, config.verify_max_collision_iterations,
                              " (the first at step %d)" % first if first else ""),
                           count=collisions, limit=config.verify_max_collision_iterations, first_step=first or None))
    outside = int(run.boundary_violations or 0)
    if outside > config.verify_max_boundary_iterations:
        first = run.first_boundary_step
        broken.append(rule("boundary", "Robots were outside the arena in %d iterations, more than the %d the Robotarium "
                                       "allows%s." % (outside, config.verify_max_boundary_iterations,
                                                      " (the first at step %d)" % first if first else ""),
                           count=outside, limit=config.verify_max_boundary_iterations, first_step=first or None))
    n = run.number_of_robots
    if robots is not None and n is not None and int(n) != robots:
        broken.append(rule("robots", "The script uses %d robots, but %d were declared (--robots)." % (n, robots),
                           count=int(n), limit=robots))
    if duration is not None and outcome != "time_limit":
        limit = int(math.floor(config.verify_duration_factor * duration / config.time_step + 1e-9))
        if iterations > limit:
            broken.append(rule("duration", "The script ran %d iterations (%.1f s), more than %g x the declared %g s "
                                           "(%d iterations)." % (iterations, iterations * config.time_step,
                                                                 config.verify_duration_factor, duration, limit),
                               count=iterations, limit=limit))
    return broken


def verdict(rules, run=None, report="", results=None):
    """The --json document; `run` the verification run's run_record.RunRecord (None: it never ran)."""
    counted = ("collisions", "boundary_violations", "actuator_limit_iterations", "first_collision_step",
               "first_boundary_step", "safety_interventions")
    return {"verdict": "rejected" if rules else "accepted", "rules": rules,
            "iterations": int(run.steps or 0) if run else 0,
            "number_of_robots": run.number_of_robots if run else None, "outcome": run.outcome if run else "not_run",
            "report": report,
            "counts": {key: getattr(run, key) if run else None for key in counted},
            "results": results,
            "api": run.api if run else ""}   # the API the script ran with ("guide", "2"): the service runs it so


def verdict_lines(rules, run, config, robots, duration):
    """The console's closing lines: one per broken rule, or what passed."""
    if rules:
        return ["Verification failed (%s): %s" % (r["rule"], r["message"]) for r in rules] + [
            "The Robotarium would reject this experiment."]
    iterations = int(run.steps or 0)
    checked = ["%d collision iteration(s) (at most %d)" % (int(run.collisions or 0),
                                                          config.verify_max_collision_iterations),
               "%d iteration(s) outside the arena (at most %d)" % (int(run.boundary_violations or 0),
                                                                   config.verify_max_boundary_iterations)]
    checked.append("%d robots%s" % (run.number_of_robots or 0, " as declared" if robots is not None else ""))
    checked.append("%d iterations (%.1f s)%s" % (iterations, iterations * config.time_step,
                                                 " within %g x the declared %g s" % (config.verify_duration_factor,
                                                                                    duration)
                                                 if duration is not None else ""))
    skipped = [what for what, given in (("the robot count (--robots N)", robots), ("the duration (--duration S)",
                                                                                  duration)) if given is None]
    lines = ["Verification passed: %s. The Robotarium's verification would accept this experiment." % "; ".join(checked)]
    if skipped:
        lines.append("Not checked, as none was declared: %s." % " and ".join(skipped))
    return lines


def write_json(path, document):
    with open(path, "w", encoding="utf-8") as f:
        json.dump(document, f, indent=2)
        f.write("\n")


class NoVerdict(Exception):
    """The verification could not judge the script (the testbed failed, or it was interrupted);
    `code` is the exit code that says so."""

    def __init__(self, message, code):
        super().__init__(message)
        self.code = code


@dataclasses.dataclass
class Verdict:
    """A script judged by the Robotarium's rules: the rules it broke, the verification run's
    run_record.RunRecord (None: it never ran) and debug report, where its results are, and what was
    declared."""
    rules: list
    run: object
    report: str
    results: object
    config: object
    robots: object = None
    duration: object = None

    @property
    def accepted(self):
        return not self.rules

    def document(self):
        """The --json document (and run.json's `verdict`)."""
        return verdict(self.rules, self.run, self.report, self.results)

    def text(self):
        """What the console shows: the verification's debug report and one line per broken rule,
        or what passed."""
        lines = ["", "##### VERIFICATION (the Robotarium's rules) #####"]
        if self.report:
            lines.append(self.report.rstrip("\n"))
        lines += verdict_lines(self.rules, self.run, self.config, self.robots, self.duration)
        return "\n".join(lines) + "\n"
