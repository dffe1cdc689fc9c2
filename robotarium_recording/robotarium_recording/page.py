"""index.html of a run folder: the run's results page, as the Robotarium's results page shows a run.

How the run ended first, then the video, the trajectory plot, the report and the printed output
(inline, and as files), the run's settings, and every file of the folder as a link (the script,
its data files, the recording). One static file with relative links and no script, so it opens
from the file system (file://) in any browser, and the folder can be moved or zipped as it is.
"""
import html
import os
import time
import urllib.parse

from robotarium_core import run_record

LOG_SHOWN = 200_000   # characters of log.txt shown inline (the whole file is linked)

STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1320px; color: #222; padding: 0 1em; }
h1 { font-size: 1.4em; margin-bottom: 0.2em; }
.outcome { font-size: 1.1em; padding: 0.5em 0.8em; border-radius: 4px; margin: 0.6em 0 1em; }
.completed { background: #e3f4e3; border-left: 6px solid #2e8b57; }
.failed { background: #fbe5e1; border-left: 6px solid #c0392b; }
video, img.plot { width: 100%; max-width: 1280px; border: 1px solid #ccc; }
pre { background: #f6f6f6; padding: 0.8em; overflow: auto; font-size: 0.85em; max-height: 40em;
      white-space: pre-wrap; overflow-wrap: anywhere; }
table { border-collapse: collapse; }
td { padding: 0.15em 1em 0.15em 0; vertical-align: top; overflow-wrap: anywhere; }
td:first-child { color: #555; white-space: nowrap; }
"""


def _link(path, text=None):
    href = urllib.parse.quote(path.replace(os.sep, "/"))
    return '<a href="%s">%s</a>' % (html.escape(href, quote=True), html.escape(text or path))


def _read(path, limit=None):
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read()
    except OSError:
        return None
    if limit is not None and len(text) > limit:
        text = "... (%d characters before this are in the file)\n" % (len(text) - limit) + text[-limit:]
    return text


def _files(run_dir):
    """Every file under run_dir (relative paths, sorted), but the page itself."""
    out = []
    for root, dirs, files in os.walk(run_dir):
        dirs.sort()
        for name in sorted(files):
            rel = os.path.relpath(os.path.join(root, name), run_dir)
            if rel != "index.html":
                out.append(rel)
    return out


def _settings(run, numbers, bag):
    """(label, html) rows of the run's metadata."""
    rows = []
    run = run or run_record.RunRecord()
    last = run.last or run_record.Experiment(real_time=None)
    settings = numbers["settings"] if numbers else {}
    config = numbers["config"] if numbers else None
    run_id = settings.get("run_id") or last.run_id or run.run_id
    rows.append(("run id", html.escape(run_id) if run_id else "none: no experiment ran on a testbed"))
    if run.script:
        name = os.path.basename(run.script)
        rows.append(("script", _link(name) + " (run from %s)" % html.escape(run.script)))
    if run.started:
        rows.append(("started", html.escape(run.started)))
    mode = settings.get("mode") or {True: "realtime", False: "lockstep"}.get(last.real_time)
    if mode:
        rows.append(("mode", html.escape(mode)))
    robots = numbers["number_of_robots"] if numbers else last.number_of_robots
    if robots:
        rows.append(("robots", str(robots)))
    if numbers:
        rows.append(("steps", "%d (%.2f s of experiment time)" % (numbers["iterations"],
                                                                   numbers["iterations"] * config.time_step)))
        count, arrays, largest, mean = numbers["safety_interventions"]
        rows.append(("safety interventions", "%d of %d command arrays%s" % (
            count, arrays, " (largest change %.3g, mean %.3g)" % (largest, mean) if count else "")))
        rows.append(("testbed", html.escape("arena %s m, time step %g s, robot diameter %g m, command timeout %g s"
                                            % (list(config.arena), config.time_step, config.robot_diameter,
                                               config.command_timeout))))
    if run.script:   # a run of ./robotarium run (not a bag alone)
        rows.append(("wall time", "%.1f s" % run.wall_time))
        rows.append(("exit code", str(run.exit_code)))
    if bag is not None:
        rows.append(("recording", html.escape("%s (%d messages on %d topics)" % (
            bag.path, bag.message_count, len(bag.topics)))))
    rows.append(("page made", time.strftime("%Y-%m-%d %H:%M:%S")))
    return rows


def write_page(run_dir, run=None, numbers=None, bag=None):
    """Write <run_dir>/index.html from what the folder holds; returns its path. `run` is its
    run_record.RunRecord (read from the folder when not given), `numbers` results.recompute()'s, `bag`
    the Bag."""
    if run is None:
        run = run_record.read(run_dir) or run_record.RunRecord()
    files = _files(run_dir)
    report = _read(os.path.join(run_dir, "report.txt"))
    first_line = numbers["first_line"] if numbers else (report or "").split("\n", 1)[0]
    completed = numbers["completed"] if numbers else run.outcome == "completed"
    title = (numbers and numbers["settings"]["run_id"]) or run.run_id or os.path.basename(run_dir)
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             '<link rel="icon" href="data:,">',
             "<title>%s - Robotarium run</title>" % html.escape(title), "<style>%s</style></head><body>" % STYLE,
             "<h1>%s</h1>" % html.escape(title),
             '<div class="outcome %s">%s</div>' % ("completed" if completed else "failed", html.escape(first_line))]
    video = next((f for f in ("run.mp4", "run.gif") if f in files), None)
    if video == "run.mp4":
        parts.append('<h2>Video</h2><video id="video" src="run.mp4" controls muted preload="auto" playsinline>'
                     'Your browser cannot play MP4 (H.264): %s</video>' % _link("run.mp4"))
    elif video == "run.gif":
        parts.append('<h2>Video</h2><img class="plot" src="run.gif" alt="the run">')
    if "trajectories.png" in files:
        parts.append('<h2>Trajectories</h2><img class="plot" src="trajectories.png" alt="paths of the robots">')
    parts.append("<h2>Run</h2><table>%s</table>" % "".join(
        "<tr><td>%s</td><td>%s</td></tr>" % (label, value) for label, value in _settings(run, numbers, bag)))
    if report is not None:
        parts.append("<h2>Report</h2><pre>%s</pre><p>%s</p>" % (html.escape(report), _link("report.txt")))
    log = _read(os.path.join(run_dir, "log.txt"), LOG_SHOWN)
    if log is not None:
        parts.append("<h2>Output</h2><pre>%s</pre><p>%s</p>" % (html.escape(log) or "(the script printed nothing)",
                                                             _link("log.txt")))
    parts.append("<h2>Files</h2><ul>%s</ul>" % "".join(
        "<li>%s (%s)</li>" % (_link(f), _size(os.path.join(run_dir, f))) for f in files))
    parts.append("</body></html>")
    path = os.path.join(run_dir, "index.html")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(parts) + "\n")
    return path


def _size(path):
    size = os.path.getsize(path)
    for unit in ("bytes", "kB", "MB", "GB"):
        if size < 1000 or unit == "GB":
            return "%d %s" % (size, unit) if unit == "bytes" else "%.1f %s" % (size, unit)
        size /= 1000.0
