"""The testbed's Fast DDS settings, for every participant of ours (nodes, the client, the CLI's
probes): `init_context` is rclpy.init with dds_profile.xml (UDP only, never shared memory; quick
announcements and heartbeats; see the file), the only rclpy.init of the project (tests/test_lint.py
checks it). `return_freed_memory` is the allocator's half of the readers' memory policy (issue 22).
Why each setting: docs/faults.md and dds_profile.xml.
"""
import ctypes
import hashlib
import os
import tempfile

import rclpy

DDS_PROFILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "dds_profile.xml")
MMAP_THRESHOLD = 256 * 1024   # bytes: larger blocks are mapped for themselves and go back to the system when freed
_M_MMAP_THRESHOLD = -3         # glibc's mallopt parameter


def localhost_profile():
    """dds_profile.xml with its LOCALHOST blocks in force (loopback locators, localhost as the initial
    peer), written once per content to the temporary directory; None where it cannot be written."""
    with open(DDS_PROFILE, encoding="utf-8") as f:
        text = f.read().replace("<!--LOCALHOST", "").replace("LOCALHOST-->", "")
    path = os.path.join(tempfile.gettempdir(), "robotarium-dds-localhost-%s.xml"
                        % hashlib.sha256(text.encode()).hexdigest()[:16])
    if not os.path.exists(path):
        try:
            with tempfile.NamedTemporaryFile("w", dir=os.path.dirname(path), delete=False, suffix=".tmp") as f:
                f.write(text)
            os.replace(f.name, path)   # whole or not at all, for a process that reads it meanwhile
        except OSError:
            return None
    return path


def profile_is_ours(profile=None):
    """Whether a FASTRTPS_DEFAULT_PROFILES_FILE value (default: this process's, none counting as ours)
    is one of ours (inherited from a process of the testbed that started this one), not the user's choice."""
    if profile is None:
        profile = os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", DDS_PROFILE)
    return profile == DDS_PROFILE or os.path.basename(profile).startswith("robotarium-dds-localhost-")


def _localhost_only():
    """Whether rcl would start a participant with the LOCALHOST discovery range and nothing else
    (no static peers; not the deprecated ROS_LOCALHOST_ONLY, which rcl lets prevail)."""
    return (os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper() == "LOCALHOST"
            and not os.environ.get("ROS_STATIC_PEERS", "").strip() and os.environ.get("ROS_LOCALHOST_ONLY") != "1")


def init_context(context=None, args=None, domain_id=None, node=True, **options):
    """rclpy.init with the testbed's Fast DDS settings (dds_profile.xml; a profile file the user set is
    kept, and with it their choice), for its nodes and a script's client alike: UDP only (never the
    shared-memory transport, see the file); a participant announced every 0.2 s, so a process that
    joins later finds it at once; writers that send a heartbeat every 0.1 s, so a lost packet is sent
    again at once. A node's readers also allocate a sample's buffer when it arrives and free it when
    it is taken (issue 22: a flood costs no memory that stays), for which rmw_fastrtps must take the
    policies it would set itself from the file (RMW_FASTRTPS_USE_QOS_FROM_XML), data sharing among
    them; a client (node=False) keeps rmw's, data sharing off: a script in a job box runs as an
    account that may not open the testbed's shared segments.

    Under ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST rmw_fastrtps would put its own transports in place
    (shared memory among them): the participant starts with the range SYSTEM_DEFAULT and
    localhost_profile() instead, which keeps discovery on this machine just as well; the range is as
    it was afterwards (the profile file stays: a child process is to find it). Fast DDS reads its
    profile file once, when a process makes its first participant, so every participant of ours
    starts here (tests/test_lint.py checks that no other rclpy.init remains)."""
    saved = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE")
    if profile_is_ours():
        localhost = localhost_profile() if _localhost_only() else None
        os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = localhost or DDS_PROFILE
        if localhost is not None:
            os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"
        if node:
            os.environ["RMW_FASTRTPS_USE_QOS_FROM_XML"] = "1"   # only for the policies our code leaves to it
    try:
        rclpy.init(context=context, args=args, domain_id=domain_id, **options)
    finally:
        if saved is None:
            os.environ.pop("ROS_AUTOMATIC_DISCOVERY_RANGE", None)
        else:
            os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = saved


def return_freed_memory():
    """A node's freed large blocks go back to the system (issue 22): the C allocator maps every block of
    more than MMAP_THRESHOLD for itself and unmaps it when it is freed (glibc raises that threshold by
    itself after the first large block was freed, and then keeps freed 2.4 MB arrays in the process).
    Not for a script's process: its own large numpy arrays would be mapped and unmapped every time."""
    try:
        ctypes.CDLL("libc.so.6").mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
    except (OSError, AttributeError):
        pass   # not glibc: its own rules apply
