"""The testbed under faults and foreign traffic, with real processes: only the experiment's client
moves robots, a lost client frees the testbed, floods cost nothing, and every failure is reported
as what it is (README: "Faults and what the testbed does")."""
import os
import xml.etree.ElementTree as ET

from devtools import REPO


def test_sros2_policy_gives_cmd_safe_and_poses_one_writer_each():
    """The policy we ship (sros2/robotarium.policy.xml) says what the README promises: only the
    safety node's enclave publishes cmd_safe, only the simulator's publishes poses and arms the
    safety node, and no client may publish either."""
    root = ET.parse(os.path.join(REPO, "sros2", "robotarium.policy.xml")).getroot()
    assert root.tag == "policy" and root.get("version") == "0.2.0"
    allowed = {}   # (enclave, kind, name) for every ALLOW rule
    for enclave in root.find("enclaves"):
        path = enclave.get("path")
        for profile in enclave.iter("profile"):
            ns = profile.get("ns").rstrip("/")
            for group in profile:
                for kind in ("publish", "subscribe", "request", "reply"):
                    if group.get(kind) == "ALLOW":
                        for item in group:
                            name = item.text if item.text.startswith(("/", "~")) else ns + "/" + item.text
                            allowed.setdefault((kind, name), set()).add(path)
    assert allowed[("publish", "/robotarium/cmd_safe")] == {"/robotarium/safety"}
    assert allowed[("publish", "/robotarium/poses")] == {"/robotarium/simulator"}
    assert allowed[("request", "/robotarium/safety/arm")] == {"/robotarium/simulator"}
    assert allowed[("publish", "/robotarium/cmd_requested")] == {"/robotarium/client"}
    assert {"/robotarium/client", "/robotarium/operator"} <= allowed[("request", "/robotarium/end_experiment")]
    # no wildcard publish rule could let anyone else write them
    assert not any(kind == "publish" and name.endswith("*") and not name.endswith("client_*")
                   for kind, name in allowed)
