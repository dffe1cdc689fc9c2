"""The Robotarium's results for a recorded run, made from its bag alone (no ROS needed).

Beside the bag: report.txt (how the run ended, then the debug report of
rps.Robotarium.call_at_scripts_end() recomputed from the recorded poses and safe commands with
robotarium_core.model's own counting functions, the run's settings, a cross-check against the
testbed's counters and the safety node's interventions), trajectories.png
(pictures.plot_trajectories), run.mp4 (pictures.render_video, with what the script drew) and
index.html (page.write_page). What each holds and how the report is recomputed:
docs/user-guide.md#what-a-run-gives-back-whatever-its-end.

Usage: ./robotarium report BAG [--out DIR] [--no-video]   (BAG: a run folder under bags/)
"""
import argparse
import os
import sys

import numpy as np

from robotarium_core import model, outcomes, rps2, run_record
from robotarium_recording import page, pictures
from robotarium_recording.bag import Bag

COUNTS_ONLY = 5             # SafetyReport.STATUS_COUNTS_ONLY: no array was filtered
PASSTHROUGH, SATURATED = 0, 6   # SafetyReport.STATUS_PASSTHROUGH, _SATURATED: forwarded as asked (or scaled to the limits)


# -- the report ----------------------------------------------------------------------------------

def _run_settings(bag):
    """experiment, run id, mode, N, the testbed's final counters and how the run ended (outcome,
    detail) from the status topic: the IDLE status that closes a run says how it ended (a bag
    made before outcomes were recorded: completed); none at all means the recording ends while
    the experiment was still running."""
    statuses = bag.statuses()
    running = [s for s in statuses if s.state == 1]
    if not running:
        return {"experiment": "", "run_id": "", "mode": "", "number_of_robots": 0, "final": None,
                "outcome": outcomes.UNFINISHED, "detail": "", "hardware_seed": None}
    last_step = max(s.step for s in running)
    final = [s for s in running if s.step == last_step][-1]   # the simulator's last word: counters, end reason
    closing = [s for s in statuses if s.state == 0 and s.run_id == final.run_id]
    if closing:
        outcome = outcomes.of_request(getattr(closing[-1], "outcome", outcomes.NONE))
        detail = getattr(closing[-1], "outcome_detail", "")
    else:
        outcome, detail = outcomes.UNFINISHED, ""
    # hardware-like runs name their seed (bags made before that mode existed have no such field)
    hardware = bool(getattr(final, "hardware", False))
    return {"experiment": final.experiment, "run_id": final.run_id, "mode": final.mode,
            "number_of_robots": int(final.number_of_robots), "final": final, "outcome": outcome, "detail": detail,
            "hardware_seed": int(final.hardware_seed) if hardware else None}


def safety_summary(bag, tolerance):
    """What the safety node did, from its reports: model.safety_lines' keyword arguments
    (interventions, arrays, largest_change, mean_change) and audit (a verification run: it let the
    script's commands through). An intervention is an array whose safe command differs from the
    requested one by more than `tolerance` for some robot, or a stop of a request not at rest
    (model.is_intervention, SafetyReport.msg); the changes are those of the interventions (stops as
    the largest finite speed they cancelled)."""
    tally, arrays, audit = model.RunTally(), 0, False
    name = bag.topic("safety_report", required=False)
    for _, report in (bag.decoded([name]) if name in bag.topics else ()):
        status = report.status   # a string ("passthrough", "stop_...") in bags before the constants
        if status == COUNTS_ONLY:
            continue
        arrays += 1
        audit = audit or bool(getattr(report, "audit", False))
        # every status but these two is a stop or a solved QP (bags before the constants: strings)
        filtered = (status not in (PASSTHROUGH, SATURATED) if isinstance(status, int)
                    else str(status).startswith(("stop", "solved")))
        tally.add_safety_report(model.is_intervention(filtered, report.max_change, tolerance), report.max_change)
    return dict(tally.safety(arrays), audit=audit)


def safety_interventions(bag, tolerance):
    """(interventions, arrays, largest change, mean change): safety_summary's."""
    summary = safety_summary(bag, tolerance)
    return summary["interventions"], summary["arrays"], summary["largest_change"], summary["mean_change"]


def _report_safety(summary):
    """The debug report's safety lines: none for a verification run (the script's own commands drove it)."""
    return None if summary["audit"] else {k: v for k, v in summary.items() if k != "audit"}


def _commands_in_force_lockstep(commands, n, steps):
    """(velocities 2 x N, requested_exceeds_limits) in force at each step 1..steps: the valid
    array marked with step k sets them (model.StepGate: the simulator applies no other)."""
    velocities = np.zeros((2, n))
    applied = 0
    for cmd in commands:
        if applied >= steps:
            break
        if model.check_commands(cmd.ids, cmd.v, cmd.omega, n) is not None or cmd.step != applied + 1:
            continue   # the simulator drops it without stepping
        velocities[0, cmd.ids] = cmd.v
        velocities[1, cmd.ids] = cmd.omega
        applied += 1
        yield velocities, cmd.requested_exceeds_limits
    return applied


def _commands_in_force_realtime(commands, n, tick_ns, timeout, arrival):
    """(velocities, requested_exceeds_limits) in force at each tick (stamps of the poses it
    produced), with the simulator's command timeout, for arrays that reached the simulator at
    `arrival(command)` (ns)."""
    velocities = np.zeros((2, n))
    since = np.full(n, -np.inf)
    flag = False
    valid = [c for c in commands if model.check_commands(c.ids, c.v, c.omega, n) is None]
    valid.sort(key=arrival)
    k = 0
    for t in tick_ns:
        while k < len(valid) and arrival(valid[k]) < t:
            c = valid[k]
            ids, v, w = c.ids, c.v, c.omega
            if c.refreshed:   # the commands in force, again: their timeout runs on (TwistArray.refreshed)
                live = arrival(c) * 1e-9 - since[ids] <= timeout
                ids, v, w = ids[live], v[live], w[live]
            else:
                since[ids] = arrival(c) * 1e-9
            velocities[0, ids], velocities[1, ids] = v, w
            flag = c.requested_exceeds_limits
            k += 1
        stale = (t * 1e-9 - since > timeout) & np.any(velocities != 0, axis=0)
        if stale.any():
            velocities[:, stale] = 0.0
            flag = False
        yield velocities, flag


def _tick_stamps(track, by_step):
    """{step: stamp (ns) of the tick that produced its poses}."""
    return {int(s): int(track.stamp_ns[i]) for s, i in by_step.items()}


def _sent(command):
    """When a command array was sent (its stamp; where it has none, when it was recorded)."""
    return command.stamp_ns or command.log_ns


def _realtime_arrivals(track, by_step):
    """Real time: the bag knows when an array was sent (its stamp), not when it reached the
    simulator, which applies it at the next tick and times it out `command_timeout` after it came.
    model.StepGate takes an array marked step s only while the testbed is at step s - 1 or s, so it
    came at the earliest when it was sent and at the latest just before the tick that produced step
    s + 1: on a loaded machine a tick either way. Returns (ticks, (earliest, latest)): the tick
    stamps of steps 1.. and the two arrival-time functions."""
    tick_of = _tick_stamps(track, by_step)
    ticks = [tick_of[s] for s in sorted(tick_of) if s >= 1]

    def latest(c):
        after = tick_of.get(c.step + 1)
        return _sent(c) if after is None else max(_sent(c), after - 1)
    return ticks, (_sent, latest)


def _likeliest_stale(commands, track, by_step, count):
    """The `count` arrays of `commands` the simulator most likely dropped as stale (the testbed counts
    them, the bag cannot tell which): those sent closest to, or after, the tick that made them too
    late (the one that produced step s + 1 for an array marked s)."""
    if count <= 0:
        return commands
    tick_of = _tick_stamps(track, by_step)

    def margin(c):
        after = tick_of.get(c.step + 1)
        return np.inf if after is None else after - _sent(c)
    late = set(sorted(range(len(commands)), key=lambda k: margin(commands[k]))[:count])
    return [c for k, c in enumerate(commands) if k not in late]


def _bag_count(counts, testbed_count):
    """One count from those the bag allows (by when arrays arrived): the testbed's where it lies
    among them (the bag confirms it), else the first (then _cross_check reports the difference)."""
    if testbed_count is not None and min(counts) <= testbed_count <= max(counts):
        return testbed_count
    return counts[0]


def _final_count(settings, key):
    final = settings["final"]
    return None if final is None else int(getattr(final, key))


NAMES = {name: outcome for outcome, name in outcomes.NAMES.items()}


def recompute(bag, run=None):
    """The debug report's numbers from the bag: a dict with iterations, collisions,
    boundary_violations, actuator_limit_iterations, report (the exact text rps prints for a
    completed run), outcome and first_line (how the run ended), safety_interventions (count,
    arrays, largest and mean change), settings, testbed (the status counters, or None),
    mismatches (list of strings), notes. `run` (the run's run_record.RunRecord) says how the run
    ended where the bag cannot (a testbed lost mid-run)."""
    if not isinstance(bag, Bag):
        bag = Bag(bag)
    settings = _run_settings(bag)
    config = bag.config()   # the numbers the run was made with, not today's defaults
    track = bag.poses()
    notes = []
    n = track.x.shape[1] if track.x.size else settings["number_of_robots"]
    steps = int(track.steps[-1]) if len(track.steps) else 0
    by_step = {int(s): i for i, s in enumerate(track.steps)}
    missing = [s for s in range(steps) if s not in by_step]
    if missing:
        notes.append("poses of %d step(s) are missing from the bag (first: step %d); they are not counted."
                     % (len(missing), missing[0]))
    notes += outcomes.run_notes(run)
    lost = {"recording_lost_poses": len(missing), "recording_first_lost_step": missing[0] if missing else None}
    experiment = bag.experiment()
    if experiment.get("api") == rps2.API:
        return dict(_recompute_2x(bag, settings, config, track, n, steps, by_step, notes, experiment, run), **lost)
    collisions = boundary = 0
    for s in range(steps):
        if s in by_step:
            i = by_step[s]
            poses = np.vstack((track.x[i], track.y[i], track.theta[i]))
            collisions += model.count_collisions(poses, config.robot_diameter)
            boundary += int(np.count_nonzero(model.outside_arena(poses, config.arena)))

    commands = bag.commands("cmd_safe")
    actuator = 0
    if settings["mode"] == "realtime":
        ticks, arrivals = _realtime_arrivals(track, by_step)
        # Arrays that came too late (a tick after the poses they were filtered at) were dropped as stale: the
        # testbed counts them (a loaded machine's safety node), the bag holds them; without them too.
        stale = (_dropped(settings["final"]).get("cmd_safe") or {}).get("stale", 0) if settings["final"] else 0
        applied = [commands] + ([_likeliest_stale(commands, track, by_step, stale)] if stale else [])
        actuator = _bag_count(
            [sum(model.is_actuator_limit_iteration(velocities, requested_over, **config.limits)
                 for velocities, requested_over in _commands_in_force_realtime(
                     these, n, ticks, config.command_timeout, arrival)) for these in applied for arrival in arrivals],
            _final_count(settings, "actuator_limit_iterations"))
    else:
        applied = 0
        for velocities, requested_over in _commands_in_force_lockstep(commands, n, steps):
            actuator += model.is_actuator_limit_iteration(velocities, requested_over, **config.limits)
            applied += 1
        if applied != steps:
            notes.append("%d valid command arrays on cmd_safe for %d steps: the bag is missing commands "
                         "(recorder started late or was killed?)." % (applied, steps))

    completed = _add_outcome(settings, run)
    safety = safety_summary(bag, config.intervention_tolerance)
    return _cross_check(bag, {
        **lost,
        "iterations": steps, "collisions": collisions, "boundary_violations": boundary,
        "actuator_limit_iterations": actuator, "number_of_robots": n, "settings": settings,
        "report": model.debug_report(steps, boundary, collisions, actuator, config.time_step, completed, n,
                                     config.real_testbed_max_robots, settings["hardware_seed"], _report_safety(safety)),
        "notes": notes, "config": config, "mismatches": [], "testbed": None, "safety": safety})


def _add_outcome(settings, run):
    """How the run ended, in `settings`: the testbed's word, else (a testbed lost mid-run) the
    client's (run.json); both, the client's first, where the client lost the testbed and the testbed then
    lost the client. Returns whether it completed."""
    if run is not None and settings["outcome"] == outcomes.UNFINISHED and run.outcome in NAMES:
        settings["outcome"], settings["detail"] = NAMES[run.outcome], run.detail
    elif (run is not None and settings["outcome"] == outcomes.CLIENT_LOST
          and run.outcome == outcomes.NAMES[outcomes.TESTBED_LOST] and run.detail):
        # The client lost a node (frozen, or cut off), said so and left without waiting for the testbed; the
        # testbed then ended the run for the client's leaving. The client's cause came first: both are told.
        settings["outcome"] = outcomes.TESTBED_LOST
        settings["detail"] = "%s; then %s" % (run.detail.rstrip("."), settings["detail"] or outcomes.PHRASES[
            outcomes.CLIENT_LOST])
    elif run is not None and run.ended_by_unsent_request_at_step is not None:
        # The bag says the client ended it (the request carried its token); the client knows it sent none.
        settings["outcome"] = outcomes.ENDED_BY_UNSENT_REQUEST
        settings["detail"] = outcomes.unsent_end(run.ended_by_unsent_request_at_step)
    return settings["outcome"] == outcomes.COMPLETED


def _recompute_2x(bag, settings, config, track, n, steps, by_step, notes, experiment, run=None):
    """As recompute, for a 2.x experiment: 2.x's rules (robotarium_core.rps2.Testbed2), nothing
    counted before the drive-on phase ended."""
    obstacles = rps2.check_obstacles(experiment.get("obstacles"))
    goals = experiment.get("drive_on_goals")
    done_at = -1
    if goals is not None:
        done_at = None
        goals = np.array(goals, dtype=float)
        for s in range(1, steps + 1):
            if s in by_step:
                i = by_step[s]
                if rps2.at_pose(np.vstack((track.x[i], track.y[i], track.theta[i])), goals,
                                config.drive_on_position_error, config.drive_on_rotation_error)[0]:
                    done_at = s
                    break
        if done_at is None:
            notes.append("the robots never reached their initial conditions: the drive-on phase did not end.")
            done_at = steps
    too_close = outside = hits = 0
    for s in range(done_at + 1, steps):
        if s in by_step:
            i = by_step[s]
            poses = np.vstack((track.x[i], track.y[i], track.theta[i]))
            too_close += rps2.count_too_close(poses, config.collision_diameter, config.collision_offset)
            outside += int(np.any(model.outside_arena(poses, config.arena)))
            hits += rps2.count_obstacle_hits(poses, obstacles, config.collision_diameter, config.collision_offset)

    def count(in_force):
        return sum(bool(requested_over or rps2.exceeds_wheel_limit(velocities, config))
                   for step, (velocities, requested_over) in enumerate(in_force, start=1)
                   if step - 1 > done_at)   # step k moves from the poses of step k - 1
    commands = bag.commands("cmd_safe")
    if settings["mode"] == "realtime":
        ticks, arrivals = _realtime_arrivals(track, by_step)
        actuator = _bag_count([count(_commands_in_force_realtime(commands, n, ticks, config.command_timeout,
                                                                 arrival)) for arrival in arrivals],
                              _final_count(settings, "actuator_limit_iterations"))
    else:
        actuator = count(_commands_in_force_lockstep(commands, n, steps))
    safety = safety_summary(bag, config.intervention_tolerance)
    result = {"iterations": steps, "collisions": too_close, "boundary_violations": outside,
              "actuator_limit_iterations": actuator, "obstacle_collisions": hits, "number_of_robots": n,
              "settings": settings, "notes": notes, "config": config, "mismatches": [], "testbed": None,
              "safety": safety,
              "report": rps2.debug_report(steps, too_close, outside, actuator, config.time_step,
                                          _add_outcome(settings, run), _report_safety(safety))}
    if goals is not None:
        notes.append("2.x experiment: the drive-on phase took steps 1-%d (counted in the duration, not judged)"
                     % (done_at + 1))
    return _cross_check(bag, result)


def _cross_check(bag, result):
    """Add how the run ended, the safety interventions and the testbed's own counters (with any
    difference from the recomputed ones) to `result`."""
    settings, notes = result["settings"], result["notes"]
    result["outcome"], result["completed"] = settings["outcome"], settings["outcome"] == outcomes.COMPLETED
    result["first_line"] = outcomes.first_line(settings["outcome"], settings["detail"])
    safety = result["safety"]
    result["safety_interventions"] = (safety["interventions"], safety["arrays"], safety["largest_change"],
                                      safety["mean_change"])
    final = settings["final"]
    if final is not None:
        testbed = {"iterations": int(final.step), "collisions": int(final.collisions),
                   "boundary_violations": int(final.boundary_violations),
                   "actuator_limit_iterations": int(final.actuator_limit_iterations),
                   "command_timeouts": int(final.command_timeouts),
                   "commands_accepted": int(final.commands_accepted),
                   "safety_interventions": int(final.safety_interventions),
                   "stale_pose_stops": int(getattr(final, "stale_pose_stops", 0)),
                   "dropped": _dropped(final), "end_reason": getattr(final, "end_reason", "")}
        result["testbed"] = testbed
        for key in ("iterations", "collisions", "boundary_violations", "actuator_limit_iterations"):
            if testbed[key] != result[key]:
                result["mismatches"].append("%s: %d from the bag, %d counted by the testbed"
                                            % (key.replace("_", " "), result[key], testbed[key]))
    else:
        notes.append("no status of the running experiment in the bag: nothing to cross-check against.")
    return result


def _dropped(status):
    """{input: {reason: count}} of the arrays the testbed dropped (a TestbedStatus); bags recorded
    before the counts by input and reason have three counts of the simulator's input."""
    if hasattr(status, "dropped_cmd_safe"):
        return {name: {reason: int(getattr(counts, reason)) for reason in model.DROP_REASONS}
                for name, counts in (("cmd_requested", status.dropped_cmd_requested),
                                     ("cmd_safe", status.dropped_cmd_safe))}
    return {"cmd_safe": {reason: int(getattr(status, "dropped_" + reason, 0)) for reason in model.DROP_REASONS}}


def verdict_text(numbers, run):
    """Where the safety layer changed the script's commands, the Robotarium's verdict on the script's
    own (./robotarium run judges the script then and keeps the verdict in run.json), or how to get
    it. Empty for a run it did not change, and for a verification run."""
    if not numbers["safety"]["interventions"] or numbers["safety"]["audit"]:
        return ""
    verdict = run.verdict if run is not None else None
    if not verdict:
        return ("The Robotarium's verdict on your script's own commands is not known from this recording: "
                "./robotarium verify SCRIPT judges the script as the Robotarium does.\n")
    return verdict.get("text") or "The Robotarium's verification: %s.\n" % verdict.get("verdict")


def report_text(bag, numbers):
    """report.txt: how the run ended (first line), the debug report as rps prints it (never the
    acceptance estimate for a run that did not complete), the Robotarium's verdict where the safety
    layer changed the script's commands (verdict_text), then settings and the cross-check."""
    s = numbers["settings"]
    verdict = numbers.get("verdict_text", "")
    lines = [numbers["first_line"], "", numbers["report"].rstrip("\n")] + ([verdict.strip("\n")] if verdict else []) + ["",
             "##### RUN (recomputed from the recording) #####",
             "bag:          %s%s" % (bag.path, "" if bag.complete else "  (not closed: recorder stopped early; "
                                     "every complete chunk was read)"),
             "experiment:   %s   run id: %s   mode: %s%s" % (
                 s["experiment"] or "?", s["run_id"] or "?", s["mode"] or "?",
                 "" if s["hardware_seed"] is None else ", hardware-like (seed %d)" % s["hardware_seed"]),
             "robots:       %d" % numbers["number_of_robots"],
             "steps:        %d (%.2f s of simulated time; the recording spans %.2f s of wall time)"
             % (numbers["iterations"], numbers["iterations"] * numbers["config"].time_step, bag.duration_ns * 1e-9),
             "config:       arena %s, command timeout %g s, time step %g s, robot diameter %g m%s" % (
                 list(numbers["config"].arena), numbers["config"].command_timeout, numbers["config"].time_step,
                 numbers["config"].robot_diameter, "" if bag.topic("config", required=False) in bag.topics
                 else " (defaults: this bag predates recorded configurations)")]
    t = numbers["testbed"]
    if t is not None:
        lines.append("cross-check:  %s" % ("collisions, boundary violations, actuator-limit iterations and steps "
                                          "agree with the testbed's counters" if not numbers["mismatches"]
                                          else "DIFFERS: " + "; ".join(numbers["mismatches"])))
        lines.append("testbed:      %d command timeouts, %d command arrays accepted, %d stops for stale poses" % (
            t["command_timeouts"], t["commands_accepted"], t["stale_pose_stops"]))
        for name, counts in t["dropped"].items():
            lines.append("dropped:      %s: %s" % (name, ", ".join("%d %s" % (n, reason) for reason, n in counts.items()
                                                                 if n) or "none"))
        if t["end_reason"]:
            lines.append("ended:        %s" % t["end_reason"])
    count, arrays, largest, mean = numbers["safety_interventions"]
    lines.append("safety:       %d interventions in %d command arrays (a safe command more than %g m/s or rad/s "
                 "from the requested one, or a stop)%s%s" % (
                     count, arrays, numbers["config"].intervention_tolerance,
                     "; change largest %.3g, mean %.3g" % (largest, mean) if count else "",
                     "; the testbed counted %d" % t["safety_interventions"] if t is not None else ""))
    if numbers.get("obstacle_collisions"):
        lines.append("obstacles:    %d robot-steps with a collider touching one of the script's obstacles (2.x "
                     "draws them for its distance sensors and never checks them: not judged)"
                     % numbers["obstacle_collisions"])
    safety = numbers["safety"]
    if safety["audit"]:
        lines.append("verification: the safety node audited this run (./robotarium verify): it let the script's own "
                     "commands through, so the counts above are the Robotarium's")
    lines += ["note:         " + note for note in numbers["notes"]]
    lines.append("messages:     " + ", ".join("%s %d" % (topic, info.count) for topic, info in sorted(bag.topics.items())))
    return "\n".join(lines) + "\n"


# -- entry points -----------------------------------------------------------------------------------



def preload(video=True):
    """Import what write_results needs (matplotlib, Pillow, ffmpeg's path) ahead of time: ./robotarium run
    does it in a thread while the script runs, where the lockstep chain leaves a core mostly idle, rather
    than after it (about 0.7 s on a quiet machine). Not rosbags: a bag of today's messages is read without
    it (robotarium_recording.bag.FAST_TYPES). Only a head start: a failure here is met again, and reported,
    where the results are made."""
    try:
        import matplotlib.figure  # noqa: F401
        from matplotlib.backends import backend_agg  # noqa: F401

        if video:
            import PIL.ImageDraw  # noqa: F401
            pictures.ffmpeg_path()
    except Exception:   # noqa: BLE001
        pass


def write_results(bag_dir, progress=True, *, out_dir=None, video=True, run=None, live=None):
    """Write report.txt, trajectories.png, run.mp4 (or run.gif) and index.html for the run in
    `bag_dir` (into `out_dir`, default the bag folder); `run` (its run_record.RunRecord, default the
    run.json beside the bag) says how the run ended where the bag cannot and goes on the page; `live`
    (a live_video.LiveVideo) the video made while the run went, kept where it is the bag's.
    Returns {"report": path, "trajectories": path, "video": path, "page": path} ("video" only when
    video=True and the bag has poses). Prints nothing but progress (stderr)."""
    bag = Bag(bag_dir)
    out_dir = os.path.abspath(out_dir or bag.path)
    os.makedirs(out_dir, exist_ok=True)
    run = run if run is not None else run_record.read(bag.path)
    numbers = recompute(bag, run)
    stopped = outcomes.recording_stopped(run)
    if stopped:   # no verdict from a recording that stopped early (the report's notes say where)
        numbers["report"] = numbers["report"].replace(model.ACCEPTANCE_LIKELY, model.RECORDING_INCOMPLETE)
        numbers["first_line"] = outcomes.with_recording_stopped(numbers["first_line"], stopped)
    if numbers["recording_lost_poses"]:   # a gap in the bag's steps: no verdict, and run.json says so
        lost = outcomes.lost_poses(numbers["recording_lost_poses"], numbers["recording_first_lost_step"])
        numbers["report"] = numbers["report"].replace(model.ACCEPTANCE_LIKELY, model.RECORDING_INCOMPLETE)
        numbers["first_line"] = "%s %s%s." % (numbers["first_line"], lost[0].upper(), lost[1:])
        if run is not None:
            run.recording_lost_poses = numbers["recording_lost_poses"]
            run.recording_first_lost_step = numbers["recording_first_lost_step"]
            if run.exit_code == 0:   # completed, its recording not: not a success (README)
                run.exit_code = outcomes.EXIT_CODES[outcomes.TESTBED_LOST]
            if os.path.isfile(os.path.join(out_dir, run_record.FILE)):
                run_record.write(run, out_dir)
    numbers["verdict_text"] = verdict_text(numbers, run)
    paths = {"report": os.path.join(out_dir, "report.txt")}
    with open(paths["report"], "w", encoding="utf-8") as f:
        f.write(report_text(bag, numbers))
    track, drawings, config = bag.poses(), bag.drawings(), numbers["config"]
    obstacles = bag.experiment().get("obstacles") or ()
    title = numbers["settings"]["run_id"] or bag.name
    if live is not None:   # (first: its thread draws with matplotlib until it is done)
        movie = os.path.join(out_dir, "run.mp4")
        if video and len(track.steps) and live.video_for(track, drawings, config, title, obstacles, movie, progress):
            paths["video"] = movie
            if progress:
                print("rendering run.mp4: made as the run went (%d frames)" % len(live.frames.plan), file=sys.stderr,
                      flush=True)
        live.close()
    plot = pictures.plot_trajectories(track, drawings, config, os.path.join(out_dir, "trajectories.png"), title,
                                     obstacles)
    if plot:
        paths["trajectories"] = plot
    if video and "video" not in paths:
        movie = pictures.render_video(track, drawings, config, out_dir, title, progress=progress,
                                      obstacles=obstacles)
        if movie:
            paths["video"] = movie
    paths["page"] = page.write_page(out_dir, run=run, numbers=numbers, bag=bag)
    return paths


REPORT_DESCRIPTION = ("Recompute the results of a recorded run from its bag: report.txt (the debug report), "
                      "trajectories.png, a video and the results page index.html, written beside the bag (or into "
                      "--out).")


def add_report_arguments(parser):
    """report's arguments (robotarium report, ros2 robotarium report)."""
    parser.add_argument("bag", help="run folder (bags/<run_id>), its metadata.yaml or its .mcap file")
    parser.add_argument("--out", help="folder for the results (default: the bag folder)")
    parser.add_argument("--no-video", action="store_true", help="skip the video")
    parser.add_argument("--quiet", action="store_true", help="no progress output")


def main(argv=None):
    parser = argparse.ArgumentParser(prog="robotarium report", description=REPORT_DESCRIPTION)
    add_report_arguments(parser)
    return report(parser.parse_args(argv))


def report(args):
    """Write the results of the bag `args` (add_report_arguments) name and print the report."""
    try:
        run = run_record.read(Bag(args.bag).path)
        paths = write_results(args.bag, progress=not args.quiet, out_dir=args.out, video=not args.no_video,
                              run=run)
    except (FileNotFoundError, KeyError) as error:
        print("report: %s" % error, file=sys.stderr)
        return 2
    with open(paths["report"], encoding="utf-8") as f:
        print(f.read(), end="")
    print("\nresults:\n" + "\n".join("  %-13s %s" % (k, v) for k, v in paths.items()))
    # A recording that lost poses is incomplete: exit code 4, as ./robotarium run gives it (README).
    return outcomes.EXIT_CODES[outcomes.TESTBED_LOST] if run is not None and run.recording_lost_poses else 0


if __name__ == "__main__":
    sys.exit(main())
