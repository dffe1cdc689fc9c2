"""The live view in Foxglove (./robotarium view, replay --view): a real testbed on its own domain,
the view's Foxglove WebSocket server on a free port, and a client that speaks the SDK's
subprotocol (devtools.foxglove_client), subscribes, and decodes what it gets during a run: the
scene (protobuf, by the schema the server advertised) and the testbed's own messages (CDR, with
rclpy). The scene must show the robots exactly at poses the testbed published.
"""
import json
import os
import re
import subprocess
import sys
import time

import numpy as np
import pytest
from rclpy.serialization import deserialize_message

from devtools.foxglove_client import SUBPROTOCOL, FoxgloveClient
from devtools.rosutil import REPO, NodeProcess, node_env, unique_domain_id
from robotarium_msgs.msg import RobotPoses, TestbedStatus, TwistArray
from robotarium_recording import foxglove_scene
from robotarium_recording.bag import Bag
from robotarium_recording.view_node import LAYOUT_FILE, READY, SCENE, SCENE_DRAWING, layout_text

pytestmark = pytest.mark.node   # real testbed nodes in subprocesses

NS = "/robotarium"
SAMPLE = os.path.join(REPO, "bags", "sample_consensus")
START = [[-0.6, 0.0, 0.6], [-0.3, 0.3, -0.3], [0.0, 0.0, 0.0]]
GOAL = (0.9, 0.6)   # where the script draws a red square

SCRIPT = '''
import numpy as np
import rps.robotarium as robotarium

r = robotarium.Robotarium(number_of_robots=3, show_figure=True, sim_in_real_time=True,
                          initial_conditions=np.array(%r))
r.axes.scatter([%r], [%r], s=2000, marker="s", color="red", zorder=-2)
for _ in range(100):
    r.get_poses()
    r.set_velocities(np.arange(3), np.array([[0.08] * 3, [0.6] * 3]))
    r.step()
r.call_at_scripts_end()
''' % (START, GOAL[0], GOAL[1])


def served_url(process, timeout=90):
    """The ws:// address the view printed (it was started with port 0: any free one)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        match = re.search(re.escape(READY) + r"([0-9.]+):(\d+)", process.output())
        if match:
            return "ws://%s:%s" % match.groups()
        assert process.alive(), "the view ended before it served:\n" + process.output()
        time.sleep(0.2)
    raise AssertionError("the view did not serve within %d s:\n%s" % (timeout, process.output()))


def robots_of(update):
    """{robot id: (x, y, z of the heading quaternion, w, text)} of a decoded SceneUpdate."""
    robots = {}
    for entity in update["entities"]:
        if entity["id"].startswith("robot/"):
            (cylinder,), (text,) = entity["cylinders"], entity["texts"]
            position, orientation = cylinder["pose"]["position"], cylinder["pose"]["orientation"]
            robots[int(entity["id"][len("robot/"):])] = (position["x"], position["y"], orientation["z"],
                                                         orientation["w"], text["text"])
    return robots


def published_at(robots, poses):
    """The poses message (RobotPoses) at which the scene's robots stand exactly, or None."""
    for msg in poses:
        if len(msg.x) == len(robots) and all(
                robots.get(int(i)) is not None and robots[int(i)][:2] == (x, y) and
                np.isclose(robots[int(i)][2], np.sin(t / 2)) and np.isclose(robots[int(i)][3], np.cos(t / 2))
                for i, x, y, t in zip(msg.ids, msg.x, msg.y, msg.theta)):
            return msg
    return None


@pytest.mark.slow
def test_a_foxglove_client_gets_the_live_scene_poses_status_and_commands_during_a_run(tmp_path):
    domain = unique_domain_id()
    scene, grid = NS + "/" + SCENE, NS + "/" + SCENE_DRAWING
    topics = [scene, grid, NS + "/poses", NS + "/status", NS + "/cmd_safe"]
    nodes = [NodeProcess("robotarium_sim.simulator_node", domain, log_path=tmp_path / "sim.log"),
             NodeProcess("robotarium_safety.safety_node", domain, log_path=tmp_path / "safety.log")]
    view = NodeProcess("robotarium_recording.view_node", domain, args=["--port", "0"], log_path=tmp_path / "view.log")
    nodes.append(view)
    client = script = None
    try:
        client = FoxgloveClient(served_url(view), topics)
        assert client.subprotocol == SUBPROTOCOL
        assert client.wait_until(lambda: client.messages[scene], 60), "no scene before the run:\n" + view.output()
        # Before any experiment: the empty arena, and nothing else.
        idle = client.decode(scene, client.messages[scene][0][1])
        assert [e["id"] for e in idle["entities"]] == ["arena"], idle
        assert idle["deletions"][0]["type"] == 1   # ALL: each update is the whole scene

        # the simulator answers (its idle status) before the script looks for a testbed
        assert client.wait_until(lambda: client.messages[NS + "/status"], 60), "no status:\n" + view.output()
        (tmp_path / "script.py").write_text(SCRIPT)
        script = subprocess.Popen([sys.executable, str(tmp_path / "script.py")], env=node_env(domain), cwd=tmp_path,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        output = script.communicate(timeout=240)[0].decode(errors="replace")
        assert script.returncode == 0, output
        statuses = lambda: [deserialize_message(p, TestbedStatus) for _, p in client.messages[NS + "/status"]]  # noqa: E731
        # the closing status (IDLE, the run's outcome) comes through too
        assert client.wait_until(lambda: any(s.state == TestbedStatus.STATE_IDLE and s.run_id for s in statuses()), 30)
    finally:
        if script is not None and script.poll() is None:
            os.killpg(script.pid, 9)
            script.wait()
        if client is not None:
            client.close()
        for node in reversed(nodes):
            node.close()

    channels = client.channels
    assert channels[scene]["schemaName"] == "foxglove.SceneUpdate" and channels[scene]["encoding"] == "protobuf"
    assert channels[grid]["schemaName"] == "foxglove.Grid"
    assert (channels[NS + "/poses"]["encoding"], channels[NS + "/poses"]["schemaEncoding"],
            channels[NS + "/poses"]["schemaName"]) == ("cdr", "ros2msg", "robotarium_msgs/msg/RobotPoses")
    assert "float64[] x" in channels[NS + "/poses"]["schema"]

    # The testbed's own messages, forwarded as their CDR bytes: rclpy reads them.
    poses = [deserialize_message(p, RobotPoses) for _, p in client.messages[NS + "/poses"]]
    run_id = poses[-1].run_id
    run = [p for p in poses if p.run_id == run_id]
    assert run and all(len(p.x) == 3 for p in run)
    assert np.allclose([run[0].x, run[0].y, run[0].theta], START)
    assert any(s.state == TestbedStatus.STATE_RUNNING and s.run_id == run_id and s.number_of_robots == 3
               for s in statuses())
    commands = [deserialize_message(p, TwistArray) for _, p in client.messages[NS + "/cmd_safe"]]
    assert commands and all(len(c.ids) == 3 for c in commands)

    # The scene during the run: three robots, each exactly at a pose the testbed published.
    updates = [client.decode(scene, p) for _, p in client.messages[scene]]
    assert all(u["deletions"] and u["deletions"][0]["type"] == 1 for u in updates)
    shown = [robots_of(u) for u in updates]
    shown = [(u, r) for u, r in zip(updates, shown) if r]
    assert len(shown) >= 2, "the scene never showed the run's robots twice:\n" + view.output()
    for update, robots in shown:
        assert sorted(robots) == [0, 1, 2] and [robots[i][4] for i in range(3)] == ["0", "1", "2"]
        assert published_at(robots, run) is not None, "robots %s at no published pose" % robots
        assert all(e["frame_id"] == foxglove_scene.FRAME for e in update["entities"])
    first, last = shown[0][1], shown[-1][1]
    assert max(abs(first[i][0] - last[i][0]) + abs(first[i][1] - last[i][1]) for i in range(3)) > 0.05, \
        "the robots did not move in the streamed scene"
    trails = [e for e in shown[-1][0]["entities"] if e["id"] == "trails"]
    assert trails and len(trails[0]["lines"]) == 3 and all(len(line["points"]) >= 2 for line in trails[0]["lines"])

    # What the script drew: a red square at GOAL on the arena floor, nothing far from it.
    assert client.messages[grid], "the script's drawing never reached the view:\n" + view.output()
    cells = client.decode(grid, client.messages[grid][-1][1])
    columns, size = cells["column_count"], cells["cell_size"]
    rgba = np.frombuffer(cells["data"], dtype=np.uint8).reshape(-1, columns, 4)
    origin = cells["pose"]["position"]

    def cell(x, y):
        return rgba[int((y - origin["y"]) / size["y"]), int((x - origin["x"]) / size["x"])]
    assert tuple(cell(*GOAL)) == (255, 0, 0, 255), cell(*GOAL)
    assert cell(-1.2, -0.8)[3] == 0


def test_replay_view_streams_a_recorded_run(tmp_path):
    domain = unique_domain_id()
    scene, poses_topic = NS + "/" + SCENE, NS + "/poses"
    replay = NodeProcess("robotarium_recording.replay_node", domain,
                         args=[SAMPLE, "--view", "--view-port", "0", "--loop"], log_path=tmp_path / "replay.log")
    client = None
    try:
        client = FoxgloveClient(served_url(replay), [scene, poses_topic])

        def matched():
            recorded = [deserialize_message(p, RobotPoses) for _, p in client.messages[poses_topic]]
            return any(robots and published_at(robots, recorded) is not None
                       for robots in (robots_of(client.decode(scene, p)) for _, p in client.messages[scene]))
        assert client.wait_until(matched, 90), "no scene at the replayed poses:\n" + replay.output()
    finally:
        if client is not None:
            client.close()
        replay.close(grace=10)
    assert "[replay]" in replay.output()


@pytest.mark.slow
def test_replay_view_played_once_waits_for_a_viewer(tmp_path):
    """Without --loop the replay would be over before anyone opened Foxglove: it says it waits for a
    viewer, waits, and plays the run once a client subscribed, then ends by itself."""
    domain = unique_domain_id()
    scene, poses_topic = NS + "/" + SCENE, NS + "/poses"
    replay = NodeProcess("robotarium_recording.replay_node", domain,
                         args=[SAMPLE, "--view", "--view-port", "0", "--rate", "4"], log_path=tmp_path / "replay.log")
    client = None
    try:
        url = served_url(replay)
        deadline = time.monotonic() + 90
        while "[replay] waiting for a viewer" not in replay.output():
            assert replay.alive() and time.monotonic() < deadline, replay.output()
            time.sleep(0.2)
        assert url in replay.output() and "[replay] done" not in replay.output()
        client = FoxgloveClient(url, [scene, poses_topic])
        last = int(Bag(SAMPLE).poses().steps[-1])

        def steps():
            return [deserialize_message(p, RobotPoses).step for _, p in client.messages[poses_topic]]
        # the viewer gets the run from its first step to its last: it started only once the viewer was there
        assert client.wait_until(lambda: last in steps(), 120), replay.output()
        assert steps()[0] == 0, steps()[:5]
        assert replay.proc.wait(timeout=120) == 0 and "[replay] done" in replay.output()
    finally:
        if client is not None:
            client.close()
        replay.close(grace=10)


def test_the_committed_layout_is_the_views():
    with open(os.path.join(REPO, LAYOUT_FILE)) as f:
        text = f.read()
    assert text == layout_text(NS), "regenerate it: ./robotarium view --layout %s" % LAYOUT_FILE
    layout = json.loads(text)
    three_d = layout["configById"][layout["layout"]["first"]]
    assert three_d["followTf"] == foxglove_scene.FRAME
    assert {NS + "/" + SCENE, NS + "/" + SCENE_DRAWING} <= set(three_d["topics"])
