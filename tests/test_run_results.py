"""Every run returns its results, whatever its end: ./robotarium run against real nodes.

Each way a run can end - an exception mid-run, Ctrl-C, no call_at_scripts_end(), a script that
cannot be imported (before any testbed is started), a testbed lost mid-run - leaves a run folder
with log.txt (the traceback too), report.txt whose first line says how it ended (never the
acceptance estimate for a run that did not complete), run.json, index.html and, from the
recording, trajectories.png and run.mp4; the last line printed names the folder. A guide
plotting script's video shows what it drew on r.axes; the results page works in a real browser
(Chromium); replay plays a lockstep run in experiment time and refuses a live testbed's namespace.

One testbed serves the module (as in test_examples.py); the lost-testbed test stops its
simulator, so it comes last.
"""
import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from devtools.e2e import own_domain_testbed
from devtools.rosutil import REPO

pytestmark = pytest.mark.e2e   # whole runs through ./robotarium

START = "np.array([[0.0, 0.5], [0.0, 0.0], [0.0, 0.0]])"
HEADER = """import time
import rps.robotarium as robotarium
import numpy as np
N = 2
r = robotarium.Robotarium(number_of_robots=N, show_figure=True, sim_in_real_time=False, initial_conditions=%s)
r.axes.scatter([1.0], [0.5], s=300, marker='s', facecolors='none', edgecolors='r', linewidth=4)
""" % START
STEP = """    r.get_poses()
    r.set_velocities(np.arange(N), np.array([[0.05, 0.05], [0.0, 0.0]]))
    r.step()
"""
SCRIPTS = {
    "fails.py": HEADER + "goals = {}\nfor k in range(40):\n" + STEP + "    if k == 9:\n        goals['goal']\n"
                "r.call_at_scripts_end()\n",
    "endless.py": HEADER + "for k in range(100000):\n" + STEP + "    if k == 5:\n        print('running', flush=True)\n"
                  "    time.sleep(0.02)\nr.call_at_scripts_end()\n",
    "no_end.py": HEADER + "for k in range(6):\n" + STEP,
    "typo.py": "import numpy as np\nimport nump\nimport rps.robotarium as robotarium\n",
    "broken.py": "import numpy as np\nfor k in range(3)\n    print(k)\n",
    # Slow to begin its loop (the real-time testbed steps meanwhile), its goal marker moved halfway.
    "slow_start.py": HEADER.replace("sim_in_real_time=False", "sim_in_real_time=True")
                     + "goal = r.axes.scatter([-1.0], [-0.5], s=300, marker='o', facecolors='none', edgecolors='b')\n"
                       "time.sleep(1.5)\nfor k in range(90):\n" + STEP
                     + "    if k == 45:\n        goal.set_offsets([[1.0, -0.5]])\nr.call_at_scripts_end()\n",
}


@pytest.fixture(scope="module")
def testbed(tmp_path_factory):
    scripts = tmp_path_factory.mktemp("scripts")
    for name, text in SCRIPTS.items():
        (scripts / name).write_text(text)
    with own_domain_testbed(tmp_path_factory) as (env, bags, tb):
        yield {"env": env, "bags": bags, "scripts": scripts, "testbed": tb,
               "results": tmp_path_factory.mktemp("results"), "runs": {}}


def start_run(ctx, script, *flags, env=None):
    """./robotarium run in its own session (as a terminal's foreground job: signals reach it alone)."""
    command = [sys.executable, "-m", "robotarium_cli", "run", *flags, "--results-dir", str(ctx["results"]),
               script if os.path.isabs(script) else str(ctx["scripts"] / script)]
    return subprocess.Popen(command, env=env or ctx["env"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, cwd=str(ctx["scripts"]), start_new_session=True)


def finish(process, timeout=180):
    try:
        out, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        out, _ = process.communicate()
        raise AssertionError("./robotarium run did not finish within %d s:\n%s" % (timeout, out)) from None
    return process.returncode, out


def wait_for_line(process, text, timeout=60):
    """Read the run's output until a line contains `text`; returns what was read."""
    lines = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        lines.append(line)
        if text in line:
            return "".join(lines)
    raise AssertionError("no %r in the output:\n%s" % (text, "".join(lines)))


def run_folder(out):
    """The folder the last line names."""
    last = out.strip().splitlines()[-1]
    assert last.startswith("[robotarium] results in "), out
    folder = last[len("[robotarium] results in "):].split(" (open ")[0]
    return folder


def check_folder(folder, cwd, recorded=True, out=""):
    """The files every run folder has; returns (first line of report.txt, report, log, run.json).
    `out`: what ./robotarium run printed, shown with the report when a file is missing."""
    folder = os.path.join(cwd, folder)
    names = set(os.listdir(folder))
    want = {"log.txt", "report.txt", "run.json", "index.html"} | ({"trajectories.png", "run.mp4"} if recorded else set())
    if not want <= names:
        try:
            with open(os.path.join(folder, "report.txt")) as f:
                report = f.read()
        except OSError as error:
            report = str(error)
        raise AssertionError("%s missing from %s\n--- run printed:\n%s\n--- report.txt:\n%s"
                             % (sorted(want - names), sorted(names), out, report))
    with open(os.path.join(folder, "report.txt")) as f:
        report = f.read()
    with open(os.path.join(folder, "log.txt")) as f:
        log = f.read()
    with open(os.path.join(folder, "run.json")) as f:
        run = json.load(f)
    return report.splitlines()[0], report, log, run


def test_a_script_that_raises_mid_run(testbed):
    code, out = finish(start_run(testbed, "fails.py", "--no-local-testbed"))
    assert code == 1, out
    folder = run_folder(out)
    first, report, log, run = check_folder(folder, str(testbed["scripts"]))
    assert first == "Run did not complete: the script raised KeyError: 'goal' at step 10 (line 13 of fails.py).", report
    assert "Acceptance" not in report and "no acceptance estimate" in report
    assert "Traceback (most recent call last)" in log and 'fails.py", line 13' in log and "KeyError: 'goal'" in log
    assert run["outcome"] == "script_error" and run["exit_code"] == 1 and run["step_calls"] == run["steps"] == 10
    assert "hint: the traceback above" in out
    testbed["runs"]["fails"] = os.path.join(str(testbed["scripts"]), folder)

    # The recording itself says how the run ended: ./robotarium report on the bag alone.
    from robotarium_recording import results
    numbers = results.recompute(testbed["runs"]["fails"])
    assert numbers["outcome"] != 1 and "did not complete" in numbers["first_line"] and not numbers["completed"]
    assert "Acceptance" not in numbers["report"]


def test_a_run_interrupted_with_ctrl_c(testbed):
    signum, code = signal.SIGINT, 130
    process = start_run(testbed, "endless.py", "--no-local-testbed")
    head = wait_for_line(process, "running")
    os.killpg(process.pid, signum)
    got, out = finish(process)
    out = head + out
    assert got == code, out
    first, report, log, run = check_folder(run_folder(out), str(testbed["scripts"]), out=out)
    name = signal.Signals(signum).name
    assert first.startswith("Run did not complete: interrupted by ") and name in first, report
    assert "Acceptance" not in report and run["outcome"] == "interrupted" and run["step_calls"] >= 6
    assert "running" in log


def test_a_script_without_call_at_scripts_end(testbed):
    code, out = finish(start_run(testbed, "no_end.py", "--no-local-testbed"))
    assert code == 3, out
    first, report, log, run = check_folder(run_folder(out), str(testbed["scripts"]), out=out)
    assert first == ("Run did not complete: the script ended without calling r.call_at_scripts_end() "
                     "(step 6)."), report
    assert "Acceptance" not in report and "hint: end the script with r.call_at_scripts_end()" in out


@pytest.mark.parametrize("script, words", [
    ("typo.py", ["could not import nump", "(line 2 of typo.py; did you mean 'numpy'?)"]),
    ("broken.py", ["could not be compiled: SyntaxError: expected ':' (line 2 of broken.py)"])])
def test_a_script_that_cannot_be_imported_fails_before_a_testbed_is_started(testbed, script, words):
    # A namespace where nothing answers: had the script been started, a testbed would be started for it.
    env = dict(testbed["env"], ROBOTARIUM_NAMESPACE="/nobody_%d" % os.getpid())
    code, out = finish(start_run(testbed, script, env=env), timeout=60)
    assert code == 1, out
    assert "starting one" not in out and "testbed" not in out.split("[robotarium] Run did not")[0], out
    first, report, log, run = check_folder(run_folder(out), str(testbed["scripts"]), recorded=False)
    assert first.startswith("Run did not complete: the script ") and "no testbed was started" in first, report
    assert all(w in first for w in words), first
    assert os.path.dirname(os.path.join(str(testbed["scripts"]), run_folder(out))) == str(testbed["results"])


def test_the_video_is_made_as_a_real_time_run_goes_and_is_the_bags(testbed, tmp_path):
    """The video is drawn while the run goes (robotarium_recording.live_video), from what ./robotarium run
    hears over DDS, for a real-time script whose loop begins 1.5 s after its experiment (the testbed ahead
    by more than the live video's lag) and whose drawing changes halfway: byte for byte the bag's video."""
    from robotarium_recording.bag import Bag
    from robotarium_recording.pictures import render_video
    code, out = finish(start_run(testbed, "slow_start.py", "--real-time"))
    assert code == 0, out
    assert re.search(r"rendering run\.mp4: made as the run went \(\d+ frames\)", out), out
    folder = run_folder(out)
    bag = Bag(folder)
    drawings = bag.drawings()
    assert {m["step"] for m in drawings} >= {0, 46}, drawings   # the marker moved, by the script's count
    assert bag.poses().steps[0] == 0 and bag.poses().steps[-1] > 90 + 30   # the testbed stepped ahead of it
    from_bag = render_video(bag.poses(), drawings, bag.config(), str(tmp_path), json.load(
        open(os.path.join(folder, "run.json")))["run_id"], progress=False)
    assert open(os.path.join(folder, "run.mp4"), "rb").read() == open(from_bag, "rb").read()


def _frame(path, index):
    import imageio_ffmpeg
    reader = imageio_ffmpeg.read_frames(path)
    meta = next(reader)
    width, height = meta["size"]
    for k, frame in enumerate(reader):
        if k == index:
            reader.close()
            return np.frombuffer(frame, dtype=np.uint8).reshape(height, width, 3)
    raise AssertionError("no frame %d in %s" % (index, path))


def test_a_guide_plotting_scripts_video_shows_its_goals_and_labels(testbed, tmp_path):
    """3.8.4 draws goal squares (random colours) with "G0".. labels on r.axes: they are in the video."""
    import imageio_ffmpeg

    from robotarium_recording.arena_figure import ArenaFigure
    from robotarium_recording.bag import Bag
    from robotarium_recording.pictures import render_video
    script = os.path.join(REPO, "examples", "guide", "3_8_4_go_to_point_single_integrator_with_plotting.py")
    command = [sys.executable, "-m", "robotarium_cli", "run", "--no-local-testbed", "--lockstep",
               "--results-dir", str(testbed["results"]), os.path.join(REPO, "devtools", "run_seeded.py"), "1", script]
    completed = subprocess.run(command, env=testbed["env"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True, cwd=os.path.dirname(script), timeout=300)
    out = completed.stdout
    assert completed.returncode == 0, out
    folder = os.path.join(os.path.dirname(script), run_folder(out))
    first, report, _, run = check_folder(folder, "")
    assert first == "Run completed." and "did not complete" not in report
    testbed["runs"]["guide"] = folder

    bag = Bag(folder)
    drawings = bag.drawings()
    scatters = [spec for message in drawings for spec in message["set"].values() if spec["kind"] == "scatter"]
    labels = [spec for message in drawings for spec in message["set"].values() if spec["kind"] == "text"]
    assert len(labels) == 5 and sorted(s["text"] for s in labels) == ["G0", "G1", "G2", "G3", "G4"]
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(os.path.join(folder, "run.mp4"))
    steps = run["runs"][-1]["steps"]
    assert frames == steps + 1 and seconds == pytest.approx((steps + 1) * bag.config().time_step, abs=0.05)
    # Made while the run went (robotarium_recording.live_video), from what ./robotarium run heard over DDS:
    # byte for byte the video the bag gives.
    assert "rendering run.mp4: made as the run went (%d frames)" % frames in out, out
    from_bag = render_video(bag.poses(), drawings, bag.config(), str(tmp_path), run["runs"][-1]["run_id"],
                            progress=False, name="from_bag")
    assert open(os.path.join(folder, "run.mp4"), "rb").read() == open(from_bag, "rb").read()

    # Frame 1 of the video against the same frame drawn without the script's drawing (a video of the
    # first three steps: the whole run's would take seconds for one frame).
    track = bag.poses()
    head = track._replace(**{field: getattr(track, field)[:3] for field in track._fields if field != "ids"})
    plain = render_video(head, [], bag.config(), str(tmp_path), progress=False, name="plain")
    with_drawing, without = _frame(os.path.join(folder, "run.mp4"), 1), _frame(plain, 1)
    assert with_drawing.shape[:2] == (800, 1280)
    view = ArenaFigure.offscreen(bag.config().arena, bag.config().robot_radius, np.zeros((3, 5)))
    height = with_drawing.shape[0]
    readable = []
    for label in labels:
        x, y = view.axes.transData.transform(label["xy"])
        col, row = int(x), int(height - y)
        box = (slice(max(row - 100, 0), row + 100), slice(max(col - 100, 0), col + 100))   # the square around it
        goal = next(s for s in scatters if np.allclose(s["offsets"][0], label["xy"]))   # its square
        colour = np.array(goal["ec"][0][:3]) * 255

        def near(image):
            return int(np.count_nonzero(np.linalg.norm(image[box].astype(float) - colour, axis=2) < 50))

        def dark(image):
            return int(np.count_nonzero(image[row - 8:row + 8, col - 15:col + 15].max(axis=2) < 90))

        assert near(with_drawing) > 150 and near(with_drawing) > 3 * near(without), (label["text"], near(with_drawing),
                                                                                     near(without))
        poses = bag.poses()
        if np.min(np.hypot(poses.x[1] - label["xy"][0], poses.y[1] - label["xy"][1])) > 0.15:   # not under a robot
            assert dark(with_drawing) > 20 + dark(without), label["text"]   # the label's letters
            readable.append(label["text"])
    assert len(readable) >= 3, readable


def test_the_results_page_in_a_real_browser(testbed):
    from devtools.browser import chromium, find_chromium, open_page
    if find_chromium() is None:
        pytest.skip("no chromium here and it could not be installed (./robotarium test installs Debian's "
                    "package when it runs as root with apt-get)")
    folder = testbed["runs"].get("guide")
    if folder is None:
        pytest.skip("needs the guide script's run of test_a_guide_plotting_scripts_video_shows_its_goals_and_labels")
    with chromium() as browser:
        page, errors = open_page(browser, "file://" + os.path.join(folder, "index.html"))
        assert "Run completed." in page.evaluate("document.querySelector('.outcome').textContent")
        played = page.evaluate("""new Promise(async (resolve) => {
            const video = document.getElementById('video');
            await video.play();
            const start = video.currentTime;
            setTimeout(() => resolve({start: start, now: video.currentTime, ready: video.readyState,
                                      width: video.videoWidth, height: video.videoHeight}), 500);
        })""")
        assert played["now"] > played["start"] and played["ready"] >= 2, played
        assert (played["width"], played["height"]) == (1280, 800)
        links = page.evaluate("""Promise.all(Array.from(document.querySelectorAll('a')).map(a => new Promise(done => {
            const request = new XMLHttpRequest();
            request.open('GET', a.href);
            request.onload = () => done([a.getAttribute('href'), request.response.length]);
            request.onerror = () => done([a.getAttribute('href'), -1]);
            request.send();
        })))""")
        hrefs = {href for href, _ in links}
        assert {"run.mp4", "report.txt", "log.txt", "run.json", "run_seeded.py", "metadata.yaml"} <= hrefs, hrefs
        assert all(size > 0 for _, size in links), links
        # long report and log lines wrap: nothing runs off to the side, even in a narrow window
        overflowing = page.evaluate("""(() => {
            document.body.style.maxWidth = '420px';
            return Array.from(document.querySelectorAll('pre, td')).filter(e => e.scrollWidth > e.clientWidth + 1)
                .map(e => e.tagName + ': ' + e.textContent.slice(0, 60));
        })()""")
        assert overflowing == [], overflowing
        page.wait_for_timeout(500)   # console errors that come late
        assert errors == []


def test_replay_plays_a_lockstep_run_in_experiment_time_and_refuses_a_live_testbed(testbed, tmp_path):
    from devtools.rosutil import RosProbe
    from robotarium_msgs.msg import RobotPoses
    bag = testbed["runs"].get("fails")
    if bag is None:
        pytest.skip("needs the run of test_a_script_that_raises_mid_run")
    env = testbed["env"]
    replay = [sys.executable, "-m", "robotarium_recording.replay_node", bag]
    refused = subprocess.run(replay, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=60)
    assert refused.returncode == 2 and "a live testbed answers in /robotarium" in refused.stdout, refused.stdout

    probe = RosProbe(int(env["ROS_DOMAIN_ID"]))
    # When the replay wrote each (DDS's source timestamp): its pacing. This process's receive times measured its own
    # spin: a test worker starved beside the others took the 11 poses in bursts (median gap 2.8 ms, 2026-11-30).
    sent = []
    probe.node.create_subscription(RobotPoses, "/replayed/poses",
                                   lambda m, info: sent.append(info["source_timestamp"]), 100)
    process = subprocess.Popen(replay + ["--namespace", "/replayed", "--delay", "2", "--figure", "--figure-file",
                                         str(tmp_path / "replay.mp4")], env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    try:
        assert probe.spin_until(lambda: process.poll() is not None, 60)
        probe.spin_for(0.2)
    finally:
        probe.close()
        if process.poll() is None:
            process.kill()
        out = process.communicate()[0]
    assert "experiment time" in out, out
    assert len(sent) == 11, out   # steps 0..10
    gaps = np.diff(sent) / 1e9
    assert np.median(gaps) == pytest.approx(0.033, abs=0.01), gaps   # recorded as fast as it ran (a few ms)
    import imageio_ffmpeg
    assert imageio_ffmpeg.count_frames_and_secs(str(tmp_path / "replay.mp4"))[0] == 11   # headless --figure: a video


def _script_process(pid):
    """The script's process (robotarium_cli.runner) that ./robotarium run `pid` started."""
    with open("/proc/%d/task/%d/children" % (pid, pid)) as f:
        children = [int(p) for p in f.read().split()]
    for child in children:
        with open("/proc/%d/cmdline" % child, "rb") as f:
            if b"robotarium_cli.runner" in f.read():
                return child
    raise AssertionError("no script process among %s" % children)


@pytest.mark.parametrize("recorder_late", [False, True], ids=["recorder-on-time", "recorder-late"])
def test_a_script_killed_outright_leaves_the_runs_folder(testbed, recorder_late):
    """kill -9 of the script's process: it says nothing more, yet ./robotarium run finishes the run's own
    folder (the recording) from the bag: the report, the video, the page, run.json with the run's steps.
    recorder-late: the recorder is frozen (SIGSTOP) until the script is dead, so the script never heard
    where its run is recorded (a busy machine's recorder opens the bag a few steps late): run asks it."""
    recorder = testbed["testbed"].processes["recorder"][0]
    if recorder_late:
        recorder.send_signal(signal.SIGSTOP)
    try:
        process = start_run(testbed, "endless.py", "--no-local-testbed")
        head = wait_for_line(process, "running")
        os.kill(_script_process(process.pid), signal.SIGKILL)
    finally:
        recorder.send_signal(signal.SIGCONT)
    code, out = finish(process)
    out = head + out
    assert code == 128 + signal.SIGKILL, out
    folder = os.path.join(str(testbed["scripts"]), run_folder(out))
    first, report, log, run = check_folder(folder, "", out=out)
    assert os.path.dirname(folder) == str(testbed["bags"]) and run["run_id"] == os.path.basename(folder), folder
    assert "No experiment ran" not in report and "##### DEBUG OUTPUT #####" in report, report
    # the testbed ended it when the script stopped answering, and the recording says so
    assert first.startswith("Run did not complete: ") and "Acceptance" not in report, report
    assert run["outcome"] == "interrupted" and "killed by SIGKILL" in run["detail"], run
    assert run["steps"] > 5 and "steps:        %d " % run["steps"] in report, (run["steps"], report)
    assert "running" in log


def test_a_run_command_killed_outright_is_finished_by_the_next_command(testbed, tmp_path):
    """kill -9 of ./robotarium run itself: the orphaned script ends its experiment, and the next
    ./robotarium status (or run, or report) finishes the run folder that run could not."""
    root = tmp_path / "root"   # status finishes the runs of <ROBOTARIUM_ROOT>/results
    process = start_run(dict(testbed, results=root / "results"), "endless.py", "--no-local-testbed")
    wait_for_line(process, "running")
    os.kill(process.pid, signal.SIGKILL)
    process.communicate()
    pending = os.listdir(root / "results" / ".unfinished")
    assert len(pending) == 1, pending
    status = subprocess.run([sys.executable, "-m", "robotarium_cli", "status", "--timeout", "0.5"],
                            env=dict(testbed["env"], ROBOTARIUM_ROOT=str(root)), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, timeout=120, cwd=str(tmp_path))
    out = status.stdout
    assert status.returncode == 0 and "lost its ./robotarium run" in out and "its folder is finished now" in out, out
    folder = out.split("its folder is finished now: ")[1].split("\n")[0].strip()
    folder = os.path.join(str(tmp_path), folder)
    assert os.path.dirname(folder) == str(testbed["bags"]), folder
    first, report, log, run = check_folder(folder, "")
    # The orphaned script ends its experiment saying why (the testbed ends it itself should the script
    # not get that far within its 1.5 s): either way the recording says the run did not complete.
    assert first.startswith("Run did not complete: ") and "##### DEBUG OUTPUT #####" in report, report
    assert "No experiment ran" not in report and "Acceptance" not in report, report
    assert run["outcome"] == "interrupted" and run["steps"] > 5, run
    assert run["step_calls"] is None or run["steps"] >= run["step_calls"] > 5, run
    assert "steps:        %d " % run["steps"] in report and "running" in log
    assert os.listdir(root / "results" / ".unfinished") == []
    again = subprocess.run([sys.executable, "-m", "robotarium_cli", "status", "--timeout", "0.5"],
                           env=dict(testbed["env"], ROBOTARIUM_ROOT=str(root)), stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True, timeout=60)
    assert "lost its ./robotarium run" not in again.stdout   # once


def test_a_testbed_lost_mid_run(testbed):
    """Last: it stops the module's simulator."""
    process = start_run(testbed, "endless.py", "--no-local-testbed")
    head = wait_for_line(process, "running")
    simulator = testbed["testbed"].processes["simulator"][0]
    os.killpg(simulator.pid, signal.SIGKILL)   # lost: it cannot say goodbye (SIGTERM would end the run cleanly)
    code, out = finish(process)
    out = head + out
    assert code == 4, out
    first, report, log, run = check_folder(run_folder(out), str(testbed["scripts"]), out=out)
    assert first.startswith("Run did not complete: the testbed was lost at step "), report
    assert "Acceptance" not in report and run["outcome"] == "testbed_lost" and "TestbedLost" in log
    assert "hint: the testbed stopped answering" in out
