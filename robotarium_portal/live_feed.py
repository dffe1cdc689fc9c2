"""The live view's feed: inside a run's job box, beside its testbed, the poses and the script's drawing
as they come, appended to a file of the run's folder that the portal streams to the browser.

    python -m robotarium_portal.live_feed FILE      (the run's job starts it; it ends with the job)

One JSON object a line: {"t": wall time, "step": k, "x": [...], "y": [...], "th": [...]} for each poses
message, and {"t": ..., "drawing": "data:image/png;base64,..."} (the script's figure on the arena, as
the video draws it: robotarium_recording.foxglove_scene.DrawingRaster) whenever it changed, at most
DRAWING_RATE a second. The file is on the data folder, so a portal on another machine reads it too.
"""
import base64
import io
import json
import sys
import time

DRAWING_RATE = 2.0   # drawings rendered a second at most (each a PNG of the arena)


def main(path):
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from robotarium_core.config import TestbedConfig
    from robotarium_core.dds_settings import init_context
    from robotarium_core.topics import DEFAULT_NAMESPACE, DRAWING, POSES
    from robotarium_msgs.msg import RobotPoses
    from robotarium_recording.drawing import DrawingState
    from robotarium_recording.foxglove_scene import DrawingRaster

    context = init_context()
    node = Node("live_feed", namespace="/" + DEFAULT_NAMESPACE, context=context)
    config = TestbedConfig.load()
    raster, state = DrawingRaster(config.arena), DrawingState()
    changed, drawn_at = [False], [0.0]
    out = open(path, "a", buffering=1)

    def poses(msg):
        out.write(json.dumps({"t": round(time.time(), 3), "step": msg.step, "x": [round(v, 4) for v in msg.x],
                              "y": [round(v, 4) for v in msg.y], "th": [round(v, 4) for v in msg.theta]}) + "\n")
        if changed[0] and time.monotonic() - drawn_at[0] >= 1.0 / DRAWING_RATE:
            changed[0], drawn_at[0] = False, time.monotonic()
            out.write(json.dumps({"t": round(time.time(), 3), "drawing": png(raster.pixels(state))}) + "\n")

    def drawing(msg):
        state.apply(json.loads(msg.data))
        changed[0] = True

    # As a viewer subscribes (robotarium_recording.view_node): the poses from now on, the drawing's history.
    node.create_subscription(RobotPoses, POSES, poses, QoSProfile(
        depth=50, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE))
    node.create_subscription(String, DRAWING, drawing, QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    try:
        _spin(node, context)
    finally:
        out.close()


def _spin(node, context):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    while rclpy.ok(context=context):
        executor.spin_once(timeout_sec=0.5)


def png(pixels):
    from PIL import Image
    buffer = io.BytesIO()
    Image.fromarray(pixels[::-1]).save(buffer, format="PNG")   # row 0 at the top, as an image's
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode()


if __name__ == "__main__":
    main(sys.argv[1])
