"""Each package's package.xml declares what its code imports at run time (and nothing it does not),
requirements.txt pins every PyPI package that code imports, and every package has one version."""
import ast
import glob
import os
import re
import sys
import xml.etree.ElementTree as ElementTree

from devtools import REPO

# Top-level module -> (rosdep key in package.xml, distribution in requirements.txt or None for a ROS package
# that the ROS wheels bring).
PYTHON_DEPENDENCIES = {
    "numpy": ("python3-numpy", "numpy"),
    "yaml": ("python3-yaml", "PyYAML"),
    "scipy": ("python3-scipy", "scipy"),
    "matplotlib": ("python3-matplotlib", "matplotlib"),
    "osqp": ("python3-osqp-pip", "osqp"),
    "quadprog": ("python3-quadprog-pip", "quadprog"),
    "mcap": ("python3-mcap-pip", "mcap"),
    "rosbags": ("python3-rosbags-pip", "rosbags"),
    "imageio_ffmpeg": ("python3-imageio-ffmpeg-pip", "imageio-ffmpeg"),
    "PIL": ("python3-pil", "pillow"),
    "foxglove": ("python3-foxglove-sdk-pip", "foxglove-sdk"),
    "pytest": ("python3-pytest", "pytest"),
    "hypothesis": ("python3-hypothesis", "hypothesis"),
    "cv2": ("python3-opencv", "opencv-python-headless"),
}
# Declared without an import, and why.
NOT_IMPORTED = {
    ("robotarium_msgs", "rosidl_default_runtime"): "what generated interfaces need at run time",
    ("robotarium_bringup", "robotarium_sim"): "a local testbed and the launch file start the node as a process",
    ("robotarium_bringup", "robotarium_safety"): "a local testbed and the launch file start the node as a process",
    ("robotarium_bringup", "robotarium_recording"): "a local testbed and the launch file start the node as a process",
    ("robotarium_recording", "ffmpeg"): "the video encoder, where the imageio-ffmpeg wheel brings none",
    ("robotarium_recording", "geometry_msgs"): "the recorder imports the class of each recorded topic by name",
    ("robotarium_recording", "sensor_msgs"): "the recorder imports the class of each recorded topic by name",
}
SKIP = {"setuptools"}   # setup.py's own


def packages():
    return sorted(os.path.basename(os.path.dirname(p)) for p in glob.glob(os.path.join(REPO, "*", "package.xml")))


def declared(package, tags=("exec_depend", "depend")):
    root = ElementTree.parse(os.path.join(REPO, package, "package.xml")).getroot()
    return {e.text.strip() for tag in tags for e in root.iter(tag)}


def imported(package, tests=False):
    """Top-level modules that the package's Python files import (inside functions too), but its own;
    with tests, those its tests (<package>/test/) import instead."""
    own = {os.path.basename(os.path.dirname(p)) for p in glob.glob(os.path.join(REPO, package, "*", "__init__.py"))}
    modules = set()
    for path in glob.glob(os.path.join(REPO, package, "**", "*.py"), recursive=True):
        if "/examples/" in path or os.path.basename(path) == "setup.py":
            continue
        if path.startswith(os.path.join(REPO, package, "test") + os.sep) != tests:
            continue
        with open(path) as f:
            tree = ast.parse(f.read(), path)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                modules.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules.add(node.module.split(".")[0])
    # An interface package "imports" the packages whose types its .msg and .srv files use.
    for path in glob.glob(os.path.join(REPO, package, "msg", "*.msg")) + glob.glob(os.path.join(REPO, package, "srv", "*.srv")):
        with open(path) as f:
            modules.update(re.findall(r"^\s*([a-z][a-z0-9_]*)/[A-Z]\w*", f.read(), re.MULTILINE))
    return {m for m in modules if m not in sys.stdlib_module_names and m not in own and m not in SKIP}


def rosdep_key(module):
    return PYTHON_DEPENDENCIES[module][0] if module in PYTHON_DEPENDENCIES else module


def test_every_import_is_declared_and_every_declaration_imported():
    problems = []
    for package in packages():
        keys = {rosdep_key(m) for m in imported(package)}
        problems += ["%s imports %s: add <exec_depend>%s</exec_depend>" % (package, k, k)
                     for k in sorted(keys - declared(package))]
        problems += ["%s declares %s, which nothing in it imports: remove it, or say why in NOT_IMPORTED" % (package, k)
                     for k in sorted(declared(package) - keys) if (package, k) not in NOT_IMPORTED]
        # its own tests (test/, which colcon test runs): what they import beyond the package's own needs
        test_keys = {rosdep_key(m) for m in imported(package, tests=True)} - keys
        problems += ["%s's tests import %s: add <test_depend>%s</test_depend>" % (package, k, k)
                     for k in sorted(test_keys - declared(package, ("test_depend",)))]
        problems += ["%s declares the test dependency %s, which no test of it imports only" % (package, k)
                     for k in sorted(declared(package, ("test_depend",)) - test_keys)]
    assert not problems, "\n".join(problems)


def test_requirements_pin_every_python_package_the_code_imports():
    with open(os.path.join(REPO, "requirements.txt")) as f:
        pinned = {re.split(r"[=<>\[]", line.strip())[0].lower() for line in f if line.strip() and line[0] != "#"}
    modules = set().union(*(imported(p, tests) for p in packages() for tests in (False, True)))
    unknown = sorted(m for m in modules if m not in PYTHON_DEPENDENCIES and not m.startswith(("rcl", "robotarium_"))
                     and not m.endswith(("_msgs", "_srvs")) and m not in ("rps", "launch", "launch_ros",
                                                                             "ament_index_python", "rclpy",
                                                                             "ros2cli"))   # a ROS install's (ros2 robotarium)
    assert not unknown, "imports not mapped in PYTHON_DEPENDENCIES (test_manifests.py): %s" % unknown
    missing = sorted(PYTHON_DEPENDENCIES[m][1] for m in modules if m in PYTHON_DEPENDENCIES
                     and PYTHON_DEPENDENCIES[m][1].lower() not in pinned)
    assert not missing, "requirements.txt lacks %s" % missing


def test_one_version_for_every_package():
    versions = {}
    for package in packages():
        root = ElementTree.parse(os.path.join(REPO, package, "package.xml")).getroot()
        versions[package + "/package.xml"] = root.find("version").text.strip()
        setup = os.path.join(REPO, package, "setup.py")
        if os.path.exists(setup):
            with open(setup) as f:
                versions[package + "/setup.py"] = re.search(r'version="([^"]+)"', f.read()).group(1)
    assert len(set(versions.values())) == 1, versions
    for package in packages():
        with open(os.path.join(REPO, package, "CHANGELOG.rst")) as f:
            assert "\n%s (" % versions[package + "/package.xml"] in f.read(), package


def test_the_ros_route_of_the_readme_works_from_a_plain_shell():
    """`source .venv/bin/activate && source install/setup.bash` in a shell with nothing set gives the
    workspace as a ROS user expects it: our packages on the ament index (what `ros2 run`/`ros2 launch`
    look up), our messages and nodes importable. install/setup.bash once did not exist (only setup.sh)."""
    import subprocess
    assert os.path.isfile(os.path.join(REPO, "install", "setup.bash")), "./robotarium setup makes install/setup.bash"
    probe = ("import rclpy, robotarium_msgs.msg, robotarium_sim.simulator_node; "
             "from ament_index_python.packages import get_package_share_directory as share; "
             "print(share('robotarium_client'))")
    out = subprocess.run(["bash", "-c", "source .venv/bin/activate && source install/setup.bash && python -c \"%s\""
                          % probe], cwd=REPO, env={"HOME": os.environ.get("HOME", "/tmp"), "PATH": "/usr/bin:/bin"},
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == os.path.join(REPO, "install", "share", "robotarium_client")
