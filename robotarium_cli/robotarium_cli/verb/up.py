"""robotarium up: start the testbed nodes; they run as long as this command does, each restarted where it exits
on its own (robotarium_bringup.supervisor), the restart announced to the run in progress (robotarium_core.restarts)."""
import os
import time

import robotarium_recording as recording
from robotarium_bringup import supervisor
from robotarium_bringup.testbed import ANNOUNCED, LocalTestbed, RestartAnnouncer, running_testbed
from robotarium_cli.console import Interruption, say
from robotarium_cli.running import PROBE_WAIT, VERIFY_NAMESPACE, discovery_is_local
from robotarium_core.topics import namespace_from_environment as namespace

HELP = "start the testbed nodes; they run as long as this command does (Ctrl-C stops); a node that exits is restarted"


def add_arguments(parser):
    parser.add_argument("--no-record", action="store_true", help="do not start the recorder")
    parser.add_argument("--bags-dir", help="where runs are recorded (default: bags/)")
    parser.add_argument("--config", help="the testbed configuration file (default: robotarium_core's testbed.yaml)")
    parser.add_argument("--hardware", action="store_true",
                        help="run every experiment hardware-like: tracking and command latency, pose noise, wheel "
                             "dynamics (the numbers: hardware section of testbed.yaml)")
    parser.add_argument("--fleet", metavar="FILE",
                        help="move your own robots: the hardware arena in the simulator's place, with the robots, "
                             "topics, tracking and calibration of this fleet file (./robotarium fleet writes one for a "
                             "simulated fleet; docs/own-robots.md)")
    parser.add_argument("--verification", action="store_true",
                        help="a warm verification testbed, in namespace %s: ./robotarium verify on this machine and "
                             "ROS_DOMAIN_ID runs its scripts here when it is free and its settings match (--config, "
                             "--no-record, --bags-dir) instead of starting a testbed each time" % VERIFY_NAMESPACE)
    parser.add_argument("--view", action="store_true",
                        help="also serve the testbed to Foxglove, as ./robotarium view does (--view-host, --view-port)")
    recording.add_view_arguments(parser, prefix="view-")


def main(args):
    from robotarium_bringup import local_testbeds
    from robotarium_core import claim
    from robotarium_core.config import DEFAULT
    ns = VERIFY_NAMESPACE if args.verification else namespace()
    if args.verification and (args.hardware or args.fleet):
        say("error: --verification judges scripts as the Robotarium's simulator does: not with --hardware or --fleet")
        return 2
    domain = os.environ.get("ROS_DOMAIN_ID", "0")
    # One testbed per namespace: name the one that runs. Where discovery reaches this machine only,
    # the process table knows it at once (a look on the domain backs it up for a claim_wait); else
    # it is looked for on the domain, as run does (discovery can wait for the next announcement).
    running = local_testbeds.running_here(ns, local_testbeds.domain_id()) if discovery_is_local() else None
    if running is None:
        running = running_testbed(ns, timeout=DEFAULT.claim_wait if discovery_is_local() else PROBE_WAIT)
    if running is not None:
        say(claim.refusal(running, ns, domain))
        return claim.REFUSED
    if args.fleet:
        from robotarium_hardware import fleet as fleets
        try:
            fleet = fleets.load(args.fleet)
        except fleets.FleetError as error:
            say("error: %s" % error)
            return 2
        if args.hardware:
            say("error: --hardware models the Robotarium's robots in simulation; with --fleet the robots are real")
            return 2
    view = None
    if args.view:   # first: a port in use is said before any node starts
        view = recording.ViewProcess(ns, args.view_host, args.view_port)
        if not view.wait_ready():
            view.stop()
            say("the Foxglove view could not start (its message is above); no testbed was started")
            return 1
    interruption = Interruption()
    testbed = LocalTestbed(ns=ns, record=not args.no_record, quiet=False, bags_dir=args.bags_dir,
                           config_file=args.config, hardware=args.hardware, looked=True, fleet_file=args.fleet).start()
    announcer = RestartAnnouncer(ns, testbed.names)
    watcher = supervisor.Supervisor()
    code = 0
    try:
        arena = "hardware arena of fleet %s (%d robots, %s)" % (fleet.name, len(fleet.robots), fleet.tracking) \
            if args.fleet else "simulator" + (" hardware-like" if args.hardware else "") + (
                " for ./robotarium verify" if args.verification else "")
        say("testbed up in namespace %s on ROS_DOMAIN_ID %s (%s, safety%s%s). It runs as long as this "
            "command does: Ctrl-C (or SIGTERM, SIGHUP) stops it." % (
                ns, os.environ.get("ROS_DOMAIN_ID", "0"), arena,
                "" if args.no_record else ", recorder", ", Foxglove view" if view else ""))
        while interruption.signum is None:
            failed = testbed.failed()
            if claim.REFUSED in failed.values():   # one started at the same moment is older: it stays
                say("an older testbed runs in %s on ROS_DOMAIN_ID %s (named above); stopping this one"
                    % (ns, domain))
                code = claim.REFUSED
                break
            if failed and not _restarted(testbed, failed, watcher, announcer):
                code = 1
                break
            if view is not None and view.failed():
                say("the Foxglove view exited (its message is above); the testbed runs on")
                view = None
            time.sleep(0.2)
    finally:
        if view is not None:
            view.stop()
        testbed.stop()   # a running experiment is ended and its recording closed
        interruption.restore()
    say("testbed stopped" + (" (%s)" % interruption.name if interruption.signum else ""))
    return code


def _restarted(testbed, failed, watcher, announcer):
    """Restart each node that exited (announcing it), as the supervisor decides; False where one keeps exiting
    (then up stops the testbed: the supervisor's line says which node and how it ended)."""
    for name, returncode in sorted(failed.items()):
        pid = testbed.processes[name][0].pid
        decision = watcher.exited(ANNOUNCED.get(name, name), returncode, pid)
        say(decision.line)
        announcer.announce(decision.announcement)   # at once: a run in progress names it as its end (or its recording's)
        if decision.restart is None:
            return False
        testbed.restart(name, decision.restart)
    return True
