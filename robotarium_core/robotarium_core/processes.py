"""Which process a pid names, without ROS: a pid alone names a process only while it runs; a busy machine
hands it to another soon after (a suite's thousands of forks wrap the kernel's 32768 within seconds), so a
process is its pid and its start (clock ticks since boot, /proc/<pid>/stat)."""
import os
import socket


def _stat(pid):
    """The fields of /proc/PID/stat after the command name (state first), or None where there is none."""
    try:
        with open("/proc/%s/stat" % pid) as f:
            stat = f.read()
    except OSError:
        return None
    return stat[stat.rindex(")") + 2:].split()   # the command name may hold spaces and parentheses


def process_start(pid):
    """When process `pid` started (clock ticks since boot, from /proc/<pid>/stat), or None if there is no
    such process or it is a zombie (or 0 where there is no /proc: then any live process of that id counts).
    With its pid it names one process, as a pid alone does not once a busy machine hands it to another."""
    fields = _stat(pid)
    if fields is None:
        if os.path.isdir("/proc/self"):
            return None
        try:
            os.kill(pid, 0)
            return 0
        except ProcessLookupError:
            return None
        except PermissionError:
            return 0
    return None if fields[0] == "Z" else int(fields[19])   # Z: exited, not yet reaped by its parent


def runs_here(ident):
    """Whether the process of claim `ident` runs on this machine, neither stopped nor a zombie, and is that
    process: a pid whose start differs is another process that took it (a killed safety node's pid reused
    within seconds while a suite forked thousands of processes: its client waited 10 s for a restart that
    would never come, 2026-11-30). A claim without its start (an older node) is judged by the pid alone."""
    if ident is None or ident["host"] != socket.gethostname():
        return False
    fields = _stat(ident["pid"])
    started = ident.get("started")
    return fields is not None and fields[0] not in ("T", "t", "Z", "X") and (
        started is None or int(fields[19]) == started)
