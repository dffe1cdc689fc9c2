"""The user's script, demoted: the one part of a job that runs a stranger's code.

The portal's job box (robotarium_portal/jobbox.py) runs a whole `./robotarium run` or `verify` in a
network namespace of its own, as the service; the testbed's nodes and the command line stay the
service's. It hands the command line this description of the script's box in the environment:

    ROBOTARIUM_SCRIPT_BOX={"user": "robotarium-job-runs", "uid": 990, "gid": 990,
                           "home": "/srv/robotarium-boxes/runs/home",
                           "limits": {"cpu_seconds": 1200, "memory_bytes": 4294967296, ...}}

and the command line starts the script's process (robotarium_cli.runner) with popen_options():
as that account, with those resource limits, without the variable. Without it nothing changes
(`./robotarium run` on one's own machine)."""
import json
import os
import resource

VARIABLE = "ROBOTARIUM_SCRIPT_BOX"
# The job box's limit names -> the kernel's resource limits (applied to the script's process).
RLIMITS = {"cpu_seconds": resource.RLIMIT_CPU, "memory_bytes": resource.RLIMIT_AS,
           "file_bytes": resource.RLIMIT_FSIZE, "processes": resource.RLIMIT_NPROC,
           "open_files": resource.RLIMIT_NOFILE}
CPU_KILL_AFTER = 2   # s of CPU past the soft limit (SIGXCPU) before the hard one (SIGKILL)
# The script's processes share one CPU group (a cgroup of the cpu controller, one per account): however many it
# makes, together they get the CPU of one ordinary process. During a fork bomb's 200 processes at the process limit
# a worker's heartbeat path (a PostgreSQL connection and a query) took up to 0.51 s on a quiet machine, 0.10 s with
# the group (docs/portal.md). Where the machine has no cgroup v1 cpu controller (cgroup v2 hosts), none: the process
# limit still holds.
CPU_GROUPS = "/sys/fs/cgroup/cpu"
# Where the service's ROS keeps its logs: the script's own ROS writes under its HOME instead.
SERVICE_ONLY = ("ROS_LOG_DIR", "ROS_HOME", VARIABLE)


def describe(user, uid, gid, home, limits):
    """The variable's value (the job box writes it)."""
    unknown = set(limits) - set(RLIMITS)
    if unknown:
        raise ValueError("unknown script limits: %s (known: %s)" % (", ".join(sorted(unknown)), ", ".join(RLIMITS)))
    return json.dumps({"user": user, "uid": uid, "gid": gid, "home": str(home), "limits": limits})


def hand_over(env, paths):
    """Give `paths` (folders the script's process writes) to the box's account that `env` names; nothing when
    not boxed."""
    text = env.get(VARIABLE)
    if text:
        box = json.loads(text)
        for path in paths:
            os.chown(path, int(box["uid"]), int(box["gid"]))


def popen_options(env, writable=()):
    """(subprocess.Popen keyword arguments, the script's environment) for the script's process: as
    the box's account, limited, HOME in its box, `writable` folders (the run's own scratch folder,
    where the script's process writes how the run ended) handed to it. ({}, env) when not boxed."""
    text = env.get(VARIABLE)
    if not text:
        return {}, env
    box = json.loads(text)
    uid, gid = int(box["uid"]), int(box["gid"])
    hand_over(env, writable)
    script_env = {k: v for k, v in env.items() if k not in SERVICE_ONLY}
    script_env.update(HOME=box["home"], USER=box["user"], LOGNAME=box["user"])
    demoted = uid != os.geteuid()
    # A process limit counts every process of the account: without an account of its own it would
    # count the service's too, so it holds only for a demoted script.
    limits = [(RLIMITS[name], int(value)) for name, value in box["limits"].items()
              if demoted or name != "processes"]

    procs = cpu_group(uid) if demoted else None

    def limit():   # in the child, after it became the account, before it runs python
        if procs is not None:
            try:
                with open(procs, "w") as f:   # (the group's member list is the account's to write)
                    f.write(str(os.getpid()))
            except OSError:
                pass   # (the group went meanwhile: the process limit still holds)
        for which, value in limits:
            hard = value + CPU_KILL_AFTER if which == resource.RLIMIT_CPU else value
            ceiling = resource.getrlimit(which)[1]   # an account cannot raise its hard limit
            if ceiling != resource.RLIM_INFINITY:
                value, hard = min(value, ceiling), min(hard, ceiling)
            resource.setrlimit(which, (value, hard))
        os.umask(0o077)

    if not demoted:   # a service that is not root: the script runs as the service, limited
        return {"preexec_fn": limit}, script_env
    return {"user": uid, "group": gid, "extra_groups": [], "preexec_fn": limit}, script_env


def cpu_group_folder(uid):
    return os.path.join(CPU_GROUPS, "robotarium-script-%d" % uid)


def cpu_group(uid):
    """The member list (cgroup.procs) of account uid's CPU group, made where missing and writable by the account
    (a process may move itself into a group whose list it may write); None where there are no CPU groups."""
    folder = cpu_group_folder(uid)
    try:
        os.makedirs(folder, exist_ok=True)
        procs = os.path.join(folder, "cgroup.procs")
        os.chown(procs, uid, -1)
        return procs
    except OSError:
        return None


def remove_cpu_group(uid):
    """Account uid's CPU group goes with the account (once its processes are gone; else it stays)."""
    try:
        os.rmdir(cpu_group_folder(uid))
    except OSError:
        pass
