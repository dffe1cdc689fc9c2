"""robotarium stop: stop a testbed running on this machine."""
from robotarium_cli.console import say
from robotarium_core.topics import namespace_from_environment as namespace

HELP = "stop a testbed running on this machine (e.g. one left behind)"
DESCRIPTION = ("Stop the testbed running on this machine in a namespace and domain (default: ROBOTARIUM_NAMESPACE and "
               "ROS_DOMAIN_ID of this shell): its owner (./robotarium run or up) is asked to stop, else its nodes are; "
               "each ends its experiment and closes its recording. Whatever is left after 15 s is killed.")


def add_arguments(parser):
    parser.add_argument("--namespace", help="the testbed's namespace (default: $ROBOTARIUM_NAMESPACE or /robotarium)")
    parser.add_argument("--domain", type=int, help="the testbed's ROS_DOMAIN_ID (default: $ROS_DOMAIN_ID or 0)")
    parser.add_argument("--all", action="store_true", help="every testbed on this machine")


def running_experiments(targets):
    """{(domain, namespace): the run id of the experiment running there} for the testbeds `targets`
    (local_testbeds entries), from their status topics: what stopping them will end."""
    from robotarium_bringup.testbed import testbed_status
    from robotarium_msgs.msg import TestbedStatus
    status = testbed_status([(str(t["domain"]), t["namespace"], None) for t in targets], timeout=2.0)
    return {key: msg.run_id for key, msg in status.items() if msg is not None and msg.state == TestbedStatus.STATE_RUNNING}


def main(args):
    from robotarium_bringup import local_testbeds
    found = local_testbeds.find()
    if args.all:
        targets = found
        where = "on this machine"
    else:
        ns = "/" + args.namespace.strip("/") if args.namespace else namespace()
        domain = str(args.domain) if args.domain is not None else local_testbeds.domain_id()
        targets = local_testbeds.matching(found, ns, domain)
        where = "in %s on ROS_DOMAIN_ID %s on this machine" % (ns, domain)
    if not targets:
        say("no testbed runs %s; nothing to stop%s" % (where, " (./robotarium status lists them)" if found else ""))
        return 1
    running = running_experiments(targets)
    for t in targets:
        owner = t.get("owner")
        run_id = running.get((str(t["domain"]), t["namespace"]))
        say("stopping the testbed in %s on ROS_DOMAIN_ID %s (%s)" % (
            t["namespace"], t["domain"], "via its owner, pid %d: %s" % (owner["pid"], owner["command"])
            if owner and owner["running"] else "nodes %s" % ", ".join(str(p) for p in t["nodes"].values())))
        how = local_testbeds.stop(t)
        if how != "stopped":
            say("killed: it did not stop within the grace period (its recording may need ./robotarium report)")
        else:
            say("stopped: experiment %s ended, its recording closed" % run_id if run_id else
                "stopped (no experiment was running)")
    return 0
