"""Free ROS_DOMAIN_IDs on this machine: each one handed out is held (a file lock) while its process lives.

The portal's workers draw their testbeds' domains here; the tests and benchmarks (devtools.rosutil) too,
so no two processes on this machine ever share a domain."""
import fcntl
import os
import tempfile

# Domain ids 1..101 only: DDS derives its UDP ports from the domain (7400 + 250 x domain + ...), and
# above 101 they fall in Linux's ephemeral port range (32768-60999), where any process's outgoing
# socket may hold a port a participant needs, and fewer participants fit below 65535 (ROS 2's
# "About Domain ID"; its own test helper, domain_coordinator, uses 1..100). Each one handed out is
# held with an exclusive lock
# on a file until this process exits, so no two processes on this machine (two pytest runs, a
# benchmark, another checkout's tests) ever share a domain, and no test of this process gets a
# domain an earlier test used (a module's testbed may still be running on it) while another is free.
_DOMAIN_LOCKS = os.path.join(tempfile.gettempdir(), "robotarium-domains")
_MAX_DOMAIN_ID = 101
_held = {}        # domain -> its lock file's descriptor, in the order drawn; closed when the process exits
_cursor = [None]  # where the next search starts: after the last domain handed out
# When every domain is held: whether a domain this process drew earlier may be handed out again (nothing
# runs on it any more). The tests set it (tests/conftest.py): one whole suite's three workers held up to 87 of
# the 101, each keeping all of its own; None: never, the search fails.
reusable = None


def unique_domain_id():
    """A ROS_DOMAIN_ID that no other process on this machine holds, locked for this process."""
    os.makedirs(_DOMAIN_LOCKS, exist_ok=True)
    if _cursor[0] is None:
        _cursor[0] = os.getpid() % _MAX_DOMAIN_ID   # spread concurrent processes
    for k in range(_MAX_DOMAIN_ID):
        candidate = 1 + (_cursor[0] + k) % _MAX_DOMAIN_ID
        fd = os.open(os.path.join(_DOMAIN_LOCKS, "%d.lock" % candidate), os.O_CREAT | os.O_RDWR, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:   # held by another process, or by this one already
            os.close(fd)
            continue
        _held[candidate] = fd
        _cursor[0] = candidate   # 1 + candidate % N is the next one tried
        return candidate
    for domain in list(_held) if reusable is not None else ():   # the earliest drawn first
        if reusable(domain):
            _held[domain] = _held.pop(domain)   # (now the newest drawn)
            return domain
    raise RuntimeError("every ROS_DOMAIN_ID 1..%d is held by a process on this machine" % _MAX_DOMAIN_ID)
