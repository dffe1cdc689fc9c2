"""robotarium end: end your experiment running on the testbed and print its report."""
import os
import time

from robotarium_cli.console import say, seconds
from robotarium_cli.verb.status import ago, started_at
from robotarium_core.topics import namespace_from_environment as namespace

HELP = "end your experiment running on the testbed and print its report"
DESCRIPTION = ("End your experiment running in ROBOTARIUM_NAMESPACE on ROS_DOMAIN_ID (on any machine of the domain: "
               "yours when its client runs as your user on this host) and print its debug report and where it was "
               "recorded; its script stops with exit code 4. Someone else's is not ended: end says whose it is "
               "(user@host, pid, script, run, since when) and that --force ends it anyway. The testbed keeps running "
               "for the next experiment.")


def add_arguments(parser):
    parser.add_argument("--force", action="store_true", help="end it whoever's it is (the operator's override)")
    parser.add_argument("--timeout", type=seconds, default=10.0, metavar="S",
                        help="seconds to wait for the testbed (default 10)")


def _holder_parts(holder):
    """("user@host", "pid N", "script") of a StartExperiment.holder ("user@host pid N script.py")."""
    words = holder.split(None, 3)
    if len(words) == 4 and words[1] == "pid":
        return words[0], "pid " + words[2], words[3]
    return holder, "", ""


def main(args):
    """Ends your own experiment: the one whose client runs as this user on this host (its holder,
    robotarium_client.testbed_link.holder_of_this_process). Another's is refused here, naming whose it is,
    unless --force (the operator's override). The check is a courtesy, not a lock: the testbed
    itself refuses only requests without the client's token and without force."""
    from robotarium_bringup.testbed import end_experiment, testbed_status
    from robotarium_client.testbed_link import holder_of_this_process
    from robotarium_core import outcomes
    from robotarium_msgs.msg import TestbedStatus
    ns = namespace()
    force, outcome, detail = args.force, outcomes.NONE, ""
    if not force:
        here = (os.environ.get("ROS_DOMAIN_ID", "0").strip() or "0", ns)
        msg = testbed_status([(here[0], ns, None)], timeout=args.timeout).get(here)
        if msg is None:
            say("no testbed answers in %s on ROS_DOMAIN_ID %s; ./robotarium status shows what runs where" % here[::-1])
            return 1
        if msg.state != TestbedStatus.STATE_RUNNING:
            say("no experiment is running in %s: nothing to end" % ns)
            return 1
        me = _holder_parts(holder_of_this_process())[0]
        who, pid, script = _holder_parts(msg.holder)
        since = started_at(msg.run_id)
        if who != me:
            say("experiment %s is not yours: it is held by %s (%s%s), run %s since %s, step %d. It ends when its "
                "client ends it or is gone; ./robotarium end --force ends it anyway (the operator's override)." % (
                    msg.run_id, who or "a client that did not say who it is", pid or "pid ?",
                    ", script %s" % script if script else "", msg.run_id,
                    time.strftime("%H:%M:%S", since) + " (%s)" % ago(time.time() - time.mktime(since))
                    if since else "?", msg.step))
            return 1
        # Yours (this user on this host): ended as an operator would, saying by whom.
        force, outcome = True, outcomes.INTERRUPTED
        detail = "ended by its user (%s) with ./robotarium end" % me
    try:
        response = end_experiment(ns, timeout=args.timeout, force=force, outcome=outcome, detail=detail)
    except TimeoutError as error:
        say("%s; ./robotarium status shows what runs where" % error)
        return 1
    if not response.success:
        say("could not end the experiment in %s: %s" % (ns, response.message))
        return 1
    print(response.report, end="")
    print("Run %s %s; %s" % (
        response.run_id, response.end_reason, "recorded in %s" % response.recording if response.recording
        else "not recorded (no recorder was running)"))
    return 0
