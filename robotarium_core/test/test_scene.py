"""What viewers draw (robotarium_core.scene, robotarium_core.markers): plain geometry, and the
MarkerArray RViz and Foxglove get from the simulator."""
import numpy as np
from rclpy.serialization import deserialize_message
from visualization_msgs.msg import Marker, MarkerArray

from robotarium_core import markers, scene
from robotarium_core.config import DEFAULT


def test_arena_outline_is_the_closed_border():
    outline = scene.arena_outline(DEFAULT.arena)
    assert outline.shape == (5, 2) and np.array_equal(outline[0], outline[-1])
    assert set(map(tuple, outline)) == {(-1.6, -1.0), (1.6, -1.0), (1.6, 1.0), (-1.6, 1.0)}


def test_headings_point_along_theta():
    poses = np.array([[0.0, 1.0], [0.0, -0.5], [0.0, np.pi / 2]])
    segments = scene.headings(poses, 0.055)
    assert segments.shape == (2, 2, 2)
    assert np.allclose(segments[:, 0], poses[:2].T)
    assert np.allclose(segments[0, 1], [0.055, 0.0]) and np.allclose(segments[1, 1], [1.0, -0.445])


def test_trails_keep_the_last_seconds_thinned_and_end_at_the_newest_pose():
    trails = scene.Trails(seconds=1.0, time_step=0.01, points=20)   # 100 steps, one kept every 5
    assert trails.paths() == []
    for step in range(0, 301):
        trails.add(step, np.array([[step * 0.01, -step * 0.01], [0.0, 0.0], [0.0, 0.0]]))
    a, b = trails.paths()
    assert len(a) <= 21 and np.isclose(a[-1, 0], 3.0) and np.isclose(b[-1, 0], -3.0)
    assert a[0, 0] >= 2.0 - 1e-9                         # nothing older than a second of testbed time
    assert np.all(np.diff(a[:, 0]) > 0)                  # oldest first
    # a run with another number of robots, or steps starting over, starts afresh
    trails.add(0, np.zeros((3, 3)))
    assert [len(p) for p in trails.paths()] == [1, 1, 1]
    trails.add(1, np.ones((3, 3)))
    trails.add(0, np.full((3, 3), 2.0))
    assert [p.tolist() for p in trails.paths()] == [[[2.0, 2.0]]] * 3


def test_marker_array_draws_arena_robots_headings_ids_and_trails():
    poses = np.array([[-0.5, 0.5], [0.2, -0.2], [0.0, np.pi]])
    trails = scene.Trails(5.0, DEFAULT.time_step)
    trails.add(0, poses - [[0.1], [0.0], [0.0]])
    trails.add(1, poses)
    data = markers.marker_array(DEFAULT, 1_500_000_123, poses, trails=trails.paths())
    array = deserialize_message(data, MarkerArray)   # our CDR bytes are an ordinary MarkerArray
    first, *rest = array.markers
    assert first.action == Marker.DELETEALL            # each array is the whole scene
    assert all(m.header.frame_id == "arena" and (m.header.stamp.sec, m.header.stamp.nanosec) == (1, 500_000_123)
               for m in array.markers)
    by_ns = {}
    for m in rest:
        by_ns.setdefault(m.ns, []).append(m)
    assert sorted(by_ns) == ["arena", "headings", "ids", "robots", "trails"]
    bodies = sorted(by_ns["robots"], key=lambda m: m.id)
    assert [(m.type, m.id) for m in bodies] == [(Marker.CYLINDER, 0), (Marker.CYLINDER, 1)]
    assert [(m.pose.position.x, m.pose.position.y) for m in bodies] == [(-0.5, 0.2), (0.5, -0.2)]
    assert all(m.scale.x == m.scale.y == DEFAULT.robot_diameter and m.pose.orientation.w == 1.0 for m in bodies)
    assert [(round(m.color.r, 3), round(m.color.g, 3)) for m in bodies] == [(0.122, 0.467), (1.0, 0.498)]
    assert sorted(m.text for m in by_ns["ids"]) == ["0", "1"]
    tips = [(p.x, p.y) for p in by_ns["headings"][0].points][1::2]
    assert np.allclose(tips, [(-0.5 + 0.055, 0.2), (0.5 - 0.055, -0.2)])
    trail = by_ns["trails"][0]
    assert trail.type == Marker.LINE_LIST and len(trail.points) == 4 and len(trail.colors) == 4
    assert [(p.x, p.y) for p in trail.points[:2]] == [(-0.6, 0.2), (-0.5, 0.2)]   # robot 0: from where it was
    border = next(m for m in by_ns["arena"] if m.type == Marker.LINE_STRIP)
    assert [(p.x, p.y) for p in border.points] == [tuple(c) for c in scene.arena_outline(DEFAULT.arena)]


def test_an_idle_testbed_is_the_empty_arena():
    array = deserialize_message(markers.marker_array(DEFAULT), MarkerArray)
    assert [m.action for m in array.markers][0] == Marker.DELETEALL
    assert {m.ns for m in array.markers[1:]} == {"arena"}
