"""The testbed as a visualization_msgs/MarkerArray (robotarium_core.scene's geometry), which RViz
and Foxglove draw with no configuration: the arena (floor and border), each robot's footprint, its
heading and its id, and the robots' recent trails, all in the `arena` frame.

Built straight as CDR bytes with numpy (robotarium_core.cdr.MARKER): rclpy's Python objects cost
~140 ms to build and ~90 ms to serialize for 50 robots with trails, this ~5 ms. Each array starts
with DELETEALL, so it is the whole scene: a run with fewer robots leaves nothing behind, and an
idle testbed is the empty arena.
"""
import numpy as np

from robotarium_core import cdr, scene

TYPE = "visualization_msgs/msg/MarkerArray"
FRAME = "arena"
ROBOT_HEIGHT = 0.03   # m, the footprint disc's thickness (the GTernal is ~7 cm tall; thin keeps the top view clear)
# visualization_msgs/Marker's constants
CUBE, CYLINDER, LINE_STRIP, LINE_LIST, TEXT_VIEW_FACING = 1, 3, 4, 5, 9
ADD, DELETEALL = 0, 3


def _rgba(rgb, alpha=1.0):
    return dict(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=float(alpha))


def _xyz(xy, z):
    """k x 2 -> k x 3 points at height z."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return np.column_stack((xy, np.full(len(xy), z)))


def marker_array(config, stamp_ns=0, poses=None, ids=None, trails=()):
    """The serialized MarkerArray of the scene at `poses` (3 x N, or None: the empty arena) with
    robot `ids` (default 0..N-1) and `trails` (scene.Trails.paths()), stamped `stamp_ns`."""
    head = dict(sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000), frame_id=FRAME)
    x_min, x_max, y_min, y_max = config.arena
    out = [
        dict(head, action=DELETEALL),
        dict(head, ns="arena", id=0, type=CUBE, x=(x_min + x_max) / 2, y=(y_min + y_max) / 2, z=-0.002,
             scale_x=x_max - x_min, scale_y=y_max - y_min, scale_z=0.002, **_rgba((0.94, 0.94, 0.94))),
        dict(head, ns="arena", id=1, type=LINE_STRIP, scale_x=0.01, points=_xyz(scene.arena_outline(config.arena), 0.0),
             **_rgba((0.2, 0.2, 0.2))),
    ]
    if poses is None or len(poses[0]) == 0:
        return cdr.build_sequence(cdr.MARKER, out)

    poses = np.asarray(poses, dtype=float)
    n = poses.shape[1]
    ids = list(range(n)) if ids is None else [int(i) for i in ids]
    colours = scene.robot_colours(n)
    d = config.robot_diameter
    for i, x, y, rgb in zip(ids, poses[0].tolist(), poses[1].tolist(), colours):
        out.append(dict(head, ns="robots", id=i, type=CYLINDER, x=x, y=y, z=ROBOT_HEIGHT / 2,
                        scale_x=d, scale_y=d, scale_z=ROBOT_HEIGHT, **_rgba(rgb)))
        out.append(dict(head, ns="ids", id=i, type=TEXT_VIEW_FACING, x=x, y=y, z=ROBOT_HEIGHT + 0.04, scale_z=0.06,
                        text=str(i), **_rgba((0, 0, 0))))
    out.append(dict(head, ns="headings", id=0, type=LINE_LIST, scale_x=0.012, **_rgba((1, 1, 1)),
                    points=_xyz(scene.headings(poses, d / 2), ROBOT_HEIGHT + 0.002)))
    segments, segment_colours = [], []
    for path, rgb in zip(trails, colours):
        if len(path) >= 2:
            pairs = np.repeat(path, 2, axis=0)[1:-1]   # p0 p1 p1 p2 ...: consecutive points as segments
            segments.append(pairs)
            segment_colours.append(np.tile(np.append(rgb, 0.8), (len(pairs), 1)))
    if segments:
        out.append(dict(head, ns="trails", id=0, type=LINE_LIST, scale_x=0.006, **_rgba((0.5, 0.5, 0.5)),
                        points=_xyz(np.concatenate(segments), 0.001), colors=np.concatenate(segment_colours)))
    return cdr.build_sequence(cdr.MARKER, out)
