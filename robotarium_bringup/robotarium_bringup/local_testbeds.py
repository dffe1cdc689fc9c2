"""The testbeds running on this machine: what `./robotarium status` lists and `./robotarium stop` stops.

Two sources, so that nothing running is missed: the registry (every LocalTestbed writes a small
JSON file into REGISTRY while it runs: namespace, ROS_DOMAIN_ID, its owner process, when, its node
pids and log folder; one folder per user, shared by every checkout on the machine), and the process
table (every process running a testbed node, with its `__ns:=` and ROS_DOMAIN_ID), which finds
nodes started by `ros2 run` or a launch file and testbeds orphaned by older versions. A process
id is trusted only together with its start time (from /proc), so a reused id is never taken for a
testbed's process, and never signalled.
"""
import json
import os
import signal
import socket
import tempfile
import time

from robotarium_core.processes import process_start

REGISTRY = os.path.join(tempfile.gettempdir(), "robotarium-testbeds-%d" % os.getuid())

# How a node shows in a process's command line: `-m MODULE`, or the installed console script.
NODE_MODULES = {"robotarium_sim.simulator_node": "simulator", "robotarium_safety.safety_node": "safety",
                "robotarium_recording.recorder_node": "recorder", "robotarium_hardware.arena_node": "arena",
                "robotarium_hardware.tag_tracker_node": "tag_tracker"}
NODE_EXECUTABLES = {("robotarium_sim", "simulator"): "simulator", ("robotarium_safety", "safety"): "safety",
                    ("robotarium_sim", "recorder"): "recorder", ("robotarium_recording", "recorder"): "recorder",
                    ("robotarium_hardware", "arena"): "arena", ("robotarium_hardware", "tag_tracker"): "tag_tracker"}


def domain_id(env=None):
    return (env if env is not None else os.environ).get("ROS_DOMAIN_ID", "").strip() or "0"


# -- processes ------------------------------------------------------------------------------------

def process(pid):
    """{"pid", "start"} for a live process, or None."""
    start = process_start(pid)
    return None if start is None else {"pid": pid, "start": start}


def running(proc):
    """Whether the process recorded as `proc` ({"pid", "start"}) still runs (the same one)."""
    if proc is None or proc.get("start") is None:
        return False
    return process_start(proc["pid"]) == proc["start"]


def _read(path, binary=False):
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return None
    return data if binary else data.decode(errors="replace")


def node_of(argv):
    """The testbed node a command line runs ("simulator", "safety", "recorder"), or None."""
    for i, arg in enumerate(argv[:4]):
        if arg == "-m" and i + 1 < len(argv) and argv[i + 1] in NODE_MODULES:
            return NODE_MODULES[argv[i + 1]]
        parts = arg.split("/")
        if len(parts) >= 2 and (parts[-2], parts[-1]) in NODE_EXECUTABLES:
            return NODE_EXECUTABLES[(parts[-2], parts[-1])]
    return None


def scan_nodes():
    """Every testbed node process of this user on this machine: [{"pid", "start", "node",
    "namespace", "domain", "discovery_range"}]. Empty where there is no /proc."""
    found = []
    if not os.path.isdir("/proc"):
        return found
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        pid = int(entry)
        raw = _read("/proc/%d/cmdline" % pid, binary=True)
        if not raw:
            continue
        argv = raw.decode(errors="replace").split("\0")
        node = node_of(argv)
        if node is None:
            continue
        start = process_start(pid)
        if start is None:
            continue
        ns = "/robotarium"
        for arg in argv:
            if arg.startswith("__ns:="):
                ns = "/" + arg[len("__ns:="):].strip("/")
        environ = _read("/proc/%d/environ" % pid, binary=True)
        env = dict(item.split("=", 1) for item in (environ or b"").decode(errors="replace").split("\0") if "=" in item)
        found.append({"pid": pid, "start": start, "node": node, "namespace": ns,
                      "domain": domain_id(env) if environ is not None else "?",
                      "discovery_range": env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")})
    return found


# -- the registry ---------------------------------------------------------------------------------

def register(testbed, owner_command):
    """Write the registry entry of a started LocalTestbed; returns its path."""
    os.makedirs(REGISTRY, exist_ok=True)
    entry = {
        "namespace": testbed.ns,
        "domain": domain_id(),
        "discovery_range": os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", ""),
        "owner": dict(process(os.getpid()) or {"pid": os.getpid(), "start": 0}, command=owner_command),
        "started": time.time(),
        "log_dir": os.path.abspath(testbed.log_dir),
        "bags_dir": os.path.abspath(testbed.bags_dir) if testbed.bags_dir else "",
        # what the testbed judges by: the checkout it runs from, its configuration file ("": the packaged
        # one), hardware-like or not, a fleet (./robotarium verify takes a warm testbed only where they match)
        "root": testbed.root,
        "config_file": os.path.abspath(testbed.config_file) if testbed.config_file else "",
        "hardware": bool(testbed.hardware),
        "fleet_file": testbed.fleet_file or "",
        "nodes": {name: process(p.pid) or {"pid": p.pid, "start": None} for name, (p, _) in testbed.processes.items()},
    }
    path = os.path.join(REGISTRY, "%s_%s_%d_%d.json" % (
        testbed.ns.strip("/").replace("/", "-") or "root", entry["domain"], os.getpid(), id(testbed)))
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(entry, f, indent=2)
    os.replace(tmp, path)
    return path


def unregister(path):
    try:
        os.remove(path)
    except (OSError, TypeError):
        pass


def registered():
    """[(path, entry)] of the registry, stale entries (every process gone) removed."""
    entries = []
    try:
        names = sorted(os.listdir(REGISTRY))
    except FileNotFoundError:
        return entries
    for name in names:
        path = os.path.join(REGISTRY, name)
        if not name.endswith(".json"):
            continue
        try:
            with open(path) as f:
                entry = json.load(f)
        except (OSError, ValueError):
            continue
        if running(entry["owner"]) or any(running(p) for p in entry["nodes"].values()):
            entries.append((path, entry))
        else:
            unregister(path)
    return entries


def find():
    """The testbeds on this machine, each {"namespace", "domain", "nodes": {name: pid}, and, for
    registered ones, "owner" {"pid", "command", "running"}, "started", "log_dir", "registry"}."""
    nodes = scan_nodes()
    testbeds, claimed = [], set()
    for path, entry in registered():
        live = {name: p["pid"] for name, p in entry["nodes"].items() if running(p)}
        claimed.update((p["pid"], p["start"]) for p in entry["nodes"].values())
        testbeds.append({"namespace": entry["namespace"], "domain": entry["domain"],
                         "discovery_range": entry.get("discovery_range", ""),
                         "owner": dict(entry["owner"], running=running(entry["owner"])),
                         "started": entry["started"], "log_dir": entry["log_dir"], "bags_dir": entry["bags_dir"],
                         "nodes": live, "registry": path, "_procs": entry["nodes"]})
    groups = {}
    for n in nodes:
        if (n["pid"], n["start"]) in claimed:
            continue
        group = groups.setdefault((n["namespace"], n["domain"]), {
            "namespace": n["namespace"], "domain": n["domain"], "discovery_range": n["discovery_range"],
            "owner": None, "started": None, "log_dir": "", "nodes": {}, "_procs": {}})
        key = n["node"] if n["node"] not in group["nodes"] else "%s-%d" % (n["node"], n["pid"])
        group["nodes"][key] = n["pid"]
        group["_procs"][key] = {"pid": n["pid"], "start": n["start"]}
        started = time.time() - _age(n["start"]) if _age(n["start"]) is not None else None
        group["started"] = min(filter(None, (group["started"], started)), default=None)
    return testbeds + sorted(groups.values(), key=lambda g: (g["domain"], g["namespace"]))


def _age(start_ticks):
    """Seconds since a process started, from its start time in clock ticks since boot."""
    uptime = _read("/proc/uptime")
    if not uptime or not start_ticks:
        return None
    return max(0.0, float(uptime.split()[0]) - start_ticks / os.sysconf("SC_CLK_TCK"))


def matching(testbeds, namespace=None, domain=None):
    return [t for t in testbeds if (namespace is None or t["namespace"] == namespace)
            and (domain is None or t["domain"] == str(domain))]


def running_here(namespace, domain):
    """The testbed of this machine with a live node in `namespace` on `domain`, as the identity a
    node claims its place with (robotarium_core.claim: who, host, pid, since, testbed, owner), or
    None. Where discovery reaches this machine only, this is the whole answer, at once."""
    for testbed in matching(find(), namespace, domain):
        if not testbed["nodes"]:
            continue
        who = next((name for name in ("simulator", "arena", "safety", "recorder") if name in testbed["nodes"]),
                   sorted(testbed["nodes"])[0])
        owner = testbed["owner"] or {}
        return {"who": who.split("-")[0], "host": socket.gethostname(), "pid": testbed["nodes"][who],
                "since": testbed["started"] or 0.0, "testbed": owner.get("pid", testbed["nodes"][who]),
                "owner": "%s (pid %d)" % (owner["command"], owner["pid"]) if owner.get("command") else ""}
    return None


# -- stopping -------------------------------------------------------------------------------------

def _signal(proc, sig):
    """Send `sig` to a recorded process if it is still that process."""
    if running(proc):
        try:
            os.kill(proc["pid"], sig)
        except ProcessLookupError:
            pass


def _wait_gone(procs, timeout):
    deadline = time.monotonic() + timeout
    while any(running(p) for p in procs) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not any(running(p) for p in procs)


def stop(testbed, grace=15.0):
    """Stop a testbed found by find(), as cleanly as it allows: its owner (`./robotarium run` or
    `up`) gets SIGTERM and stops its script and nodes itself; nodes without a running owner get
    SIGTERM (each ends its experiment and the recorder closes the bag); whatever still runs after
    `grace` seconds gets SIGKILL. Returns "stopped" or "killed"."""
    procs = list(testbed["_procs"].values())
    owner = testbed.get("owner")
    if owner and owner.get("running"):
        _signal(owner, signal.SIGTERM)
        if _wait_gone(procs + [owner], grace):
            return "stopped"
    for p in procs:
        _signal(p, signal.SIGTERM)
    if _wait_gone(procs, grace / 2):
        return "stopped"
    for p in procs + ([owner] if owner and owner.get("running") else []):
        _signal(p, signal.SIGKILL)
    _wait_gone(procs, 2.0)
    if testbed.get("registry"):
        unregister(testbed["registry"])
    return "killed"
