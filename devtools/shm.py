"""Fast DDS's shared-memory files that no live process uses, removed before a test session.

Every participant maps files in /dev/shm (its ports, their locks and mutexes, data-sharing
segments); a process killed with SIGKILL, as many tests do on purpose, leaves them there, and a
machine that ran the suite many times held 2,100 of them (230 MB of memory). Fast DDS's own
`fastdds shm clean` removes only those with an unheld lock file (about half); a later participant
that opens a dead port waits out its 1 s health check first. This removes every such file that no
process that can be read has open or mapped, only those of this user (0644: nobody else may use
them) and none changed in the last few seconds (a participant being set up). A process that even
its user cannot read (a protected init, as here) is taken for one that maps no such file.
"""
import os
import time

SHM = "/dev/shm"
PREFIXES = ("fastrtps_", "fast_datasharing_", "sem.fastrtps_")
SETTLE = 10.0   # s: a file changed more recently may belong to a participant being created


def files_in_use():
    """Paths under SHM that a process this user can read has open or mapped."""
    used = set()
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open("/proc/%s/maps" % pid) as maps:
                for line in maps:
                    if SHM + "/" in line:
                        used.add(line.split(None, 5)[-1].strip().removesuffix(" (deleted)"))
            for fd in os.listdir("/proc/%s/fd" % pid):
                try:
                    used.add(os.readlink("/proc/%s/fd/%s" % (pid, fd)))
                except OSError:
                    pass   # closed meanwhile
        except OSError:
            continue   # exited meanwhile, or not readable (another user's: it cannot use ours)
    return used


def remove_unused():
    """Remove Fast DDS's files in SHM that no process uses; returns how many were removed."""
    try:
        names = [n for n in os.listdir(SHM) if n.startswith(PREFIXES)]
    except OSError:
        return 0
    used = files_in_use() if names else set()
    removed, now, me = 0, time.time(), os.getuid()
    for name in names:
        path = os.path.join(SHM, name)
        try:
            info = os.stat(path)
            if path not in used and info.st_uid == me and now - info.st_mtime > SETTLE:
                os.remove(path)
                removed += 1
        except OSError:
            pass   # gone meanwhile, or not ours
    return removed


if __name__ == "__main__":
    print("removed %d unused Fast DDS files from %s" % (remove_unused(), SHM))
