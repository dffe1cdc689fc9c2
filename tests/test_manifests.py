"""Each package's package.xml declares what its code imports at run time (and nothing it does not),
the requirements files pin every PyPI package that code imports, what running needs (requirements.txt)
brings everything the packages import outside their tests, and every package has one version."""
import ast
import glob
import importlib.metadata
import os
import re
import sys
import xml.etree.ElementTree as ElementTree

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

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
# The sets of .venv, each including the one before: ./robotarium installs the first two for running (the build's
# first), the third too for serve and worker, all for test.
BUILD, RUNNING, PORTAL, EVERYTHING = ("requirements-build.txt", "requirements.txt", "requirements-portal.txt",
                                      "requirements-dev.txt")
# Modules a ROS 2 install brings and the PyPI wheels do not, imported only on the ROS route (never by a
# ./robotarium command): no requirements file can bring them.
ROS_INSTALL_ONLY = {
    "launch": "robotarium_bringup/launch/testbed.launch.py, which ros2 launch reads",
    "launch_ros": "robotarium_bringup/launch/testbed.launch.py, which ros2 launch reads",
    "ros2cli": "robotarium_cli/command/robotarium.py, the ros2 robotarium extension",
}


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


def requirements(name):
    """The requirements of a requirements file in the repository, with those of the files it includes (-r)."""
    found = []
    with open(os.path.join(REPO, name)) as f:
        for line in f:
            line = line.split("#")[0].strip()
            if line.startswith(("-r ", "--requirement")):
                found += requirements(re.split(r"[ =]", line, maxsplit=1)[1].strip())
            elif line:
                found.append(Requirement(line))
    return found


def installed_closure(name):
    """The distributions that installing the requirements file brings: its requirements and theirs (extras
    followed), by the metadata of what is installed here; canonical names."""
    closure, todo = set(), [(r.name, frozenset(r.extras)) for r in requirements(name)]
    while todo:
        dist_name, extras = todo.pop()
        if (canonicalize_name(dist_name), extras) in closure:
            continue
        closure.add((canonicalize_name(dist_name), extras))
        try:
            dist = importlib.metadata.distribution(dist_name)
        except importlib.metadata.PackageNotFoundError:
            raise AssertionError("%s (from %s) is not installed in .venv: ./robotarium test installs every set"
                                 % (dist_name, name)) from None
        for line in dist.requires or []:
            requirement = Requirement(line)
            if requirement.marker is None or any(requirement.marker.evaluate({"extra": e}) for e in extras | {""}):
                todo.append((requirement.name, frozenset(requirement.extras)))
    return {dist_name for dist_name, _ in closure}


def imported_by_files(paths):
    """Top-level modules the Python files import (inside functions too), standard library and setuptools
    left out; module -> the files that import it."""
    modules = {}
    for path in paths:
        with open(path) as f:
            tree = ast.parse(f.read(), path)
        for node in ast.walk(tree):
            names = ([alias.name for alias in node.names] if isinstance(node, ast.Import) else
                     [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else [])
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in SKIP:
                    modules.setdefault(top, []).append(os.path.relpath(path, REPO))
    return modules


def not_brought(modules, requirements_file, first_party):
    """What of `modules` (imported_by_files) the requirements file does not bring, one line each."""
    brought = installed_closure(requirements_file)
    providers = importlib.metadata.packages_distributions()
    problems = []
    for module, files in sorted(modules.items()):
        if module in first_party or module in ROS_INSTALL_ONLY:
            continue
        if module not in providers:
            problems.append("%s imports %s, which no installed distribution provides" % (files[0], module))
        elif not {canonicalize_name(d) for d in providers[module]} & brought:
            problems.append("%s imports %s (distribution %s), which %s does not bring: move it there"
                            % (files[0], module, " or ".join(providers[module]), requirements_file))
    return problems


def first_party():
    """The repository's own top-level modules: the packages (robotarium_msgs's made by the build), their
    Python packages (rps among them), and devtools."""
    return ({"devtools"} | {os.path.basename(p) for p in glob.glob(os.path.join(REPO, "robotarium_*"))}
            | {os.path.basename(os.path.dirname(p)) for p in glob.glob(os.path.join(REPO, "robotarium_*", "*", "__init__.py"))})


def test_what_running_needs_comes_with_requirements_txt():
    """./robotarium demo, run, verify, up, ... install requirements.txt alone: every module the ROS packages
    import outside their tests (inside functions too: a lazy import of a dev-only tool in a run path fails
    here, not on a student's fresh clone) is brought by it, the ROS route's own (ROS_INSTALL_ONLY) aside."""
    paths = [p for package in packages() for p in glob.glob(os.path.join(REPO, package, "**", "*.py"), recursive=True)
             if not p.startswith(os.path.join(REPO, package, "test") + os.sep)]
    modules = imported_by_files(paths)
    assert "rclpy" in modules and "numpy" in modules   # the scan sees the packages
    problems = not_brought(modules, RUNNING, first_party())
    assert not problems, "\n".join(problems)


def test_the_portal_needs_only_the_portal_set():
    """./robotarium serve and worker install requirements-portal.txt (running's set and the portal's stack):
    the portal's modules outside its tests, and those of devtools/ they import, import nothing beyond it (no
    test tool)."""
    portal = os.path.join(REPO, "robotarium_portal")
    paths = [p for p in glob.glob(os.path.join(portal, "**", "*.py"), recursive=True)
             if not p.startswith(os.path.join(portal, "test") + os.sep)]
    modules = imported_by_files(paths)
    assert "django" in modules
    for path in paths:   # devtools.X: devtools/X.py runs in the portal's process too
        with open(path) as f:
            paths_of_devtools = re.findall(r"^\s*from devtools\.(\w+) import", f.read(), re.MULTILINE)
        for module in imported_by_files([os.path.join(REPO, "devtools", m + ".py") for m in paths_of_devtools]).items():
            modules.setdefault(module[0], []).extend(module[1])
    problems = not_brought(modules, PORTAL, first_party())
    assert not problems, "\n".join(problems)


def test_submit_needs_only_what_running_needs():
    """`./robotarium submit` is a student's command: it installs requirements.txt alone, so
    robotarium_portal/submit.py (and the package's __init__) import nothing of the portal's stack."""
    portal = os.path.join(REPO, "robotarium_portal")
    modules = imported_by_files([os.path.join(portal, "__init__.py"), os.path.join(portal, "submit.py")])
    problems = not_brought(modules, RUNNING, first_party())
    assert not problems, "\n".join(problems)


def test_each_set_adds_to_the_one_before():
    """requirements.txt includes requirements-build.txt, requirements-portal.txt requirements.txt,
    requirements-dev.txt the portal's, and no distribution is pinned twice (one version each, in the first
    set that needs it)."""
    names = {name: [canonicalize_name(r.name) for r in requirements(name)]
             for name in (BUILD, RUNNING, PORTAL, EVERYTHING)}
    assert set(names[BUILD]) < set(names[RUNNING]) < set(names[PORTAL]) < set(names[EVERYTHING])
    assert len(names[EVERYTHING]) == len(set(names[EVERYTHING])), names[EVERYTHING]


def test_requirements_pin_every_python_package_the_code_imports():
    pinned = {canonicalize_name(r.name) for r in requirements(EVERYTHING)}
    modules = set().union(*(imported(p, tests) for p in packages() for tests in (False, True)))
    unknown = sorted(m for m in modules if m not in PYTHON_DEPENDENCIES and not m.startswith(("rcl", "robotarium_"))
                     and not m.endswith(("_msgs", "_srvs", "_interfaces")) and m not in ("rps", "launch", "launch_ros",
                                                                             "ament_index_python", "rclpy",
                                                                             "ros2cli"))   # a ROS install's (ros2 robotarium)
    assert not unknown, "imports not mapped in PYTHON_DEPENDENCIES (test_manifests.py): %s" % unknown
    missing = sorted(PYTHON_DEPENDENCIES[m][1] for m in modules if m in PYTHON_DEPENDENCIES
                     and canonicalize_name(PYTHON_DEPENDENCIES[m][1]) not in pinned)
    assert not missing, "no requirements file (requirements.txt for running, -dev.txt for tests) pins %s" % missing


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
