"""robotarium status: the testbeds on this machine, and the experiment running on this domain."""
import json
import time

from robotarium_cli.console import seconds
from robotarium_cli.running import finish_unfinished
from robotarium_core import model
from robotarium_core.topics import namespace_from_environment as namespace

HELP = "the testbeds on this machine, and the experiment running on this domain"
DESCRIPTION = ("List the testbeds running on this machine (namespace, ROS_DOMAIN_ID, who started them and when, process "
               "ids, logs) and, where a testbed answers, which experiment runs and since when; also for ROS_DOMAIN_ID "
               "and ROBOTARIUM_NAMESPACE of this shell.")


def add_arguments(parser):
    parser.add_argument("--json", action="store_true", help="print the same as JSON")
    parser.add_argument("--timeout", type=seconds, default=3.0, metavar="S",
                        help="seconds to wait for testbeds to answer (default 3)")


def started_at(run_id):
    """When an experiment started, from its run id (<name>_<YYYYmmdd-HHMMSS>), as a local time."""
    try:
        return time.strptime(run_id.rsplit("_", 1)[-1], "%Y%m%d-%H%M%S")
    except ValueError:
        return None


def ago(seconds):
    seconds = int(max(0, seconds))
    if seconds < 120:
        return "%d s ago" % seconds
    if seconds < 7200:
        return "%d min ago" % (seconds // 60)
    return "%.1f h ago" % (seconds / 3600)


INCOMPLETE = "incomplete: no safety node"   # what status says of a testbed whose safety node does not answer


def _describe_status(msg, safety=True):
    """One line on what a testbed's status says, and the same as a dict (--json); safety: whether
    its safety node answers (without it nothing can run there)."""
    from robotarium_msgs.msg import TestbedStatus
    if msg is None:
        return "no testbed answers", None
    if not safety and msg.state != TestbedStatus.STATE_RUNNING:
        return ("a testbed answers, %s (no experiment can run: start one there, or ./robotarium stop it and "
                "./robotarium up a whole one)" % INCOMPLETE,
                {"running": False, "incomplete": INCOMPLETE, "last_run_id": msg.run_id,
                 "last_end_reason": msg.end_reason})
    if msg.state != TestbedStatus.STATE_RUNNING:
        last = " (the last, %s, %s)" % (msg.run_id, msg.end_reason) if msg.run_id and msg.end_reason else ""
        return ("a testbed answers: no experiment is running%s" % last,
                {"running": False, "last_run_id": msg.run_id, "last_end_reason": msg.end_reason})
    since = started_at(msg.run_id)
    dropped = {name: {reason: int(getattr(counts, reason)) for reason in model.DROP_REASONS if getattr(counts, reason)}
               for name, counts in (("cmd_requested", msg.dropped_cmd_requested), ("cmd_safe", msg.dropped_cmd_safe))}
    info = {"running": True, "experiment": msg.experiment, "run_id": msg.run_id, "mode": msg.mode,
            "number_of_robots": msg.number_of_robots, "step": msg.step, "sim_time": msg.sim_time,
            "since": time.strftime("%Y-%m-%d %H:%M:%S", since) if since else None, "dropped": dropped}
    info.update(holder=msg.holder, waiting=list(msg.waiting))
    text = "experiment %s running since %s: %d robots, %s, step %d (%.1f s of testbed time)%s%s" % (
        msg.run_id, time.strftime("%H:%M:%S", since) + " (%s)" % ago(time.time() - time.mktime(since))
        if since else "?", msg.number_of_robots, msg.mode, msg.step, msg.sim_time,
        ", held by %s" % msg.holder if msg.holder else "",
        "; waiting in line: %s" % "; ".join("%d. %s" % (k, who) for k, who in enumerate(msg.waiting, start=1))
        if msg.waiting else "")
    foreign = ["%s: %s" % (name, ", ".join("%d %s" % (n, reason) for reason, n in counts.items()))
               for name, counts in dropped.items() if counts]
    if foreign:
        text += "; arrays dropped on %s" % "; ".join(foreign)
    return text, info


def fleet_roster(ns, timeout):
    """The roster of a hardware arena in `ns` (its latched `fleet` topic) as lines, or "" (a simulator)."""
    if timeout <= 0:
        return ""
    import json

    from std_msgs.msg import String

    from robotarium_bringup.testbed import probe_node
    from robotarium_core.topics import LATCHED
    heard = []
    with probe_node("robotarium_fleet") as (node, executor):
        node.create_subscription(String, "%s/fleet" % ns.rstrip("/"), lambda msg: heard.append(msg.data), LATCHED)
        deadline = time.monotonic() + timeout
        while not heard and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
    if not heard:
        return ""
    roster = json.loads(heard[-1])
    lines = ["Robots of fleet %s (tracking: %s):" % (roster["fleet"], roster["tracking"])]
    for r in roster["robots"]:
        state = "present and tracked" if r["tracked"] and r["answering"] else ", ".join(
            w for w, bad in (("not tracked", not r["tracked"]), ("not answering", not r["answering"])) if bad)
        lines.append("  %s: %s%s%s" % (r["name"], state, "" if r["battery"] is None else ", battery %.0f %%" % r["battery"],
                                       ", %d poses dropped" % r["dropped"] if r["dropped"] else ""))
    return "\n".join(lines)


def main(args):
    from robotarium_bringup import local_testbeds
    from robotarium_bringup.testbed import testbed_status
    finish_unfinished(quiet=args.json)
    found = local_testbeds.find()
    here = (local_testbeds.domain_id(), namespace())
    # only where a simulator runs can a testbed answer (a probe that gets no answer waits the whole timeout)
    targets = [(t["domain"], t["namespace"], t.get("discovery_range")) for t in found
               if t["domain"] != "?" and any(name.startswith(("simulator", "arena")) for name in t["nodes"])]
    # A safety node in this machine's process table is there; for the others its presence decides.
    safety = {(t["domain"], t["namespace"]): True for t in found if any(name.startswith("safety") for name in t["nodes"])}
    statuses = testbed_status(targets + [(here[0], here[1], None)], timeout=args.timeout, safety=safety)

    def described(key):
        return _describe_status(statuses.get(key), safety.get(key, True))
    if args.json:
        listed = [{k: v for k, v in t.items() if not k.startswith("_")} for t in found]
        for t in listed:
            t["experiment"] = described((t["domain"], t["namespace"]))[1]
        print(json.dumps({"local_testbeds": listed, "here": {
            "domain": here[0], "namespace": here[1], "answers": statuses.get(here) is not None,
            "experiment": described(here)[1]}}, indent=2))
        return 0
    if not found:
        print("No testbed runs on this machine.")
    else:
        print("Testbeds on this machine:")
    for t in found:
        started = ("started %s (%s)" % (time.strftime("%H:%M:%S", time.localtime(t["started"])),
                                        ago(time.time() - t["started"])) if t["started"] else "started ?")
        owner = t.get("owner")
        if owner:
            by = "by %s (pid %d%s)" % (owner["command"], owner["pid"], "" if owner["running"] else
                                       ", gone: its nodes should follow within seconds")
        else:
            by = "not by ./robotarium (ros2 run or a launch file, or left behind by an older version)"
        print("  %s on ROS_DOMAIN_ID %s: %s %s" % (t["namespace"], t["domain"], started, by))
        print("      nodes: %s" % (", ".join("%s %d" % item for item in sorted(t["nodes"].items())) or "none left"))
        if t.get("log_dir"):
            print("      logs:  %s" % t["log_dir"])
        print("      %s" % (described((t["domain"], t["namespace"]))[0]
                             if "simulator" in t["nodes"] or "arena" in t["nodes"]
                             else "no simulator: nothing can run here"))
        print("      stop it: ./robotarium stop --domain %s --namespace %s" % (t["domain"], t["namespace"]))
    local_here = local_testbeds.matching(found, here[1], here[0])
    if statuses.get(here) is not None and any("arena" in t["nodes"] for t in local_here):
        roster = fleet_roster(here[1], timeout=2.0)   # a hardware arena of this machine: its robots
        if roster:
            print(roster)
    print("On ROS_DOMAIN_ID %s, namespace %s (this shell's, where ./robotarium run goes): %s%s" % (
        here[0], here[1], described(here)[0],
        "" if local_here or statuses.get(here) is None else " (not started on this machine)"))
    return 0
