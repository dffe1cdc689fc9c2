"""The testbed as Foxglove draws it in its 3D panel, as data: no rclpy here (the view node,
robotarium_recording.view_node, is the thin shell that feeds this from the testbed's topics).

- `scene_update`: a foxglove.SceneUpdate of the arena (floor and border), each robot (footprint,
  heading, id) and the robots' recent trails, in the `arena` frame, from robotarium_core.scene's
  geometry (the same the simulator's MarkerArray, robotarium_core.markers, is made of). Each update
  first deletes every entity, so it is the whole scene: a run with fewer robots leaves nothing
  behind, and with no poses it is the empty arena.
- `DrawingRaster`: what the script drew on r.axes (robotarium_recording.drawing's state, as the
  video draws it, with the same DrawingPainter) rendered onto the arena and sent as a
  foxglove.Grid of RGBA cells lying on the arena floor. One path for every kind the drawing keeps
  (markers, lines, text, images, patches) and exactly what the video shows, at `DRAWING_CELL`
  metres a cell.
"""
import numpy as np
from foxglove.messages import (
    Color,
    CubePrimitive,
    CylinderPrimitive,
    Grid,
    KeyValuePair,
    LinePrimitive,
    LinePrimitiveLineType,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    TextPrimitive,
    Timestamp,
    Vector2,
    Vector3,
)

from robotarium_core import scene
from robotarium_recording.drawing import DrawingPainter

FRAME = "arena"
ROBOT_HEIGHT = 0.03     # m, the footprint's thickness (as robotarium_core.markers)
ID_SIZE = 0.06          # m, the height of a robot's id label
DRAWING_CELL = 0.005    # m per cell of the script's drawing (640 x 400 cells on the 3.2 m x 2 m arena)
DRAWING_HEIGHT = 0.001  # m above the floor: under the robots and their trails
ROBOT_ENTITY = "robot/%d"   # one entity per robot, by its id


def _timestamp(stamp_ns):
    return Timestamp(int(stamp_ns // 1_000_000_000), int(stamp_ns % 1_000_000_000))


def _colour(rgb, alpha=1.0):
    return Color(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=float(alpha))


def _pose(x, y, z, theta=0.0):
    return Pose(position=Vector3(x=float(x), y=float(y), z=float(z)),
                orientation=Quaternion(x=0.0, y=0.0, z=float(np.sin(theta / 2)), w=float(np.cos(theta / 2))))


def _points(xy, z):
    return [Point3(x=float(x), y=float(y), z=float(z)) for x, y in np.asarray(xy, dtype=float).reshape(-1, 2)]


def scene_update(config, stamp_ns=0, poses=None, ids=None, trails=()):
    """The SceneUpdate of the testbed at `poses` (3 x N, or None: the empty arena) with robot `ids`
    (default 0..N-1) and `trails` (scene.Trails.paths()), stamped `stamp_ns`."""
    stamp = _timestamp(stamp_ns)
    x_min, x_max, y_min, y_max = config.arena
    entities = [SceneEntity(
        timestamp=stamp, frame_id=FRAME, id="arena",
        cubes=[CubePrimitive(pose=_pose((x_min + x_max) / 2, (y_min + y_max) / 2, -0.001),
                             size=Vector3(x=x_max - x_min, y=y_max - y_min, z=0.002),
                             color=_colour((0.94, 0.94, 0.94)))],
        lines=[LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=0.01,
                             points=_points(scene.arena_outline(config.arena), 0.0),
                             color=_colour((0.2, 0.2, 0.2)))])]
    deletions = [SceneEntityDeletion(timestamp=stamp, type=SceneEntityDeletionType.All)]
    if poses is None or len(poses[0]) == 0:
        return SceneUpdate(deletions=deletions, entities=entities)

    poses = np.asarray(poses, dtype=float)
    n = poses.shape[1]
    ids = list(range(n)) if ids is None else [int(i) for i in ids]
    colours = scene.robot_colours(n)
    d = config.robot_diameter
    tips = scene.headings(poses, d / 2)
    for k, (i, rgb) in enumerate(zip(ids, colours)):
        x, y, theta = poses[:, k]
        entities.append(SceneEntity(
            timestamp=stamp, frame_id=FRAME, id=ROBOT_ENTITY % i,
            metadata=[KeyValuePair(key="robot", value=str(i))],
            cylinders=[CylinderPrimitive(pose=_pose(x, y, ROBOT_HEIGHT / 2, theta),
                                         size=Vector3(x=d, y=d, z=ROBOT_HEIGHT), bottom_scale=1.0, top_scale=1.0,
                                         color=_colour(rgb))],
            lines=[LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=0.012,
                                 points=_points(tips[k], ROBOT_HEIGHT + 0.002), color=_colour((1, 1, 1)))],
            texts=[TextPrimitive(pose=_pose(x, y, ROBOT_HEIGHT + 0.04), billboard=True, font_size=ID_SIZE,
                                 color=_colour((0, 0, 0)), text=str(i))]))
    lines = [LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=0.006, points=_points(path, 0.002),
                           color=_colour(rgb, 0.8))
             for path, rgb in zip(trails, colours) if len(path) >= 2]
    if lines:
        entities.append(SceneEntity(timestamp=stamp, frame_id=FRAME, id="trails", lines=lines))
    return SceneUpdate(deletions=deletions, entities=entities)


class DrawingRaster:
    """Renders a drawing.DrawingState onto the arena (matplotlib's Agg, transparent where nothing
    was drawn) and returns it as a foxglove.Grid on the floor of the `arena` frame."""

    DPI = 100

    def __init__(self, arena, cell=DRAWING_CELL):
        # matplotlib when a view shows a drawing, not when the view node starts
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.arena = tuple(float(v) for v in arena)
        x_min, x_max, y_min, y_max = self.arena
        self.cell = cell
        self.columns = max(1, int(round((x_max - x_min) / cell)))
        self.rows = max(1, int(round((y_max - y_min) / cell)))
        figure = Figure(figsize=(self.columns / self.DPI, self.rows / self.DPI), dpi=self.DPI)
        figure.patch.set_alpha(0.0)
        axes = figure.add_axes((0, 0, 1, 1))
        axes.set_xlim(x_min, x_max)
        axes.set_ylim(y_min, y_max)
        axes.set_axis_off()
        axes.patch.set_alpha(0.0)
        self.canvas = FigureCanvasAgg(figure)
        self.painter = DrawingPainter(axes)

    def pixels(self, state):
        """rows x columns x 4 uint8 RGBA (straight alpha), row 0 at the arena's lower edge (y_min)."""
        self.painter.paint(state)
        self.canvas.draw()
        image = np.asarray(self.canvas.buffer_rgba())   # row 0 at the top of the image
        return image[::-1]

    def grid(self, state, stamp_ns=0):
        pixels = self.pixels(state)
        rows, columns = pixels.shape[:2]
        x_min, _, y_min, _ = self.arena
        fields = [PackedElementField(name=name, offset=k, type=PackedElementFieldNumericType.Uint8)
                  for k, name in enumerate(("red", "green", "blue", "alpha"))]
        # the cells span the arena exactly (the canvas may round its size by a pixel)
        size = Vector2(x=(self.arena[1] - x_min) / columns, y=(self.arena[3] - y_min) / rows)
        return Grid(timestamp=_timestamp(stamp_ns), frame_id=FRAME, pose=_pose(x_min, y_min, DRAWING_HEIGHT),
                    column_count=columns, cell_size=size, row_stride=4 * columns, cell_stride=4, fields=fields,
                    data=np.ascontiguousarray(pixels).tobytes())
