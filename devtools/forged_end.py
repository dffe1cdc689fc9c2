"""A process holding the run's token ends it: copies the token off the wire and sends end_experiment.

    python -m devtools.forged_end [--namespace /robotarium] [--at-step 115] [--wait 60]

It copies the running experiment's token from the client's arrays on cmd_requested (without SROS2
the token is no secret: devtools.flood.Forger), waits until the client's arrays reach step
--at-step (lockstep numbers its arrays; real time's are unnumbered: use --at-step 0), and
sends the end_experiment request with that token and no outcome, as a script's own
call_at_scripts_end() does. It prints "token copied" when it has the token, then one JSON line
{"success": ..., "message": ..., "step": the client's step it saw, "end_reason": ...}.
Exit code 0 when the testbed took the request, 1 otherwise.
"""
import argparse
import json
import sys
import time

import rclpy
from rclpy.node import Node

from devtools.flood import Forger
from robotarium_core.topics import END_EXPERIMENT
from robotarium_msgs.srv import EndExperiment


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--namespace", default="/robotarium")
    parser.add_argument("--at-step", type=int, default=115, help="end once the client's arrays reach this step")
    parser.add_argument("--wait", type=float, default=60.0, help="seconds to wait for a client's arrays")
    args = parser.parse_args(argv)

    rclpy.init()
    node = Node("forged_end")
    ns = args.namespace.rstrip("/")
    forger = Forger(node, "%s/cmd_requested" % ns, robots=1)
    end = node.create_client(EndExperiment, "%s/%s" % (ns, END_EXPERIMENT))
    deadline = time.monotonic() + args.wait
    forger.wait_for_token(deadline)
    print("token copied", flush=True)
    while forger.step < args.at_step and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.005)
    if not end.wait_for_service(timeout_sec=10.0):
        raise SystemExit("forged_end: no end_experiment service in %s" % ns)
    future = end.call_async(EndExperiment.Request(token=forger.token))
    rclpy.spin_until_future_complete(node, future, timeout_sec=30.0)
    response = future.result()
    result = {"success": bool(response and response.success), "message": response.message if response else "no answer",
              "step": forger.step, "end_reason": response.end_reason if response else ""}
    print(json.dumps(result), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0 if result["success"] else 1


if __name__ == "__main__":
    sys.exit(main())
