"""One testbed per namespace: each simulator, safety node and recorder claims its place.

A node of kind `who` publishes who it is (host, pid, since when, who started it) on the hidden,
latched topic `<ns>/_claim/<who>` and listens there; hearing an *older* node of its kind (an
earlier since, host, testbed pid: a LocalTestbed's nodes share its `since` and pid, so every kind
picks the same survivor) in its domain and namespace, it refuses: exit code 4 and one line naming
it. Nodes wait `DEFAULT.claim_wait` for an older claim before they create anything else, unless
their starter looked already (ENV_CHECKED), and keep listening after. A claim is not
authenticated: a forged older claim keeps a testbed from starting, it cannot take over one.
How it behaves, measured: docs/faults.md#a-second-testbed-a-full-disk-large-data-files.
"""
import json
import os
import socket
import time

from std_msgs.msg import String

from robotarium_core.processes import process_start
from robotarium_core.topics import LATCHED

ENV_SINCE = "ROBOTARIUM_TESTBED_SINCE"       # epoch seconds the testbed started (its nodes share it)
ENV_TESTBED = "ROBOTARIUM_TESTBED_PID"       # pid of the process that started the testbed
ENV_OWNER = "ROBOTARIUM_TESTBED_OWNER"       # how that process was started (./robotarium up, ...)
ENV_CHECKED = "ROBOTARIUM_TESTBED_CHECKED"   # "1": the starter looked for a testbed already: no wait

REFUSED = 4   # the exit code of a node (and of ./robotarium up) that refuses to be a second one
NAMES = {"safety": "safety node"}   # the kinds for people

QOS = LATCHED   # reliable, transient local, depth 1: the claim is handed to whoever joins later


def claim_topic(who):
    return "_claim/" + who


def identity(who):
    """What this process says about itself on its claim topic."""
    return {"who": who, "host": socket.gethostname(), "pid": os.getpid(), "started": process_start(os.getpid()),
            "since": float(os.environ.get(ENV_SINCE) or time.time()),
            "testbed": int(os.environ.get(ENV_TESTBED) or os.getpid()),
            "owner": os.environ.get(ENV_OWNER, "")}


def parse(text):
    """An identity from a claim message, or None for anything malformed (never raises)."""
    try:
        value = json.loads(text)
        started = value.get("started")
        ident = {"who": str(value["who"]), "host": str(value["host"]), "pid": int(value["pid"]),
                 "started": None if started is None else int(started),
                 "since": float(value["since"]), "testbed": int(value["testbed"]),
                 "owner": str(value.get("owner", ""))}
    except (ValueError, TypeError, KeyError, AttributeError):
        return None
    return ident


def order(ident):
    return (ident["since"], ident["host"], ident["testbed"], ident["pid"])


def is_older(other, mine):
    """Whether `other` (another process's identity) came first: then `mine` must give way."""
    same_process = (other["host"], other["pid"]) == (mine["host"], mine["pid"])
    # A node of the same testbed and kind is this node's earlier process, restarted (./robotarium up's
    # supervisor): its claim may still be in discovery's hands for a moment; it never refuses the new one.
    same_testbed = (other["host"], other["testbed"], other["since"]) == (mine["host"], mine["testbed"], mine["since"])
    return not same_process and not same_testbed and order(other) < order(mine)


def describe(ident, ns, domain):
    """One line naming the node that runs."""
    since = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(ident["since"]))
    owner = ", started by %s" % ident["owner"] if ident["owner"] else ""
    return ("a %s already runs in %s on ROS_DOMAIN_ID %s: host %s, pid %d, since %s%s"
            % (NAMES.get(ident["who"], ident["who"]), ns or "/", domain, ident["host"], ident["pid"], since, owner))


def refusal(ident, ns, domain):
    """The line a second node (or ./robotarium up) prints when it refuses to start."""
    return ("not starting a second testbed: %s. Use that one, stop it (./robotarium stop on its host), "
            "or choose another ROBOTARIUM_NAMESPACE or ROS_DOMAIN_ID." % describe(ident, ns, domain))


class Claim:
    """This node's claim on `<ns>/_claim/<who>`; `older` is the identity of an older node of the
    same kind once one was heard (then `on_older(identity)` was called once)."""

    def __init__(self, node, who, on_older=None):
        self.node = node
        self.mine = identity(who)
        self.on_older = on_older
        self.older = None
        topic = claim_topic(who)
        self.publisher = node.create_publisher(String, topic, QOS)
        self.subscription = node.create_subscription(String, topic, self._heard, QOS)
        self.publisher.publish(String(data=json.dumps(self.mine)))

    def _heard(self, msg):
        other = parse(msg.data)
        if other is None or self.older is not None or not is_older(other, self.mine):
            return
        self.older = other
        if self.on_older is not None:
            self.on_older(other)
