"""The Robotarium service (robotarium_portal) in a real browser: headless Chromium (Playwright) walking the
guide's whole flow against `./robotarium serve`.

The walk starts `./robotarium serve` itself, with its mail sent to a real SMTP server (aiosmtpd) the test
starts, its runs and verification on ROS_DOMAIN_IDs of their own, and stops the service mid-run to check
that the experiment runs again and completes after the restart. The security rules through Django's test
client are the portal's own tests (robotarium_portal/test/).
"""
import os
import re
import signal
import socket
import sqlite3
import subprocess
import threading
import time
import urllib.request

import pytest

from devtools.rosutil import REPO, processes_on_domain, processes_with_env, unique_domain_id

PASSWORD = "a-long-Passphrase-7"


# --- the whole flow in a real browser, against ./robotarium serve -------------------------------------------

# The experiment of the walk: a main file, a helper module it imports and a data file it reads; it saves a
# data file and prints. It turns its robots in place until the test drops `release` into its working
# folder (at most 900 steps, 30 s; its verification runs them all), so the test can stop the service while
# it surely runs. The second experiment drives four robots head-on into each other: rejected.
WALK_FILES = {
    "main.py": """import os
import numpy as np
import rps.robotarium as robotarium
from helper import turn_rates

gains = np.loadtxt("gains.txt")
print("read %d gains from gains.txt" % len(gains), flush=True)
N = 2
r = robotarium.Robotarium(number_of_robots=N, show_figure=False, sim_in_real_time=True,
                          initial_conditions=np.array([[-0.4, 0.4], [0.0, 0.0], [0.0, 0.0]]))
for k in range(900):
    r.get_poses()
    r.set_velocities(np.arange(N), turn_rates(gains, N))
    r.step()
    if k >= 30 and os.path.exists("release"):
        break
np.savetxt("turned.txt", [k])
print("helper module and data file used; the robots turned for", k + 1, "steps", flush=True)
r.call_at_scripts_end()
""",
    "helper.py": """import numpy as np


def turn_rates(gains, n):
    return np.vstack([np.zeros(n), gains[:n]])
""",
    "gains.txt": "0.5\n-0.5\n0.2\n",
}
TIMEOUT = 240.0
HEAD_ON = os.path.join(REPO, "tests", "data", "head_on_no_barrier.py")   # 168 collision iterations


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Serve:
    """./robotarium serve in a session of its own, its output collected."""

    def __init__(self, args, env):
        self.lines = []
        self.process = subprocess.Popen([os.path.join(REPO, "robotarium"), "serve", *args], env=env, cwd=REPO,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                        start_new_session=True)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.process.stdout:
            self.lines.append(line.rstrip("\n"))

    def wait_for_address(self):
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline and self.process.poll() is None:
            for line in self.lines:
                found = re.search(r"portal is at (http://\S+)", line)
                if found:
                    return found.group(1)
            time.sleep(0.2)
        raise AssertionError("serve did not start:\n" + "\n".join(self.lines))

    def stop(self):
        """Ctrl-C, as an operator stops it; never left behind."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=120)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()
                raise AssertionError("serve did not stop within 120 s:\n" + "\n".join(self.lines)) from None
        return self.process.returncode


class SmtpInbox:
    """A real SMTP server (aiosmtpd) on localhost that keeps what it receives."""

    def __init__(self):
        from aiosmtpd.controller import Controller
        self.messages = []
        inbox = self

        class Handler:
            async def handle_DATA(self, server, session, envelope):
                inbox.messages.append((envelope.rcpt_tos, envelope.content.decode("utf-8", "replace")))
                return "250 OK"

        self.controller = Controller(Handler(), hostname="127.0.0.1", port=free_port())
        self.controller.start()
        self.port = self.controller.port

    def wait_for(self, to, subject_part):
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline:
            for rcpt, text in self.messages:
                if to in rcpt and subject_part in text:
                    return text
            time.sleep(0.2)
        raise AssertionError("no mail to %s about %r; got %s" % (to, subject_part, self.messages))

    def close(self):
        self.controller.stop()


def goto(page, url):
    page.goto(url)


def fill_and_click(page, values, button):
    """Type the values into the form's fields (by id) and click the button: a real form post."""
    for field, value in values.items():
        page.fill("#" + field, value)
    with page.expect_navigation():
        page.click(button)


def text_of(page, selector):
    element = page.query_selector(selector)
    return element.text_content() if element else None


def body_text(page):
    return page.inner_text("body")


def log_in(page, base, email):
    goto(page, base + "login/")
    fill_and_click(page, {"id_username": email, "id_password": PASSWORD}, "button[type=submit]")
    assert "Dashboard" in page.title(), body_text(page)


def log_out(page):
    with page.expect_navigation():
        page.click("header form button")


def sign_up(page, base, email, name):
    goto(page, base + "signup/")
    fill_and_click(page, {"id_email": email, "id_password": PASSWORD, "id_confirmation": PASSWORD, "id_name": name,
                          "id_city": "Atlanta", "id_state": "GA", "id_institute": "Georgia Tech",
                          "id_reason": "multi-robot class"}, "button[type=submit]")
    assert "Thank you for signing up" in body_text(page)


def status_of(page, url):
    """The HTTP status a fetch of url gets from this page (its session's cookies)."""
    return page.evaluate("url => fetch(url).then(r => r.status)", url)


def experiment_row(data, pk):
    with sqlite3.connect(os.path.join(data, "portal.sqlite3"), timeout=30) as db:
        return db.execute("SELECT state, attempts, detail FROM robotarium_portal_experiment WHERE id = ?",
                          (pk,)).fetchone()


def service_logs(data):
    """The workers' logs and the jobs' output, for a failure's message."""
    texts = []
    for folder, _, names in os.walk(data):
        for name in names:
            if name.startswith("worker-") or name in ("output.txt", "verification-output.txt"):
                with open(os.path.join(folder, name), errors="replace") as f:
                    texts.append("--- %s\n%s" % (os.path.join(folder, name), f.read()[-3000:]))
    return "\n".join(texts)


def wait_for_state(data, pk, states, attempts=None):
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline:
        row = experiment_row(data, pk)
        if row[0] in states and (attempts is None or row[1] == attempts):
            return row
        if row[0] in ("rejected", "failed") and row[0] not in states:
            raise AssertionError("experiment %d %s: %s\n%s" % (pk, row[0], row[2], service_logs(data)))
        time.sleep(0.3)
    raise AssertionError("experiment %d still %s (wanted %s)\n%s" % (pk, row, states, service_logs(data)))


@pytest.mark.e2e
def test_ctrl_c_stops_serve_while_it_answers_requests(tmp_path):
    """Ctrl-C stops `serve` whatever its main thread is doing: while it handles connections too, where waitress took
    the stop for a connection's error and went on serving (a whole suite's browser test above, 2026-12-01). Pages
    asked for without a pause by eight clients, then SIGINT, five times (no worker: --jobs 0)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ROBOTARIUM_PORTAL", "DJANGO_"))}
    for attempt in range(5):
        serve = Serve(["--data", str(tmp_path / "service"), "--port", str(free_port()), "--jobs", "0"], env)
        try:
            base = serve.wait_for_address()
            asking = threading.Event()

            def ask():
                while not asking.is_set():
                    try:
                        urllib.request.urlopen(base + "login/", timeout=5).read()
                    except OSError:
                        pass

            clients = [threading.Thread(target=ask, daemon=True) for _ in range(8)]
            for client in clients:
                client.start()
            time.sleep(1.0 + 0.3 * attempt)
            serve.process.send_signal(signal.SIGINT)
            try:
                code = serve.process.wait(timeout=30)
            finally:
                asking.set()
            assert code == 0 and "[robotarium] stopped" in serve.lines, (attempt, "\n".join(serve.lines))
        finally:
            if serve.process.poll() is None:
                os.killpg(serve.process.pid, signal.SIGKILL)
                serve.process.wait()


def test_the_whole_flow_in_a_real_browser_with_a_restart_mid_run(tmp_path):
    from devtools.browser import chromium, find_chromium, open_page
    if find_chromium() is None:
        pytest.skip("no chromium here and it could not be installed (./robotarium test installs Debian's "
                    "package when it runs as root with apt-get)")
    data = str(tmp_path / "service")
    for name, text in WALK_FILES.items():
        (tmp_path / name).write_text(text)
    run_domain, verify_domain = unique_domain_id(), unique_domain_id()
    inbox = SmtpInbox()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ROBOTARIUM_PORTAL", "DJANGO_"))}
    env.update(ROBOTARIUM_SMTP_HOST="127.0.0.1", ROBOTARIUM_SMTP_PORT=str(inbox.port))
    args = ["--data", data, "--port", str(free_port()), "--run-domain", str(run_domain),
            "--verify-domain", str(verify_domain)]
    admin = subprocess.run([os.path.join(REPO, "robotarium"), "serve", "--data", data, "--create-admin",
                            "admin@example.org"], input=PASSWORD + "\n", text=True, env=env, cwd=REPO,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=TIMEOUT)
    assert admin.returncode == 0 and "is an administrator" in admin.stdout, admin.stdout
    serve = Serve(args, env)
    shots = os.environ.get("ROBOTARIUM_PORTAL_SCREENSHOTS")
    try:
        base = serve.wait_for_address()
        with chromium() as browser:
            page, errors = open_page(browser)
            sign_up(page, base, "ada@example.org", "Ada Lovelace")
            confirmation = inbox.wait_for("ada@example.org", "confirm your email")
            link = re.search(r"(http://\S+/confirm/\S+/)", confirmation).group(1)
            assert link.startswith(base), (link, base)   # serve's own address, on its own port
            goto(page, link)
            assert "Your email address is confirmed" in body_text(page)

            log_in(page, base, "admin@example.org")
            goto(page, base + "staff/approvals/")
            assert "ada@example.org" in body_text(page)
            with page.expect_navigation():
                page.click('button[value="ada@example.org"]')
            assert "Approved Ada Lovelace" in body_text(page)
            approved = inbox.wait_for("ada@example.org", "your account is approved")
            assert re.findall(r"http://\S+", approved) == [base], approved   # not localhost:8000
            log_out(page)

            log_in(page, base, "ada@example.org")
            goto(page, base + "experiments/new/")
            page.set_input_files("#id_upload", [str(tmp_path / name) for name in WALK_FILES])
            # the main file is chosen among the files being added, on the create page itself
            assert page.eval_on_selector_all("#id_main_file option", "o => o.map(x => x.value)") == ["helper.py",
                                                                                                   "main.py"]
            assert page.input_value("#id_main_file") == "main.py"
            page.select_option("#id_main_file", "main.py")
            fill_and_click(page, {"id_title": "Turn <in> place", "id_description": "two robots turn",
                                  "id_estimated_duration": "90", "id_number_of_robots": "2"}, "button[value=submit]")
            assert "Submitted" in body_text(page), body_text(page)
            pk = int(re.search(r"/experiments/(\d+)/", page.url).group(1))
            assert text_of(page, "h1").startswith("Turn <in> place")   # the title is text
            goto(page, base + "experiments/new/")
            page.set_input_files("#id_upload", [HEAD_ON])
            fill_and_click(page, {"id_title": "Head-on", "id_estimated_duration": "10", "id_number_of_robots": "4"},
                           "button[value=submit]")
            head_on = int(re.search(r"/experiments/(\d+)/", page.url).group(1))
            goto(page, base + "experiments/%d/" % pk)

            # Verified, queued, running: the page names the step; then the service is stopped mid-run.
            deadline = time.monotonic() + TIMEOUT
            while text_of(page, "#step") is None:
                assert time.monotonic() < deadline, body_text(page) + service_logs(data)
                time.sleep(0.5)
                goto(page, base + "experiments/%d/" % pk)
            assert text_of(page, "#state") == "running"
            if shots:
                goto(page, base)
                screenshot(page, os.path.join(shots, "portal_dashboard.png"))
            assert serve.stop() == 0, "\n".join(serve.lines)
            assert not [line for line in serve.lines if "error" in line], serve.lines   # a clean stop says none
            # the truth: run 1 was cut short by the stop, and it waits at the head of the queue to run again
            state, attempts, detail = experiment_row(data, pk)
            assert (state, attempts) == ("queued", 1) and "The service stopped during run 1" in detail, detail
            assert processes_on_domain(run_domain) == {} and processes_on_domain(verify_domain) == {}

            serve = Serve(args, env)
            assert serve.wait_for_address() == base
            # Off the run's page: its live stream, back once the service is, reloads it when the run completes, and
            # that reload raced with the goto to the head-on experiment's page below (a whole suite: the head-on's
            # state read from the run's page).
            goto(page, base)
            wait_for_state(data, pk, ("running",), attempts=2)
            work = os.path.join(data, "experiments", str(pk), "run-2", "work")
            deadline = time.monotonic() + TIMEOUT
            while not os.path.isdir(work):
                assert time.monotonic() < deadline
                time.sleep(0.2)
            open(os.path.join(work, "release"), "w").close()
            state, attempts, detail = wait_for_state(data, pk, ("completed",))
            assert "Run completed." in detail
            inbox.wait_for("ada@example.org", "has completed")

            # The head-on script: rejected by the verification, the rule with its count and first step shown
            # on its page and in the mail.
            wait_for_state(data, head_on, ("rejected",))
            goto(page, base + "experiments/%d/" % head_on)
            rejection = text_of(page, "#detail")
            assert text_of(page, "#state") == "rejected" and "collisions:" in rejection, rejection
            assert re.search(r"collisions: \d+ times, limit 100 \(first at step \d+\)", rejection), rejection
            assert "collisions:" in inbox.wait_for("ada@example.org", "issues found")
            # As root, each verification ran in its box on the slot's warm verification testbed (the box joined the
            # slot's network namespace: jobs.start_warm_testbed), the head-on rejection's counts included.
            if os.geteuid() == 0:
                for number in (pk, head_on):
                    with open(os.path.join(data, "experiments", str(number), "verification-output.txt")) as f:
                        said = f.read()
                    assert "on the warm verification testbed" in said, said

            goto(page, base + "experiments/%d/" % pk)
            body = body_text(page)
            for section in ("Experiment Settings", "Experiment Video", "Scripts", "Return Messages", "Data Files",
                            "Log Files"):
                assert section in body, section
            assert "The service stopped during run 1" in body   # said truthfully on its page
            log = text_of(page, "#log")
            assert "read 3 gains from gains.txt" in log and "helper module and data file used" in log, log
            assert "turned.txt" in text_of(page, "#data-files")
            assert {"main.py", "helper.py", "gains.txt"} <= set(text_of(page, "#scripts").split())
            assert ".mcap" in text_of(page, "#log-files") and "Run completed." in text_of(page, "#report")
            played = page.evaluate("""new Promise(async (resolve) => {
                const video = document.getElementById('video');
                await video.play();
                const start = video.currentTime;
                setTimeout(() => resolve({start: start, now: video.currentTime, ready: video.readyState}), 500);
            })""")
            assert played["now"] > played["start"] and played["ready"] >= 2, played
            saved = page.evaluate("""fetch(document.querySelector('#data-files a').href).then(r => r.text())""")
            assert int(float(saved)) >= 30
            if shots:
                page.evaluate("document.getElementById('video').pause()")
                screenshot(page, os.path.join(shots, "portal_results.png"), full=True)
            results_url = page.url
            log_out(page)

            # A second user: 404 on the first user's results, files and settings.
            sign_up(page, base, "bob@example.org", "Bob")
            log_in(page, base, "bob@example.org")
            for url in (results_url, results_url + "settings.json", results_url + "files/main.py",
                        results_url + "results/log.txt"):
                assert status_of(page, url) == 404, url

        # serve killed outright: its workers notice (their lifeline) and stop; nothing of the service is left.
        serve.process.kill()
        serve.process.wait()
        deadline = time.monotonic() + 60
        while processes_with_env("ROBOTARIUM_PORTAL_DATA", os.path.realpath(data)):
            assert time.monotonic() < deadline, processes_with_env("ROBOTARIUM_PORTAL_DATA", os.path.realpath(data))
            time.sleep(0.2)
    finally:
        serve.stop()
        inbox.close()
    assert processes_on_domain(run_domain) == {} and processes_on_domain(verify_domain) == {}


def screenshot(page, path, full=False):
    """A PNG of the page at a laptop's width (docs/)."""
    page.set_viewport_size({"width": 1280, "height": 800})
    page.screenshot(path=path, full_page=full)
