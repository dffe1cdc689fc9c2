"""The recorder: bags that independent readers (rosbags, the mcap library) open, counts and poses
equal to what was published, and a bag that survives a SIGKILL of the recorder.

Node tests start the simulator and the recorder from the source tree in subprocesses on their own
DDS domain and drive the simulator in lockstep from the test (publishing on cmd_safe directly).
"""
import os
import shutil
import subprocess

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import Twist
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from devtools.stack import NS, Stack, rosbags_messages
from robotarium_msgs.msg import RobotPoses, TwistArray
from robotarium_recording import bag as bagmod
from robotarium_recording.bag_writer import PROVISIONAL_TAIL, BagWriter
from robotarium_recording.recorder_node import RunRecorder
from robotarium_recording.schema import qos_profile, stamp_from_cdr

pytestmark = pytest.mark.node   # real testbed nodes in subprocesses


@pytest.fixture
def stack(tmp_path):
    s = Stack(tmp_path)
    try:
        yield s
    finally:
        s.close()


def mcap_messages(path):
    """{topic: [(schema, channel, message, decoded)]} read with the mcap library alone."""
    files = [f for f in os.listdir(path) if f.endswith(".mcap")]
    assert len(files) == 1
    out = {}
    with open(os.path.join(path, files[0]), "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            out.setdefault(channel.topic, []).append((schema, channel, message, decoded))
    return header, out


def check_statuses(statuses, steps):
    """Every step's status (the simulator also repeats the current one once a second), the final
    counters, then IDLE."""
    assert {s.step for s in statuses[:-1]} == set(range(steps + 1))
    assert all(s.state == 1 for s in statuses[:-1]) and statuses[-1].state == 0
    assert statuses[-2].step == steps and [s.step for s in statuses[:-1]] == sorted(s.step for s in statuses[:-1])


# -- node tests ------------------------------------------------------------------------------------

LINE = np.array([[-0.6, -0.2, 0.2, 0.6], [0.0, 0.1, -0.1, 0.0], [0.0, 1.0, 2.0, 3.0]])


def test_run_through_the_stack_is_recorded_completely(stack):
    steps = 40
    started = stack.start(4, LINE, name="recorded")
    rng = np.random.default_rng(3)
    for k in range(1, steps + 1):
        stack.step(k, rng.uniform(-0.15, 0.15, 4), rng.uniform(-2, 2, 4))
    ended = stack.end()
    # the start found every reader it waits for (the recorder's of the hidden status stream included:
    # a node one namespace above its topic was once not found, and every start waited 5 s)
    assert "starting without" not in stack.sim.output(), stack.sim.output()
    path = ended.recording
    assert path and os.path.isabs(path) and os.path.basename(path) == started.run_id
    assert os.path.dirname(path) == str(stack.bags_dir)
    stack.wait_closed(path)
    assert stack.probe.spin_until(lambda: stack.recording and stack.recording[-1].data == "", 5)
    seen = {p.step: p for p in stack.poses}
    expected = {NS + "/poses": steps + 1, NS + "/pose_array": steps + 1, NS + "/cmd_safe": steps}

    # rosbags
    decoded, counts, total = rosbags_messages(path)
    for topic, count in expected.items():
        assert counts[topic] == count == len(decoded[topic]), topic
    assert total == sum(len(v) for v in decoded.values())
    assert [p.step for p in decoded[NS + "/poses"]] == list(range(steps + 1))
    for p in decoded[NS + "/poses"]:
        assert np.array_equal(np.array([p.x, p.y, p.theta]), np.array([seen[p.step].x, seen[p.step].y, seen[p.step].theta]))
    assert [c.step for c in decoded[NS + "/cmd_safe"]] == list(range(1, steps + 1))
    check_statuses(decoded[NS + "/status"], steps)
    assert counts[NS + "/status"] == len(decoded[NS + "/status"])
    assert all(log.name.startswith("robotarium.") for log in decoded.get("/rosout", []))

    # the mcap library's own reader: ROS 2 profile, ros2msg schemas, cdr, publish time = header stamp
    header, by_topic = mcap_messages(path)
    assert header.profile == "ros2"
    for topic, count in expected.items():
        assert len(by_topic[topic]) == count, topic
    for schema, channel, message, msg in by_topic[NS + "/poses"]:
        assert schema.encoding == "ros2msg" and schema.name == "robotarium_msgs/msg/RobotPoses"
        assert "MSG: std_msgs/Header" in schema.data.decode()
        assert channel.message_encoding == "cdr" and "offered_qos_profiles" in channel.metadata
        assert message.publish_time == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert message.log_time >= message.publish_time
        assert np.array_equal(np.array(msg.x), np.array(seen[msg.step].x))

    # metadata.yaml as rosbag2 (Jazzy) writes it
    with open(os.path.join(path, "metadata.yaml")) as f:
        info = yaml.safe_load(f)["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap" and info["ros_distro"] == "jazzy"
    assert info["relative_file_paths"] == ["%s_0.mcap" % started.run_id]
    meta_counts = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    assert all(meta_counts[t] == c for t, c in expected.items())
    assert info["message_count"] == total and info["custom_data"]["run_id"] == started.run_id
    poses_meta = next(t["topic_metadata"] for t in info["topics_with_message_count"]
                      if t["topic_metadata"]["name"] == NS + "/poses")
    assert poses_meta["type"] == "robotarium_msgs/msg/RobotPoses" and poses_meta["type_description_hash"].startswith("RIHS01_")
    assert poses_meta["offered_qos_profiles"][0]["reliability"] == "reliable"

    # our reader agrees; a second run goes to a new folder
    bag = bagmod.Bag(path)
    assert bag.complete and not bag.truncated and bag.message_count == total
    stack.start(2, name="second")
    stack.step(1, [0.1, 0.1], [0.0, 0.0])
    second = stack.end()
    assert second.recording and second.recording != path
    stack.wait_closed(second.recording)
    assert bagmod.Bag(second.recording).topics[NS + "/poses"].count == 2


def test_a_default_qos_publisher_is_recorded_once_beside_the_testbeds_own(stack):
    """Arrays from a plain rclpy publisher with default QoS (reliable, volatile: as ros2 topic pub) on
    cmd_safe, beside the testbed's own writer (the safety node's): the testbed hears them (its inputs are
    volatile), so the bag holds them, each once, and the testbed's own arrays once too (the recorder
    used to have one transient-local reader there, which no volatile writer matches)."""
    stack.start(2, name="injected")
    stack.step(1, [0.05, 0.05], [0.0, 0.0])
    injector = stack.probe.node.create_publisher(TwistArray, NS + "/cmd_safe", 10)   # rclpy's default QoS
    # the simulator's reader matches it at once; the recorder's (if it has one that can) within its discovery
    stack.probe.spin_until(lambda: injector.get_subscription_count() >= 2, 10)
    for i in range(5):
        msg = TwistArray(token="f" * 32, step=100 + i, ids=[0, 1], twists=[Twist(), Twist()])
        msg.header.frame_id = "injected"
        injector.publish(msg)
        stack.probe.spin_for(0.02)
    for k in range(2, 6):
        stack.step(k, [0.05, 0.05], [0.0, 0.0])
    ended = stack.end()
    stack.wait_closed(ended.recording)
    decoded, counts, _ = rosbags_messages(ended.recording)
    arrays = decoded[NS + "/cmd_safe"]
    assert sorted(a.step for a in arrays if a.header.frame_id == "injected") == [100, 101, 102, 103, 104]
    assert sorted(a.step for a in arrays if a.header.frame_id != "injected") == [1, 2, 3, 4, 5]
    assert counts[NS + "/cmd_safe"] == 10
    assert [p.step for p in decoded[NS + "/poses"]] == list(range(6))   # the testbed's own topics: once each
    header, by_topic = mcap_messages(ended.recording)
    assert len(by_topic[NS + "/cmd_safe"]) == 10


def test_a_recorder_started_after_the_run_began_records_from_then_on_and_the_results_say_what_is_missing(tmp_path):
    """The streams are volatile (issue 23: a late joiner gets nothing from before it joined), so a
    recorder started mid-run gets no history: it records the run from the step it joined, and the
    results made from that bag say which steps are missing and give no verdict."""
    from robotarium_core import model
    from robotarium_recording.results import recompute, write_results
    late = Stack(tmp_path, recorder=False)
    try:
        started = late.start(3, LINE[:, :3], name="late")
        for k in range(1, 11):
            late.step(k, [0.05] * 3, [0.2] * 3)
        late.start_recorder()
        for k in range(11, 21):
            late.step(k, [0.05] * 3, [0.2] * 3)
        ended = late.end()
        path = os.path.join(late.bags_dir, started.run_id)
        late.wait_closed(path)
    finally:
        late.close()
    assert ended.recording == path
    bag = bagmod.Bag(path)
    # nothing from before it joined (its readers match the writers a moment after the graph shows
    # them: step 11 or a little later), nothing lost after
    steps = list(bag.poses().steps)
    assert steps and steps[0] >= 11 and steps == list(range(steps[0], 21)), steps
    commands = [c.step for c in bag.commands()]
    assert commands and commands[0] >= 11 and commands == list(range(commands[0], 21)), commands
    numbers = recompute(bag)
    assert (numbers["recording_lost_poses"], numbers["recording_first_lost_step"]) == (steps[0], 0), numbers
    with open(write_results(path, progress=False, video=False, out_dir=str(tmp_path / "results"))["report"]) as f:
        report = f.read()
    assert "poses of %d step(s) are missing from the bag (first: step 0)" % steps[0] in report, report
    assert model.ACCEPTANCE_LIKELY not in report and model.RECORDING_INCOMPLETE in report, report


def test_recorder_killed_mid_run_leaves_a_readable_bag(stack):
    stack.start(5, real_time=True, name="killed")
    stack.probe.spin_for(2.5)
    stack.recorder.kill()                      # SIGKILL: no chance to finish the file
    stack.probe.spin_for(0.3)
    stack.end()
    runs = os.listdir(stack.bags_dir)
    assert len(runs) == 1, stack.recorder.output()
    path = os.path.join(stack.bags_dir, runs[0])

    bag = bagmod.Bag(path)
    assert not bag.complete, stack.recorder.output()
    track = bag.poses()
    assert len(track.steps) >= 20, (bag.topics, stack.recorder.output())   # chunks reach the disk within a second
    assert np.array_equal(track.steps, np.arange(len(track.steps))), track.steps

    if bag.truncated:   # killed inside the one write of a flush (rare): cut back to the last chunk
        bagmod.recover_bag(path)
    decoded, counts, total = rosbags_messages(path)          # the provisional end makes it a valid MCAP
    assert [p.step for p in decoded[NS + "/poses"]] == list(track.steps)
    _, by_topic = mcap_messages(path)
    assert {t: len(v) for t, v in by_topic.items()} == {t: len(v) for t, v in decoded.items()}
    assert all(counts[t] <= len(decoded[t]) for t in counts)  # metadata.yaml lags at most one flush

    recovered = bagmod.recover_bag(path)                      # like ros2 bag reindex: exact counts
    _, counts, total = rosbags_messages(path)
    assert counts == {t: info.count for t, info in recovered.topics.items()} and total == recovered.message_count


# -- plain tests (no ROS graph) ------------------------------------------------------------------

def _write_sample(path, messages=300, flush_every=40):
    from rclpy.serialization import serialize_message
    writer = BagWriter(str(path))
    writer.add_topic(NS + "/poses", "robotarium_msgs/msg/RobotPoses", [qos_profile(depth=50)])
    for k in range(messages):
        msg = RobotPoses(step=k, ids=[0, 1], x=[0.01 * k, 1.0], y=[0.0, -0.5], theta=[0.1, 0.2])
        msg.header.stamp.sec, msg.header.stamp.nanosec = 1000 + k, 5
        data = serialize_message(msg)
        writer.write(NS + "/poses", data, 2_000_000_000_000 + k * 1000, stamp_from_cdr(data))
        if k % flush_every == flush_every - 1:
            writer.flush()
    return writer


def test_a_torn_file_gives_back_every_complete_chunk_and_can_be_recovered(tmp_path):
    writer = _write_sample(tmp_path / "run")
    writer.flush()                       # never closed: as a killed recorder leaves it
    mcap_path = os.path.join(writer.path, writer.file_name)
    size = os.path.getsize(mcap_path)
    full = [m.data for m in bagmod.Bag(writer.path).messages()]
    assert len(full) == 300
    for cut in range(40, size, 997):     # cut anywhere: our reader returns a prefix, never fails
        torn = tmp_path / ("torn_%d" % cut)
        shutil.copytree(writer.path, torn)
        with open(os.path.join(torn, writer.file_name), "r+b") as f:
            f.truncate(cut)
        bag = bagmod.Bag(str(torn))
        got = [m.data for m in bag.messages()]
        assert got == full[:len(got)] and bag.truncated
        if cut > size // 2:
            assert len(got) >= 120
            bagmod.recover_bag(str(torn))
            decoded, counts, total = rosbags_messages(str(torn))
            assert total == len(got) == counts[NS + "/poses"]
            assert [p.step for p in decoded[NS + "/poses"]] == list(range(len(got)))


def _torn_bag_filling_its_last_page(path, messages=5):
    """A bag as a full disk leaves it: `messages` chunks, the last one complete and only part of its
    provisional end written, where the file ends exactly at a 4 KiB page boundary (so putting the end
    back needs one more page). Returns (bag dir, mcap path, the messages' data)."""
    from rclpy.serialization import serialize_message
    tail = PROVISIONAL_TAIL

    def write(where, pad):
        writer = BagWriter(where, compression="")
        writer.add_topic(NS + "/poses", "robotarium_msgs/msg/RobotPoses", [qos_profile(depth=50)])
        sent = []
        for k in range(messages):
            msg = RobotPoses(step=k, ids=[0, 1], x=[0.0, 1.0], y=[0.0, 0.5], theta=[0.1, 0.2])
            msg.header.frame_id = "p" * (pad if k == messages - 1 else 0)
            sent.append(serialize_message(msg))
            writer.write(NS + "/poses", sent[-1], 2_000_000_000_000 + k, 2_000_000_000_000 + k)
            writer.flush()
        writer.abandon()   # as the recorder does after a failed write: the file is closed as it is
        mcap_path = os.path.join(writer.path, writer.file_name)
        with open(mcap_path, "rb") as f:
            data = f.read()
        assert data.endswith(tail)
        return writer.path, mcap_path, data[:-len(tail)], sent

    scratch = str(path) + "_probe"
    _, _, body, _ = write(scratch, 0)
    shutil.rmtree(scratch)
    pad = (-(len(body) + 24)) % 4096      # the end's first ~24 bytes written (CDR alignment moves it a little)
    where, mcap_path, body, sent = write(str(path), pad)
    written = -len(body) % 4096
    assert 0 < written < len(tail), (len(body), pad)
    with open(mcap_path, "wb") as f:
        f.write(body + tail[:written])
    return where, mcap_path, sent


def test_a_bag_torn_on_a_full_disk_is_recovered_by_giving_up_its_last_chunk(tmp_path):
    """The recorder's write fails on a full disk after the last chunk but inside its provisional end:
    recover_bag must make the file readable although the end it puts back needs a page the disk no
    longer has (a full-disk CI run left 'File end magic is invalid')."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(disk)], stderr=subprocess.PIPE,
                             text=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here: %s" % mounted.stderr.strip())
    try:
        bag_dir, mcap_path, sent = _torn_bag_filling_its_last_page(disk / "run")
        with open(disk / "filler", "wb", buffering=0) as f:   # fill the disk to its last byte
            for block in (4096, 1):
                try:
                    while f.write(b"\0" * block):
                        pass
                except OSError:
                    pass
        assert os.statvfs(disk).f_bavail == 0 and os.path.getsize(mcap_path) % 4096 == 0

        recovered = bagmod.recover_bag(bag_dir)
        decoded, counts, total = rosbags_messages(bag_dir)   # an independent reader opens it
        got = [m.data for m in recovered.messages()]
        assert len(sent) - 1 <= len(got) <= len(sent) and got == sent[:len(got)], len(got)
        assert total == len(got) == counts[NS + "/poses"]
        assert not os.path.exists(os.path.join(bag_dir, ".metadata.yaml.tmp"))
    finally:
        subprocess.run(["umount", str(disk)])


def test_bag_writer_never_overwrites_and_closes_with_a_summary(tmp_path):
    writer = _write_sample(tmp_path / "run", messages=50)
    with pytest.raises(FileExistsError):
        BagWriter(str(tmp_path / "run"))
    writer.close()
    with open(os.path.join(writer.path, writer.file_name), "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary.statistics.message_count == 50 and summary.chunk_indexes
    bag = bagmod.Bag(writer.path)
    assert bag.complete and bag.topics[NS + "/poses"].count == 50
    assert bag.poses().x.shape == (50, 2)


def test_run_recorder_takes_the_messages_of_each_run(tmp_path):
    """Which messages go into which bag, with publish stamps deciding around start and end."""
    topics = {"/ns/poses": "robotarium_msgs/msg/RobotPoses", "/ns/status": "robotarium_msgs/msg/TestbedStatus",
              "/rosout": "rcl_interfaces/msg/Log"}
    started = []
    rec = RunRecorder(tmp_path, lambda t: (topics[t], []), on_started=started.append, grace_ns=100, live_after_ns=0)
    s = 10**9
    rec.on_message("/ns/poses", b"\x00\x01\x00\x00old", recv_ns=1 * s, pub_ns=1 * s)      # before the run: dropped
    rec.on_message("/ns/poses", b"\x00\x01\x00\x00step0", recv_ns=5 * s, pub_ns=5 * s)    # overtook the status
    rec.on_status("/ns/status", b"\x00\x01\x00\x00run", 6 * s, 5 * s, True, "exp_1")
    rec.on_message("/ns/poses", b"\x00\x01\x00\x00step1", 7 * s, 7 * s)
    rec.on_status("/ns/status", b"\x00\x01\x00\x00idle", 8 * s, 8 * s, False, "exp_1")
    rec.on_message("/ns/poses", b"\x00\x01\x00\x00late", 8 * s + 10, 7 * s + 5)             # published before the end
    rec.on_message("/rosout", b"\x00\x01\x00\x00ended", 8 * s + 20, 8 * s + 15, log_line=True)
    rec.on_message("/ns/poses", b"\x00\x01\x00\x00after", 8 * s + 30, 8 * s + 25)           # after the end
    rec.tick(9 * s)
    assert rec.writer is None and len(started) == 1
    rec.on_status("/ns/status", b"\x00\x01\x00\x00stale", 9 * s, 6 * s, True, "exp_1")     # a late status: no new run
    assert rec.writer is None
    rec.on_status("/ns/status", b"\x00\x01\x00\x00again", 10 * s, 10 * s, True, "exp_1")   # same id, later: a new run
    rec.close()
    assert [os.path.basename(p) for p in started] == ["exp_1", "exp_1_1"]
    first = bagmod.Bag(started[0])
    assert [m.data[4:] for m in first.messages()] == [b"step0", b"run", b"step1", b"idle", b"late", b"ended"]
    assert [m.data[4:] for m in bagmod.Bag(started[1]).messages()] == [b"again"]


def test_run_recorder_keeps_a_closing_bag_open_until_its_last_poses_came(tmp_path):
    """A reliable stream delivers in order: one lost packet holds back every later poses message until
    it is repaired, seconds later for a recorder starved of CPU, and the bag closed at the end of its
    grace without them (a killed script's run had no poses at all). The bag now waits for the poses
    of the step the run's last RUNNING status names, catch_up_ns at most, and says what never came."""
    topics = {"/ns/poses": "robotarium_msgs/msg/RobotPoses", "/ns/status": "robotarium_msgs/msg/TestbedStatus"}
    started, logs = [], []
    rec = RunRecorder(tmp_path, lambda t: (topics[t], []), on_started=started.append, log=logs.append, grace_ns=100,
                      live_after_ns=0, catch_up_ns=1000,
                      run_step_of=lambda topic, data: (None, int(data[5:])) if topic == "/ns/poses" else None)   # b"...p<k>"
    s = 10**9
    for run, last in (("exp_1", 3), ("exp_2", 2)):
        t = s * (10 if run == "exp_2" else 1)
        rec.on_status("/ns/status", b"\x00\x01\x00\x00run", t, t, True, run, step=0)
        rec.on_message("/ns/poses", b"\x00\x01\x00\x00p0", t + 1, t + 1)
        rec.on_status("/ns/status", b"\x00\x01\x00\x00last", t + 10, t + 10, True, run, step=last)
        rec.on_status("/ns/status", b"\x00\x01\x00\x00idle", t + 20, t + 20, False, run, step=0)
        rec.tick(t + 500)   # the grace is over, the poses of steps 1..last are on their way
        assert rec.writer is not None
        if run == "exp_1":
            for k in range(1, last + 1):
                rec.on_message("/ns/poses", b"\x00\x01\x00\x00p%d" % k, t + 600, t + 5)
            rec.tick(t + 700)
        else:   # they never come: closed catch_up_ns after the grace, saying so
            rec.tick(t + 1000)
            assert rec.writer is not None
            rec.tick(t + 1200)
        assert rec.writer is None
    assert [m.data[4:] for m in bagmod.Bag(started[0]).messages()] == [b"run", b"p0", b"last", b"idle", b"p1", b"p2", b"p3"]
    assert "its poses from step 1 on never came (the last is 2)" in logs[-1]


def test_a_whole_lockstep_runs_bag_closes_at_once_and_any_other_after_its_grace(tmp_path):
    """A lockstep run's bag whose last step is all there (poses, the command arrays and the safety report of
    that step, the run's config and experiment) closes lockstep_grace_ns after the run's end, not grace_ns: a
    recorded lockstep run's results waited half a second for messages that could not come. One that lacks any
    of them, and a real-time run's, wait out the grace as before."""
    ns = "/ns"
    steps = ("cmd_requested", "cmd_safe", "safety_report")
    topics = {ns + "/" + t: "robotarium_msgs/msg/TwistArray" for t in steps}
    topics.update({ns + "/poses": "robotarium_msgs/msg/RobotPoses", ns + "/status": "robotarium_msgs/msg/TestbedStatus",
                   ns + "/config": "std_msgs/msg/String", ns + "/experiment": "std_msgs/msg/String",
                   "/rosout": "rcl_interfaces/msg/Log"})
    rec = RunRecorder(tmp_path, lambda t: (topics[t], []), grace_ns=500, lockstep_grace_ns=50, live_after_ns=0, catch_up_ns=1000,
                      run_step_of=lambda topic, data: (None, int(data[5:])) if topic == ns + "/poses" else None,
                      step_of=lambda topic, data: int(data[5:]), step_topics=[ns + "/" + t for t in steps],
                      start_topics=[ns + "/config", ns + "/experiment"])

    def run(t, lockstep=True, leave_out=()):
        """A 3-step run starting at t, its end at t + 100; returns when its bag closed (ns after the end)."""
        rec.on_status(ns + "/status", b"\x00\x01\x00\x00run", t, t, True, "exp_%d" % t, step=0, lockstep=lockstep)
        for name in ("config", "experiment"):
            if name not in leave_out:
                rec.on_message(ns + "/" + name, b"\x00\x01\x00\x00" + name.encode(), t + 1, t + 1)
        for k in range(4):
            if k:
                for name in steps:
                    if (name, k) not in leave_out:
                        rec.on_message(ns + "/" + name, b"\x00\x01\x00\x00s%d" % k, t + 10 * k, t + 10 * k)
            rec.on_message(ns + "/poses", b"\x00\x01\x00\x00p%d" % k, t + 10 * k + 1, t + 10 * k + 1)
            rec.on_status(ns + "/status", b"\x00\x01\x00\x00step", t + 10 * k + 2, t + 10 * k + 2, True, "exp_%d" % t,
                          step=k, lockstep=lockstep)
        rec.on_status(ns + "/status", b"\x00\x01\x00\x00idle", t + 100, t + 100, False, "exp_%d" % t, step=3,
                      lockstep=lockstep)
        rec.on_message("/rosout", b"\x00\x01\x00\x00ended", t + 120, t + 99, log_line=True)   # the end's log line
        for tick in range(t + 110, t + 1000, 10):
            rec.tick(tick)
            if rec.writer is None:
                return tick - (t + 100)
        return None

    assert run(10**9) == 50                                  # whole: closed 50 ns after the end, its log line in it
    assert run(2 * 10**9, lockstep=False) == 500             # real time: the grace
    assert run(3 * 10**9, leave_out=[("cmd_safe", 3)]) == 500          # the last step's safe array never came
    assert run(4 * 10**9, leave_out=[("safety_report", 3)]) == 500
    assert run(5 * 10**9, leave_out=["experiment"]) == 500
    first = bagmod.Bag(os.path.join(tmp_path, "exp_%d" % 10**9))
    assert [m.data[4:] for m in first.messages()][-2:] == [b"idle", b"ended"]


def test_a_2x_runs_bag_waits_for_the_sensor_readings_of_its_last_step(tmp_path):
    """A 2.x run's sensor readings come one a step with its poses. Held back behind a lost packet while the
    recorder was starved, they came 47 steps after the poses, and the lockstep run's bag closed at once
    without them (a whole-suite run at load 35). A run with readings waits for its last step's, as for its
    poses (catch_up_ns more at most, then closed saying which never came); a run without any closes as before."""
    ns = "/ns"
    steps = ("cmd_requested", "cmd_safe", "safety_report", "sensors")
    topics = {ns + "/" + t: "robotarium_msgs/msg/TwistArray" for t in steps}
    topics.update({ns + "/poses": "robotarium_msgs/msg/RobotPoses", ns + "/status": "robotarium_msgs/msg/TestbedStatus",
                   ns + "/config": "std_msgs/msg/String", ns + "/experiment": "std_msgs/msg/String"})
    logs = []
    rec = RunRecorder(tmp_path, lambda t: (topics[t], []), grace_ns=500, lockstep_grace_ns=50, live_after_ns=0,
                      catch_up_ns=1000, log=logs.append,
                      run_step_of=lambda topic, data: (None, int(data[5:])) if topic == ns + "/poses" else None,
                      step_of=lambda topic, data: int(data[5:]), step_topics=[ns + "/" + t for t in steps],
                      start_topics=[ns + "/config", ns + "/experiment"], followed_topics=[ns + "/sensors"])

    def run(t, sensors_until=None, late=()):
        """A 3-step lockstep run from t, its end at t + 100, its readings up to step sensors_until (None: a run
        without any) and those of steps `late` 300 ns after the end; returns when its bag closed (ns after the end)."""
        rec.on_status(ns + "/status", b"\x00\x01\x00\x00run", t, t, True, "exp_%d" % t, step=0, lockstep=True)
        for name in ("config", "experiment"):
            rec.on_message(ns + "/" + name, b"\x00\x01\x00\x00" + name.encode(), t + 1, t + 1)
        for k in range(4):
            for name in steps[:3] if k else ():
                rec.on_message(ns + "/" + name, b"\x00\x01\x00\x00s%d" % k, t + 10 * k, t + 10 * k)
            rec.on_message(ns + "/poses", b"\x00\x01\x00\x00p%d" % k, t + 10 * k + 1, t + 10 * k + 1)
            if sensors_until is not None and k <= sensors_until and k not in late:
                rec.on_message(ns + "/sensors", b"\x00\x01\x00\x00r%d" % k, t + 10 * k + 1, t + 10 * k + 1)
            rec.on_status(ns + "/status", b"\x00\x01\x00\x00step", t + 10 * k + 2, t + 10 * k + 2, True, "exp_%d" % t,
                          step=k, lockstep=True)
        rec.on_status(ns + "/status", b"\x00\x01\x00\x00idle", t + 100, t + 100, False, "exp_%d" % t, step=3,
                      lockstep=True)
        for tick in range(t + 110, t + 2000, 10):
            if tick == t + 400:
                for k in late:
                    rec.on_message(ns + "/sensors", b"\x00\x01\x00\x00r%d" % k, tick, t + 10 * k + 1)
            rec.tick(tick)
            if rec.writer is None:
                return tick - (t + 100)
        return None

    assert run(10**9) == 50                           # no readings: whole at once, as before
    assert run(2 * 10**9, sensors_until=3) == 50      # all of them: whole at once
    assert run(3 * 10**9, sensors_until=3, late=(2, 3)) == 300           # held back: the bag waits for them
    assert [m.data[4:] for m in bagmod.Bag(os.path.join(tmp_path, "exp_%d" % (3 * 10**9))).messages()
            if m.topic == ns + "/sensors"] == [b"r0", b"r1", b"r2", b"r3"]
    assert run(4 * 10**9, sensors_until=1) == 1500    # never come: closed catch_up_ns after the grace, saying so
    assert "its sensors from step 2 on never came (the last is 3)" in logs[-1]


def test_the_first_poses_of_a_restarted_simulators_run_go_into_that_runs_bag(tmp_path):
    """A simulator killed mid-run never ends its run; `up` restarts it and the next run starts. Its step 0 can
    reach the recorder before anything that says the old run is over (the restart's news, a lapse of the
    simulator's presence, the new run's status): it went into the old run's bag, and the new run's results
    said "poses of 1 step(s) are missing from the bag (first: step 0)" (a soak in a whole-suite run). Poses
    name their run: another run's poses newer than this run's start end this run, and wait for their own."""
    topics = {"/ns/poses": "robotarium_msgs/msg/RobotPoses", "/ns/status": "robotarium_msgs/msg/TestbedStatus"}
    started, logs = [], []
    rec = RunRecorder(tmp_path, lambda t: (topics[t], []), on_started=started.append, log=logs.append, grace_ns=100,
                      live_after_ns=0, run_step_of=lambda topic, data: tuple(data[4:].decode().split(":")[:1]) + (
                          int(data[4:].decode().split(":")[1]),) if topic == "/ns/poses" else None)   # b"....run:k"
    s = 10**9
    rec.on_status("/ns/status", b"\x00\x01\x00\x00old", s, s, True, "old", step=0)
    for k in range(3):
        rec.on_message("/ns/poses", b"\x00\x01\x00\x00old:%d" % k, s + k + 1, s + k + 1)
    rec.on_message("/ns/poses", b"\x00\x01\x00\x00older:9", s + 5, s - 7)   # a late one of a run before: not in it
    assert rec.writer is not None   # (the old simulator is killed here; nothing says so yet)
    rec.on_message("/ns/poses", b"\x00\x01\x00\x00new:0", 5 * s, 5 * s)
    assert rec.writer is None and "the simulator began another run (new)" in logs[-1]
    rec.on_status("/ns/status", b"\x00\x01\x00\x00new", 5 * s + 1, 5 * s, True, "new", step=0)
    rec.on_message("/ns/poses", b"\x00\x01\x00\x00new:1", 5 * s + 2, 5 * s + 2)
    rec.close()
    assert [os.path.basename(p) for p in started] == ["old", "new"]
    assert [m.data[4:] for m in bagmod.Bag(started[0]).messages()] == [b"old", b"old:0", b"old:1", b"old:2"]
    assert [m.data[4:] for m in bagmod.Bag(started[1]).messages()] == [b"new:0", b"new", b"new:1"]


def test_a_restarted_recorder_leaves_a_run_from_before_its_restart_alone_and_records_a_later_one_whole(tmp_path):
    """A recorder restarted in place matched a new client's commands before the simulator's status stream
    (a whole-suite run): the first status it heard was of step 3, it took that run for the one it had been
    restarted in and left it alone (no bag: "no recorder was running"). The status says when its run
    started: a run from before the restart is left alone, a later one is recorded from its start, the
    commands that came before its first status heard here included."""
    topics = {"/ns/cmd_requested": "robotarium_msgs/msg/TwistArray", "/ns/status": "robotarium_msgs/msg/TestbedStatus"}
    started, logs = [], []
    s = 10**9
    rec = RunRecorder(tmp_path, lambda t: (topics[t], []), on_started=started.append, log=logs.append,
                      live_after_ns=0, restarted_ns=10 * s)
    rec.on_status("/ns/status", b"\x00\x01\x00\x00b40", 11 * s, 11 * s, True, "before", step=40, started_ns=9 * s)
    rec.on_status("/ns/status", b"\x00\x01\x00\x00b41", 11 * s + 1, 11 * s + 1, True, "before", step=41,
                  started_ns=9 * s)
    assert rec.writer is None and "run before was running at step 40 when this recorder was restarted" in logs[-1]
    rec.on_status("/ns/status", b"\x00\x01\x00\x00b-idle", 11 * s + 2, 11 * s + 2, False, "before", started_ns=9 * s)
    rec.on_message("/ns/cmd_requested", b"\x00\x01\x00\x00c1", 12 * s + 1, 12 * s + 1)
    rec.on_message("/ns/cmd_requested", b"\x00\x01\x00\x00c2", 12 * s + 2, 12 * s + 2)
    rec.on_status("/ns/status", b"\x00\x01\x00\x00a3", 12 * s + 3, 12 * s + 3, True, "after", step=3, started_ns=12 * s)
    rec.close()
    assert [os.path.basename(p) for p in started] == ["after"]
    assert [m.data[4:] for m in bagmod.Bag(started[0]).messages()] == [b"c1", b"c2", b"a3"]


def test_run_recorder_ignores_a_finished_run_handed_over_as_history(tmp_path):
    """Transient-local history arrives when the recorder matches: a run that ended before the
    recorder started is not recorded; one still going is, from its first RUNNING status."""
    started = []
    rec = RunRecorder(tmp_path, lambda t: ("robotarium_msgs/msg/TestbedStatus", []), on_started=started.append,
                      live_after_ns=100)
    rec.on_status("/ns/status", b"\x00\x01\x00\x00a1", 200, 10, True, "old")
    rec.on_status("/ns/status", b"\x00\x01\x00\x00a2", 200, 20, False, "old")     # ended: never recorded
    rec.on_status("/ns/status", b"\x00\x01\x00\x00b1", 201, 50, True, "going")
    rec.on_status("/ns/status", b"\x00\x01\x00\x00b2", 201, 60, True, "going")
    assert rec.writer is None and not started
    rec.on_status("/ns/status", b"\x00\x01\x00\x00b3", 300, 150, True, "going")   # live: record from stamp 50
    rec.close()
    assert [os.path.basename(p) for p in started] == ["going"]
    assert [m.data[4:] for m in bagmod.Bag(started[0]).messages()] == [b"b1", b"b2", b"b3"]


def test_seen_samples_drop_copies_within_their_window_and_reader_kinds_cover_every_writer():
    from robotarium_recording import samples
    seen = samples.SeenSamples(window=3)
    assert [seen.first("/t", k) for k in (1, 2, 1, 3, 4, 1)] == [True, True, False, True, True, True]
    assert seen.first("/u", 2) and seen.copies == 1 and len(seen.topics["/t"][0]) == 3   # bounded, per topic
    one = samples.identity({"source_timestamp": 5, "publication_sequence_number": 2}, b"abc")
    assert one == samples.identity({"source_timestamp": 5, "publication_sequence_number": 2}, b"xyz")   # a copy
    assert len({one, samples.identity({"source_timestamp": 5, "publication_sequence_number": 3}, b"abc"),
                samples.identity({"source_timestamp": 6, "publication_sequence_number": 2}, b"abc"),
                samples.identity({"source_timestamp": 5, "publication_sequence_number": 2}, b"abcd")}) == 4
    assert samples.identity({}, b"abc") is None
    assert samples.reader_kinds([(True, True)]) == {samples.RELIABLE_LATCHED}
    assert samples.reader_kinds([(True, True), (True, False), (False, False)]) == {
        samples.RELIABLE_LATCHED, samples.RELIABLE_VOLATILE, samples.BEST_EFFORT}
