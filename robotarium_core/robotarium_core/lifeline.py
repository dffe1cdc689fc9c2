"""A lifeline from a process to the processes it starts: they notice at once when it is gone,
however it went (SIGKILL included). Plain Python, Linux and macOS.

The parent makes one pipe and keeps its write end open without ever writing to it; each child
gets the read end (its number in ROBOTARIUM_LIFELINE_FD). When the parent dies the kernel closes
the write end and the child's blocking read returns end-of-file: no polling, no delay beyond the
scheduler's. Unlike Linux's parent-death signal (PR_SET_PDEATHSIG, which fires when the parent
*thread* ends and is lost across an intermediate process), a pipe follows the process.

The write end is never inherited (Python makes pipes non-inheritable and subprocess closes other
descriptors), so only the parent holds it. A child given no lifeline (started by `ros2 run` or a
launch file) watches nothing.
"""
import os
import stat
import threading

ENV = "ROBOTARIUM_LIFELINE_FD"

_pipe = []   # (read_fd, write_fd) of this process's lifeline to its children, made on first use
_watched = []   # the read end this process was given and watches (kept for a restart in place)


def for_child(env):
    """(env, pass_fds) for subprocess.Popen: `env` plus the lifeline of this process."""
    if not _pipe:
        _pipe.extend(os.pipe())
    read_fd = _pipe[0]
    return dict(env, **{ENV: str(read_fd)}), (read_fd,)


def watch(on_lost, name="lifeline"):
    """If this process was given a lifeline, call `on_lost()` (from a daemon thread) as soon as the
    process that started it is gone. Returns whether a lifeline was given. The variable is taken
    out of the environment, so the process's own children do not mistake it for theirs."""
    value = os.environ.pop(ENV, None)
    if value is None:
        return False
    try:
        fd = int(value)
        given = stat.S_ISFIFO(os.fstat(fd).st_mode)
    except (ValueError, OSError):
        given = False
    if not given:
        return False   # a stale variable (e.g. exported in a shell): nothing to watch
    _watched[:] = [fd]

    def wait():
        while True:
            try:
                if not os.read(fd, 1):   # end of file: the last write end closed with its process
                    break
            except OSError:
                break
        on_lost()

    threading.Thread(target=wait, name=name, daemon=True).start()
    return True


def hand_on(env):
    """`env` for this very process started afresh (os.execve keeps the pid and inheritable
    descriptors): the lifeline it watches, if any, is watched again there. Returns the descriptors
    to keep open."""
    if _watched:
        env[ENV] = str(_watched[0])
        os.set_inheritable(_watched[0], True)
    return tuple(_watched)


# -- a start gate: processes started early, held until their starter decides ------------------------

GATE_ENV = "ROBOTARIUM_START_GATE_FD"


class StartGate:
    """Start processes now and let them go on later, or never: `./robotarium run` starts a testbed's
    nodes while it still looks for one on the domain, so their imports (most of a node's start)
    overlap the search; each node waits at the gate (pass_start_gate) before it joins DDS. open()
    lets them go on; a gate closed without open() (cancel(), or the starter's death) makes them exit
    without ever having joined DDS."""

    def __init__(self):
        self._read, self._write = os.pipe()

    def for_child(self, env, pass_fds):
        """(env, pass_fds) for subprocess.Popen, with this gate added."""
        return dict(env, **{GATE_ENV: str(self._read)}), tuple(pass_fds) + (self._read,)

    def open(self, children, message=b""):
        """Let `children` processes through (each takes one byte); one child alone may be handed `message`
        too (read_start_gate)."""
        try:
            os.write(self._write, b"1" * children + message)
        except BrokenPipeError:   # they are all gone already: LocalTestbed.failed() says so
            pass
        self.close()

    def close_read_end(self):
        """After the children were started: only they read."""
        try:
            os.close(self._read)
        except OSError:
            pass
        self._read = -1

    def close(self):
        for fd in (self._read, self._write):
            try:
                os.close(fd)
            except OSError:
                pass
        self._read = self._write = -1


def pass_start_gate():
    """In a process started behind a StartGate, wait until it opens: True then, or at once when
    there is no gate; False when it was closed without opening (exit without joining DDS)."""
    value = os.environ.pop(GATE_ENV, None)
    if value is None:
        return True
    try:
        fd = int(value)
        if not stat.S_ISFIFO(os.fstat(fd).st_mode):
            return True   # a stale variable: no gate
        while True:
            try:
                return os.read(fd, 1) == b"1"
            except InterruptedError:
                continue
    except (ValueError, OSError, KeyboardInterrupt):
        return False
    finally:
        try:
            os.close(fd)
        except (OSError, UnboundLocalError):
            pass


def read_start_gate():
    """In the one process started behind a StartGate, wait until it opens: what its starter handed it then
    (bytes, b"" for nothing), or None when it was closed without opening (exit without doing anything) or
    there is no gate."""
    value = os.environ.pop(GATE_ENV, None)
    if value is None:
        return None
    try:
        fd = int(value)
        if not stat.S_ISFIFO(os.fstat(fd).st_mode):
            return None
        with os.fdopen(fd, "rb") as gate:
            data = gate.read()
    except (ValueError, OSError, KeyboardInterrupt):
        return None
    return data[1:] if data[:1] == b"1" else None
