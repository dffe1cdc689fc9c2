"""Results of a recorded run from its bag alone: the debug report (equal to the live one), the
trajectory plot and the video."""
import dataclasses
import json
import math
import os
import shutil

import imageio_ffmpeg
import matplotlib.image
import numpy as np
import pytest
from test_recorder import stack  # noqa: F401  (fixture: simulator + recorder on a private domain)

from devtools.rosutil import REPO
from robotarium_core import model
from robotarium_core.run_record import RunRecord
from robotarium_recording import pictures, results
from robotarium_recording.bag import FAST_TYPES, Bag

SAMPLE = os.path.join(REPO, "bags", "sample_consensus")

# Robot 0 drives out of the arena, robots 1 and 2 drive into each other, robot 2 asks for more
# than its wheels can do: every counter of the debug report is non-zero.
START = np.array([[1.45, -0.3, -0.1], [0.0, 0.0, 0.0], [0.0, 0.0, math.pi]])
V = [0.2, 0.1, 0.1]
W = [0.0, 0.0, 5.0]


@pytest.mark.node
def test_report_from_the_bag_equals_the_live_report_and_results_are_written(stack, tmp_path):  # noqa: F811
    steps = 45
    stack.start(3, START, name="report")
    for k in range(1, steps + 1):
        stack.step(k, V, W if k > 30 else [0.0, 0.0, 0.0])
    ended = stack.end()
    assert "outside the boundaries" in ended.report and "collided" in ended.report and "actuator" in ended.report
    stack.wait_closed(ended.recording)

    numbers = results.recompute(ended.recording)
    assert numbers["report"] == ended.report
    assert numbers["mismatches"] == [] and numbers["notes"] == []
    assert (numbers["iterations"], numbers["collisions"], numbers["boundary_violations"],
            numbers["actuator_limit_iterations"]) == (ended.steps, ended.collisions, ended.boundary_violations,
                                                      ended.actuator_limit_iterations)

    # Our own types were read with robotarium_core.cdr (the bag's schemas are today's), exactly as rosbags reads them
    bag = Bag(ended.recording)
    assert {t for t in bag.schemas if bag.fast_layout(t)} == set(FAST_TYPES) - {"std_msgs/msg/String"} | (
        {"std_msgs/msg/String"} if "std_msgs/msg/String" in bag.schemas else set())
    assert decoded_as_rosbags_does(bag) > 4 * steps

    paths = results.write_results(ended.recording, progress=False, out_dir=str(tmp_path / "out"))
    with open(paths["report"]) as f:
        text = f.read()
    assert text.startswith("Run completed.\n\n" + ended.report) and "agree with the testbed's counters" in text
    image = matplotlib.image.imread(paths["trajectories"])
    assert image.shape[0] > 300 and image.shape[1] > 500 and image[..., :3].std() > 0.01
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(paths["video"])
    assert paths["video"].endswith(".mp4") and frames == steps + 1
    assert seconds == pytest.approx((steps + 1) * model.TIME_STEP, abs=0.05)   # experiment time


def same_as(ours, theirs, where):
    """ours (robotarium_recording.bag's cdr-read message) holds every field of theirs (rosbags'), equal."""
    if dataclasses.is_dataclass(theirs):
        for field in dataclasses.fields(theirs):   # (the message's constants, upper case, are not read from bags)
            if field.name != "__msgtype__" and not field.name.isupper():
                same_as(getattr(ours, field.name), getattr(theirs, field.name), "%s.%s" % (where, field.name))
    elif isinstance(theirs, np.ndarray):
        assert np.array_equal(np.asarray(ours), theirs) and np.asarray(ours).dtype.kind == theirs.dtype.kind, where
    elif isinstance(theirs, list):
        assert len(ours) == len(theirs), where
        for k, (a, b) in enumerate(zip(ours, theirs)):
            same_as(a, b, "%s[%d]" % (where, k))
    else:
        assert ours == theirs and type(ours) is type(theirs), (where, ours, theirs)


def decoded_as_rosbags_does(bag):
    """Every message of the bag's cdr-read types decodes as rosbags decodes it; returns how many there were."""
    count = 0
    for message in bag.messages():
        if bag.fast_layout(message.type):
            same_as(bag.decode(message), bag.typestore.deserialize_cdr(message.data, message.type),
                    "%s %s" % (message.topic, message.log_time))
            count += 1
    return count


def test_report_command_on_the_sample_run(tmp_path, capsys):
    bag = tmp_path / "sample"
    shutil.copytree(SAMPLE, bag)
    assert results.main([str(bag)]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("Run completed.\n\n##### DEBUG OUTPUT #####") and "agree with the testbed's counters" in out
    assert "rendering run.mp4" in err and "100%" in err                       # progress on stderr
    steps = len(Bag(str(bag)).poses().steps)
    assert imageio_ffmpeg.count_frames_and_secs(str(bag / "run.mp4"))[0] == steps
    assert matplotlib.image.imread(str(bag / "trajectories.png")).size > 0
    assert results.main([str(tmp_path / "missing")]) == 2


@pytest.mark.slow
def test_gif_when_no_video_encoder(tmp_path):
    from PIL import Image
    track = Bag(SAMPLE).poses()
    bag = Bag(SAMPLE)
    path = pictures.render_video(track, bag.drawings(), bag.config(), str(tmp_path), "gif", progress=False, fmt="gif")
    assert path.endswith("run.gif")
    with Image.open(path) as gif:
        assert gif.n_frames == math.ceil(len(track.steps) / 2)


def test_report_of_a_torn_recording_counts_what_is_there(tmp_path):
    bag = tmp_path / "torn"
    shutil.copytree(SAMPLE, bag)
    mcap = next(f for f in os.listdir(bag) if f.endswith(".mcap"))
    with open(bag / mcap, "r+b") as f:
        f.truncate(os.path.getsize(bag / mcap) * 6 // 10)
    paths = results.write_results(str(bag), progress=False, video=False)
    with open(paths["report"]) as f:
        text = f.read()
    assert "##### DEBUG OUTPUT #####" in text and "not closed" in text
    # cut before the experiment's end: it is not known to have completed, so no acceptance estimate
    assert text.startswith("Run did not complete: the recording ends while the experiment was still running")
    assert "Acceptance" not in text
    numbers = results.recompute(str(bag))
    assert 0 < numbers["iterations"] < len(Bag(SAMPLE).poses().steps)
    assert numbers["testbed"] is not None and numbers["testbed"]["iterations"] >= numbers["iterations"] - 1


def test_a_client_that_lost_the_testbed_and_then_left_is_told_first():
    """A node frozen for a few seconds (the soak, issue 41): the client names it and leaves without waiting
    for the testbed, which then ends the run for the client's leaving. The report names the node first, then
    the testbed's end; never the client's leaving alone."""
    from robotarium_core import outcomes
    client = ("the testbed was lost at step 111 (line 57 of x.py): The safety node is gone (no sign of it for "
              "1.5 s) at step 102: the experiment cannot go on, and the simulator stopped every robot")
    testbed = "the testbed ended it at step 143: its client was gone for 2 s (its last command came at step 81)"
    settings = {"outcome": outcomes.CLIENT_LOST, "detail": testbed}
    assert not results._add_outcome(settings, RunRecord(outcome="testbed_lost", detail=client))
    assert outcomes.first_line(settings["outcome"], settings["detail"]) == (
        "Run did not complete: %s; then %s." % (client, testbed))
    # The testbed's word stands where the client had nothing else to say (killed: "interrupted"), or no record.
    for run in (RunRecord(outcome="interrupted", detail="the script's process ended (killed by SIGKILL)"), None):
        settings = {"outcome": outcomes.CLIENT_LOST, "detail": testbed}
        results._add_outcome(settings, run)
        assert settings == {"outcome": outcomes.CLIENT_LOST, "detail": testbed}


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_actuator_limits_are_counted_from_the_commands_in_force(mode):
    from robotarium_recording.bag import Command
    over = Command(1, 10, 10, np.array([0, 1]), np.array([0.1, 0.1]), np.array([0.0, 5.0]))
    # within the limits as applied, but the safety node says the script asked for more
    replaced = Command(2, 40, 40, np.array([1]), np.array([0.1]), np.array([0.0]), True)
    bad = Command(3, 50, 50, np.array([5]), np.array([0.1]), np.array([0.0]))     # unknown id: dropped
    if mode == "lockstep":
        forced = [(v.copy(), f) for v, f in results._commands_in_force_lockstep([over, bad, replaced], 2, 2)]
    else:
        forced = [(v.copy(), f) for v, f in results._commands_in_force_realtime([over, bad, replaced], 2,
                                                                                 [20, 45, 10**9], model.COMMAND_TIMEOUT,
                                                                                 lambda c: c.stamp_ns)]
        assert not forced[2][0].any() and forced[2][1] is False     # stopped after the timeout: nothing asked
    assert np.array_equal(forced[0][0], [[0.1, 0.1], [0.0, 5.0]]) and forced[0][1] is False
    assert np.array_equal(forced[1][0], [[0.1, 0.1], [0.0, 0.0]]) and forced[1][1] is True
    counted = [model.is_actuator_limit_iteration(v, f) for v, f in forced]
    assert counted[:2] == [True, True]


def test_a_real_time_count_allows_for_when_each_array_reached_the_simulator():
    """The bag knows when an array was sent, the simulator applied it when it came, up to just before
    the tick after the one it was filtered for (model.StepGate), and timed it out from then: an
    over-limit array held 0.2 s counts 6 iterations if it came at once, 7 if it came a tick late.
    The testbed's 6 or 7 is the bag's count; its 5 is a difference to report."""
    from types import SimpleNamespace

    from robotarium_recording.bag import Command
    tick = 33_333_333
    track = SimpleNamespace(stamp_ns=np.arange(13) * tick)
    by_step = {s: s for s in range(13)}
    over = Command(1, 5_000_000, 5_000_000, np.array([0]), np.array([0.1]), np.array([13.8]))
    ticks, arrivals = results._realtime_arrivals(track, by_step)
    counts = [sum(model.is_actuator_limit_iteration(v, f) for v, f in
                  results._commands_in_force_realtime([over], 1, ticks, 0.2, arrival)) for arrival in arrivals]
    assert counts == [6, 7]
    assert results._bag_count(counts, 7) == 7 and results._bag_count(counts, 6) == 6
    assert results._bag_count(counts, 5) == 6 and results._bag_count(counts, None) == 6


def test_a_real_time_array_the_testbed_dropped_as_stale_is_left_out_of_one_of_the_counts():
    """A loaded machine's safety node sent an over-limit array so late that the simulator dropped it as
    stale (the testbed counts the drop, not the array): the testbed counted 0 iterations, the bag holds the
    array. The likeliest stale array (sent closest to the tick that made it late) is left out of a count of
    its own, which the testbed's 0 then matches (a whole test run beside a suite: 6 from the bag, 0 counted)."""
    from types import SimpleNamespace

    from robotarium_recording.bag import Command
    tick = 33_333_333
    track = SimpleNamespace(stamp_ns=np.arange(13) * tick)
    by_step = {s: s for s in range(13)}
    early = Command(1, 5_000_000, 5_000_000, np.array([0]), np.array([0.1]), np.array([0.0]))
    late = Command(2, 2 * tick + 30_000_000, 2 * tick + 30_000_000, np.array([0]), np.array([0.1]), np.array([13.8]))
    assert results._likeliest_stale([early, late], track, by_step, 1) == [early]
    assert results._likeliest_stale([early, late], track, by_step, 0) == [early, late]
    ticks, arrivals = results._realtime_arrivals(track, by_step)
    counts = [sum(model.is_actuator_limit_iteration(v, f) for v, f in results._commands_in_force_realtime(
        these, 1, ticks, 0.2, arrival)) for these in ([early, late], [early]) for arrival in arrivals]
    assert min(counts[:2]) > 0 and counts[2:] == [0, 0]
    assert results._bag_count(counts, 0) == 0


def test_the_results_page_wraps_long_report_and_log_lines(tmp_path):
    """A report or log line longer than the page is wide wraps (pre-wrap, broken anywhere: a long path
    has no spaces) instead of running off to the side; the browser check is in test_run_results."""
    from robotarium_recording import page
    long_path = "/very/long/" + "folder/" * 40 + "file.py"
    (tmp_path / "report.txt").write_text("Run did not complete: the script raised OSError at " + long_path + ".\n")
    (tmp_path / "log.txt").write_text("x = " + "1234567890" * 30 + "\n")
    text = open(page.write_page(str(tmp_path), run=RunRecord(outcome="script_error"))).read()
    style = text.split("<style>")[1].split("</style>")[0]
    rule = style.split("pre {")[1].split("}")[0]
    assert "white-space: pre-wrap" in rule and "overflow-wrap: anywhere" in rule, rule
    assert "overflow-wrap: anywhere" in style.split("td {")[1].split("}")[0]
    assert long_path in text and "1234567890" * 30 in text   # wrapped on the page, never cut


def _copy_without_poses(source, target, steps):
    """A copy of the bag at `source` (with the project's bag writer) without the poses of `steps`."""
    from robotarium_recording.bag_writer import BagWriter
    bag = Bag(source)
    poses_topic = bag.topic("poses")
    writer = BagWriter(str(target), custom_data=(bag.metadata or {}).get("custom_data") or {})
    dropped = 0
    for message in bag.messages():
        if message.topic == poses_topic and int(bag.decode(message).step) in steps:
            dropped += 1
            continue
        writer.add_topic(message.topic, message.type, definition=bag.schemas[message.type])   # its own types
        writer.write(message.topic, message.data, message.log_time, message.publish_time)
    writer.close()
    assert dropped == len(steps)


def test_poses_missing_from_the_bag_are_counted_and_the_recording_called_incomplete(tmp_path, capsys):
    """A gap in the bag's step sequence (poses the recorder lost): the results count it, run.json
    gets recording_lost_poses and recording_first_lost_step, the report has no acceptance estimate and
    says the recording is incomplete, exit code 4 (it used to be a note and 'Acceptance likely')."""
    bag = tmp_path / "gap"
    _copy_without_poses(SAMPLE, bag, {40, 41, 42})
    numbers = results.recompute(str(bag))
    assert (numbers["recording_lost_poses"], numbers["recording_first_lost_step"]) == (3, 40)
    run = {"outcome": "completed", "detail": "", "exit_code": 0, "run_id": numbers["settings"]["run_id"]}
    with open(bag / "run.json", "w") as f:
        json.dump(run, f)
    assert results.main([str(bag), "--no-video", "--quiet"]) == 4
    out = capsys.readouterr().out
    lost = "The recording is incomplete: poses of 3 step(s) are missing from the bag (first: step 40)."
    assert out.startswith("Run completed. " + lost) and "Acceptance of your experiment is likely" not in out, out
    with open(bag / "run.json") as f:
        info = json.load(f)
    assert (info["recording_lost_poses"], info["recording_first_lost_step"], info["exit_code"]) == (3, 40, 4), info
    with open(bag / "index.html") as f:
        assert lost in f.read()
    # the untouched sample: nothing lost
    assert results.recompute(SAMPLE)["recording_lost_poses"] == 0
