"""Which Robotarium API a script is written against: the guide's (rps 0.0.0) or the simulator 2.x's.

The two share the import path (`import rps.robotarium`, `from rps.utilities.X import ...`) but not
everything behind it (2.x's figure default, drive-on phase, sensors, obstacles, `debug()`, and
utilities of the same name with other parameters). So `rps` is set up for one of them when a
script first imports it: explicitly (`./robotarium run --rps 2|guide`, ROBOTARIUM_RPS); else from
the script's source, 2.x when it uses something only 2.x has (`r.debug()`, a 2.x keyword, a sensor
getter, a 2.x constant or a 2.x-only utility); else the guide's. See docs/rps2.md.
"""
import ast
import sys

GUIDE, V2 = "guide", "2"

V2_KEYWORDS = {"skip_initialization", "use_distance_sensors", "obstacles", "show_obstacles", "show_arena_boundaries",
               "show_robot_patches", "show_distance_endpoints", "show_distance_rays"}
V2_ATTRIBUTES = {"get_distances", "get_distance_endpoints", "get_encoders", "get_accelerations", "get_gyros",
                 "get_magnetic_fields", "get_orientations", "BOUNDARIES", "TIME_STEP", "ROBOT_DIAMETER",
                 "MAX_LINEAR_VELOCITY", "_axes_handle"}
V2_NAMES = {"create_pose_controller_hybrid", "create_pose_controller_clf", "create_pose_parking_controller_clf",
            "create_pose_parking_controller_hybrid", "create_uni_position_controller", "create_at_pose",
            "create_at_position", "generate_random_poses", "generate_random_positions", "generate_initial_poses",
            "cycleGL", "create_uni_to_si_mapping", "rotation_matrix", "unique_filename"}


def markers(source):
    """The 2.x-only things a script's source uses (a sorted list of short descriptions)."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            if (isinstance(node.func, ast.Attribute) and node.func.attr == "debug" and not node.args
                    and not node.keywords):
                found.add(".debug()")
            found.update("%s=" % k.arg for k in node.keywords if k.arg in V2_KEYWORDS)
        elif isinstance(node, ast.Attribute) and node.attr in V2_ATTRIBUTES:
            found.add("." + node.attr)
        elif isinstance(node, ast.Name) and node.id in V2_NAMES:
            found.add(node.id)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("rps"):
            found.update(a.name for a in node.names if a.name in V2_NAMES)
            if (node.module or "").startswith("rps.examples"):
                found.add("rps.examples")
    return sorted(found)


def main_script_source():
    """(path, source) of the running __main__ script, or (None, None) (interactive, -c, ...)."""
    path = getattr(sys.modules.get("__main__"), "__file__", None)
    if not path:
        return None, None
    try:
        with open(path, encoding="utf-8") as f:
            return path, f.read()
    except (OSError, UnicodeDecodeError):
        return path, None


def decide(explicit=None):
    """(GUIDE or V2, why) for the running script; explicit: "2", "guide" or "auto"/None."""
    if explicit in (GUIDE, V2):
        return explicit, "chosen explicitly (--rps / ROBOTARIUM_RPS)"
    path, source = main_script_source()
    found = markers(source) if source else []
    if found:
        return V2, "%s uses %s" % (path, ", ".join(found[:4]) + (", ..." if len(found) > 4 else ""))
    return GUIDE, "the default"
