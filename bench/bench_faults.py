"""How fast the testbed notices what it must notice, and what foreign traffic costs it.

One testbed (simulator, safety node, recorder) in subprocesses on a private domain; the
experiment's client is the real Robotarium class, in this process or (for the client's own
faults) tests/data/steps_forever.py in a subprocess. For each fault, --repeats times:
  - client kill -9 (lockstep and real time): from the SIGKILL to the testbed's IDLE status with
    "client lost at step k" (the bound is client_lease, 2 s);
  - client SIGINT: from the signal to the IDLE status "ended by its client";
  - safety node / simulator kill -9 during a real-time run: from the SIGKILL to the client's
    step() raising, naming the node (node_lease, 0.75 s); the recorder: to the client's
    "recording stopped at step k";
  - a 1 kHz flood (devtools/flood.py: foreign and malformed arrays and a 2.4 MB one twice a
    second, on both command topics) during a real-time 8-robot run: command timeouts, arrays
    counted against arrays sent; a lockstep 8-robot run with and without it: steps/s;
  - memory: the resident set of the simulator and the safety node before and after a flood at the
    highest rate one local process can send (foreign, malformed, forged with the token copied
    off the wire, and 2.4 MB arrays mixed in, on both command topics) during a real-time 8-robot
    run; and the run's command timeouts under a 1 kHz flood of foreign arrays;
  - the cost of refusing an array at a node: robotarium_core.cdr on a foreign array and on a
    100,000-twist one, against rclpy's deserialization of the latter.
Run: ./robotarium bench faults [--repeats 3]
"""
import argparse
import json
import os
import platform
import signal
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from devtools.rosutil import NodeProcess, RosProbe, node_env, unique_domain_id  # noqa: E402
from robotarium_core import cdr, presence  # noqa: E402
from robotarium_core.config import DEFAULT  # noqa: E402
from robotarium_msgs.msg import TestbedStatus, TwistArray  # noqa: E402

NS = "/robotarium"
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STEPS_FOREVER = os.path.join(REPO, "tests", "data", "steps_forever.py")
NODES = {"simulator": "robotarium_sim.simulator_node", "safety": "robotarium_safety.safety_node",
         "recorder": "robotarium_recording.recorder_node"}
LINE3 = np.array([[-0.8, 0.0, 0.8], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
EIGHT = np.array([np.linspace(-1.2, 1.2, 8), np.tile([-0.4, 0.4], 4), np.linspace(-3, 3, 8)])


class Testbed:
    def __init__(self, work):
        self.work = work
        self.domain = unique_domain_id()
        os.environ.update(ROS_DOMAIN_ID=str(self.domain), MPLBACKEND="Agg", ROBOTARIUM_PROGRESS="0")
        from robotarium_client import session
        session.options = session.RunOptions(local_testbed=False)
        self.nodes = {}
        for name in NODES:
            self.start(name)
        self.probe = RosProbe(self.domain)
        self.status = self.probe.collect(TestbedStatus, NS + "/status")
        self.watches = {name: presence.Watch(self.probe.node, NS + "/" + presence.alive_topic(name), DEFAULT.node_lease)
                        for name in NODES}
        self.heal()

    def start(self, name):
        args = ["-p", "bags_dir:=%s" % os.path.join(self.work, "bags")] if name == "recorder" else []
        self.nodes[name] = NodeProcess(NODES[name], self.domain, ros_args=args,
                                       log_path=os.path.join(self.work, "%s_%d.log" % (name, time.time_ns())))

    def heal(self):
        for name, node in list(self.nodes.items()):
            if not node.alive():
                node.close()
                self.start(name)
        if not self.probe.spin_until(lambda: all(w.alive for w in self.watches.values()), 60):
            raise RuntimeError("the testbed did not come up (logs in %s)" % self.work)

    def ended(self, run_id, timeout=30):
        """Monotonic time at which the IDLE status of run_id arrived, and its end reason."""
        found = []

        def check():
            for s in self.status:
                if s.run_id == run_id and s.state == TestbedStatus.STATE_IDLE:
                    found.append((time.monotonic(), s.end_reason))
                    return True
            return False
        self.probe.spin_until(check, timeout)
        return found[0] if found else (None, None)

    def close(self):
        self.probe.close()
        for node in self.nodes.values():
            node.close()


def client(poses, real_time):
    import rps.robotarium as rps_robotarium
    return rps_robotarium.Robotarium(number_of_robots=poses.shape[1], show_figure=False, sim_in_real_time=real_time,
                                     initial_conditions=poses.copy())


def drive(r, v, w):
    r.get_poses()
    r.set_velocities(np.arange(r.number_of_robots), np.array([v, w], dtype=float).reshape(2, -1))
    r.step()


def script_client(tb, sig, mode):
    """A client process killed (or interrupted) after 20 steps: seconds until its experiment ended."""
    log = os.path.join(tb.work, "client_%d.log" % time.time_ns())
    with open(log, "wb") as out:
        proc = subprocess.Popen([sys.executable, STEPS_FOREVER, mode], env=node_env(tb.domain, ROBOTARIUM_PROGRESS="0"),
                                stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while "step 20\n" not in open(log).read():
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(open(log).read())
            time.sleep(0.02)
        run_id = [line.split()[1] for line in open(log) if line.startswith("run ")][0]
        os.killpg(proc.pid, sig)
        sent = time.monotonic()
        proc.wait()
        at, reason = tb.ended(run_id)
        return (at - sent if at else float("nan")), reason
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)


def node_lost(tb, name):
    """Kill a node during a real-time run: seconds until the client said so, and what it said."""
    r = client(LINE3, real_time=True)
    try:
        for _ in range(15):
            drive(r, [0.05] * 3, [0.5] * 3)
        tb.nodes[name].kill()
        killed = time.monotonic()
        tb.nodes[name].proc.wait()
        while time.monotonic() - killed < 15:
            try:
                drive(r, [0.05] * 3, [0.5] * 3)
            except RuntimeError as error:
                return time.monotonic() - killed, str(error).split(":")[0]
            if name == "recorder" and r._link.recorder_lost_at is not None:
                return time.monotonic() - killed, "recording stopped at step %d" % r._link.recorder_lost_at
        return float("nan"), "not noticed"
    finally:
        r._end_quietly()
        tb.heal()


def flood(tb, seconds, *extra):
    return NodeProcess("devtools.flood", tb.domain, args=["--seconds", str(seconds), *extra],
                       log_path=os.path.join(tb.work, "flood_%d.log" % time.time_ns()))


def rss_mb(pid):
    """Resident set of a process, MB (VmRSS)."""
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def flood_memory(tb, seconds, rate="0", huge_every="50", settle=3.0):
    """RSS of the simulator and the safety node before and after a flood of `seconds` at `rate`
    (0: as fast as the flood process can send), forged arrays included, during a real-time run
    of 8 robots. Returns ({node: (before, peak, after)}, arrays sent per second on cmd_requested,
    command timeouts)."""
    names = ("simulator", "safety")
    r = client(EIGHT, real_time=True)
    started = time.monotonic()
    while time.monotonic() - started < 2.0:   # warm up: the run's own traffic
        drive(r, np.full(8, 0.0), np.full(8, 0.3))
    before = {name: rss_mb(tb.nodes[name].proc.pid) for name in names}
    peak = dict(before)
    flooding = flood(tb, seconds, "--rate", rate, "--huge-every", huge_every, "--forge")
    while flooding.alive():
        drive(r, np.full(8, 0.0), np.full(8, 0.3))
        for name in names:
            peak[name] = max(peak[name], rss_mb(tb.nodes[name].proc.pid))
    started = time.monotonic()
    while time.monotonic() - started < settle:
        drive(r, np.full(8, 0.0), np.full(8, 0.3))
    after = {name: rss_mb(tb.nodes[name].proc.pid) for name in names}
    r.call_at_scripts_end()
    out = flooding.output().strip().splitlines()
    sent = json.loads(out[-1]) if out and out[-1].startswith("{") else {}
    on_requested = sent.get(NS + "/cmd_requested", {})
    rate_sent = (sum(on_requested.values()) - on_requested.get("refused", 0)) / seconds
    return {name: (before[name], peak[name], after[name]) for name in names}, rate_sent, r.run_info.command_timeouts


def flooded_real_time(tb):
    r = client(EIGHT, real_time=True)
    flooding = flood(tb, 3)
    while flooding.alive():
        drive(r, np.full(8, 0.02), np.full(8, 0.3))
    for _ in range(30):
        drive(r, np.full(8, 0.02), np.full(8, 0.3))
    sent = json.loads(flooding.output().strip().splitlines()[-1])
    r.call_at_scripts_end()
    info = r.run_info
    counted = {topic: sum(info["dropped"][topic].values()) for topic in ("cmd_requested", "cmd_safe")}
    sent = {topic: sum(sent[NS + "/" + topic].values()) for topic in ("cmd_requested", "cmd_safe")}
    return sent, counted, info["command_timeouts"], info["steps"]


def lockstep_rate(tb, flooded):
    flooding = None
    if flooded:
        flooding = flood(tb, 8)
        while "flooding" not in flooding.output():
            time.sleep(0.05)
    r = client(EIGHT, real_time=False)
    rng = np.random.default_rng(3)
    started = time.perf_counter()
    for _ in range(200):
        drive(r, rng.uniform(0, 0.1, 8), rng.uniform(-1, 1, 8))
    rate = 200 / (time.perf_counter() - started)
    r.call_at_scripts_end()
    if flooding is not None:
        flooding.close()
    return rate


def parse_costs():
    from rclpy.serialization import deserialize_message
    token = "t" * 32
    small = cdr.TWIST_ARRAY.build(frame_id="arena", token="f" * 32, ids=np.arange(8), twists=cdr.twists(np.ones(8), np.ones(8)))
    huge = cdr.TWIST_ARRAY.build(frame_id="arena", token=token, ids=np.arange(100_000),
                                 twists=cdr.twists(np.ones(100_000), np.ones(100_000)))

    def per_call(fn, n):
        started = time.perf_counter()
        for _ in range(n):
            fn()
        return (time.perf_counter() - started) / n

    def refuse(data, token):
        try:
            cdr.parse_commands(data, 8, token=token)
        except cdr.CdrError:
            pass
    return {"foreign 8-robot array (cdr)": per_call(lambda: refuse(small, token), 20000),
            "100,000 twists, own token (cdr)": per_call(lambda: refuse(huge, token), 2000),
            "100,000 twists (rclpy deserialize)": per_call(lambda: deserialize_message(huge, TwistArray), 3)}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--flood-seconds", type=float, default=60.0, help="the memory case's flood")
    parser.add_argument("--only", choices=["memory"], help="run only this case")
    args = parser.parse_args()
    print("faults benchmark, %s, %s, %d cores, Python %s, load average %.1f" % (
        time.strftime("%Y-%m-%d"), platform.machine(), os.cpu_count(), platform.python_version(), os.getloadavg()[0]))
    work = tempfile.mkdtemp(prefix="bench_faults_")
    tb = Testbed(work)
    rows = []
    if args.only == "memory":
        try:
            for _ in range(args.repeats):
                rss, rate, timeouts = flood_memory(tb, args.flood_seconds)
                print("memory (RSS, MB) before / peak / after a %g s flood: %s; %.0f arrays/s on cmd_requested; "
                      "command timeouts %d" % (args.flood_seconds, ", ".join(
                          "%s %.1f / %.1f / %.1f (%+.1f)" % (name, b, p, a, a - b) for name, (b, p, a) in rss.items()),
                          rate, timeouts), flush=True)
        finally:
            tb.close()
        return
    try:
        for label, fn in (
                ("client kill -9, lockstep -> experiment ended", lambda: script_client(tb, signal.SIGKILL, "lockstep")),
                ("client kill -9, real time -> experiment ended", lambda: script_client(tb, signal.SIGKILL, "real-time")),
                ("client SIGINT -> experiment ended", lambda: script_client(tb, signal.SIGINT, "lockstep")),
                ("safety node kill -9 -> client raises", lambda: node_lost(tb, "safety")),
                ("simulator kill -9 -> client raises", lambda: node_lost(tb, "simulator")),
                ("recorder kill -9 -> client reports", lambda: node_lost(tb, "recorder"))):
            results = [fn() for _ in range(args.repeats)]
            times = [t for t, _ in results]
            rows.append((label, statistics.median(times), max(times), results[-1][1]))
        print("\n%-48s %9s %9s  %s" % ("fault", "median s", "worst s", "what was said"))
        for label, median, worst, said in rows:
            print("%-48s %9.2f %9.2f  %s" % (label, median, worst, said))

        print("\nflood, 1 kHz on each command topic for 3 s, real-time run of 8 robots:")
        for _ in range(args.repeats):
            sent, counted, timeouts, steps = flooded_real_time(tb)
            print("  sent %s, counted %s, command timeouts %s, %d steps" % (sent, counted, timeouts, steps))
        print("\nmemory (RSS, MB) before / peak / after a %g s flood at the highest rate one process sends "
              "(foreign, malformed, forged, 2.4 MB every 50th), real-time 8-robot run:" % args.flood_seconds)
        for _ in range(args.repeats):
            rss, rate, timeouts = flood_memory(tb, args.flood_seconds)
            print("  %s; %.0f arrays/s on cmd_requested; command timeouts %d" % (
                ", ".join("%s %.1f / %.1f / %.1f (%+.1f)" % (name, b, p, a, a - b) for name, (b, p, a) in rss.items()),
                rate, timeouts))
        quiet = [lockstep_rate(tb, False) for _ in range(args.repeats)]
        loud = [lockstep_rate(tb, True) for _ in range(args.repeats)]
        print("lockstep 8 robots, 200 steps: %.0f steps/s quiet, %.0f steps/s flooded (median; ratio %.2f)" % (
            statistics.median(quiet), statistics.median(loud), statistics.median(loud) / statistics.median(quiet)))
    finally:
        tb.close()
    print("\nrefusing an array (per array):")
    for label, seconds in parse_costs().items():
        print("  %-40s %10.1f us" % (label, seconds * 1e6))


if __name__ == "__main__":
    main()
