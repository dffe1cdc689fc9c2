"""A real headless browser for tests: Chromium (Debian's package) driven over the DevTools protocol.

    with Browser() as browser:
        page = browser.open("file:///.../index.html")    # waits for the load event
        page.evaluate("document.title")
        page.errors                                        # console errors and uncaught exceptions

`./robotarium test` installs Chromium when it is missing and it can (apt-get as root);
`find_chromium()` is None where there is none, and tests skip saying so. The protocol runs over
a WebSocket (the `websockets` package), one request at a time.
"""
import json
import os
import shutil
import subprocess
import tempfile
import time


def find_chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


class Page:
    def __init__(self, browser, target_id, socket):
        self.browser, self.target_id, self.socket = browser, target_id, socket
        self.next_id = 0
        self.errors = []      # console errors, uncaught exceptions, failed loads
        self.events = []

    def send(self, method, params=None, timeout=30.0):
        self.next_id += 1
        ident = self.next_id
        self.socket.send(json.dumps({"id": ident, "method": method, "params": params or {}}))
        deadline = time.monotonic() + timeout
        while True:
            message = json.loads(self.socket.recv(timeout=max(0.1, deadline - time.monotonic())))
            if message.get("id") == ident:
                if "error" in message:
                    raise RuntimeError("%s: %s" % (method, message["error"]))
                return message.get("result", {})
            self._event(message)

    def _event(self, message):
        method, params = message.get("method"), message.get("params", {})
        self.events.append(method)
        if method == "Runtime.exceptionThrown":
            self.errors.append("exception: %s" % params["exceptionDetails"].get("text"))
        elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            self.errors.append("console.%s: %s" % (params["type"], [a.get("value") for a in params.get("args", [])]))
        elif method == "Log.entryAdded" and params["entry"].get("level") == "error":
            self.errors.append("log: %s %s" % (params["entry"].get("text"), params["entry"].get("url", "")))

    def wait_for(self, method, timeout=30.0):
        deadline = time.monotonic() + timeout
        while method not in self.events:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError("no %s within %.0f s" % (method, timeout))
            try:
                self._event(json.loads(self.socket.recv(timeout=remaining)))
            except TimeoutError:
                break
        return method in self.events

    def evaluate(self, expression, await_promise=False, timeout=30.0):
        result = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                                "awaitPromise": await_promise}, timeout)
        if "exceptionDetails" in result:
            raise RuntimeError("%s: %s" % (expression, result["exceptionDetails"].get("text")))
        return result["result"].get("value")

    def drain(self, seconds):
        """Take the events of the next `seconds` (console errors that come late)."""
        deadline = time.monotonic() + seconds
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return
            try:
                self._event(json.loads(self.socket.recv(timeout=remaining)))
            except TimeoutError:
                return


class Browser:
    """Headless Chromium with a private profile; file:// pages may read other local files (so a
    page's links can be checked from inside it)."""

    def __init__(self, executable=None):
        self.executable = executable or find_chromium()
        if self.executable is None:
            raise FileNotFoundError("no chromium found (./robotarium test installs Debian's package: apt-get "
                                    "install chromium)")
        self.profile = tempfile.mkdtemp(prefix="robotarium-chromium-")
        self.process = None
        self.sockets = []

    def __enter__(self):
        self.process = subprocess.Popen(
            [self.executable, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
             "--no-first-run", "--mute-audio", "--autoplay-policy=no-user-gesture-required",
             "--allow-file-access-from-files", "--remote-debugging-port=0",
             "--user-data-dir=%s" % self.profile, "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        port_file = os.path.join(self.profile, "DevToolsActivePort")
        deadline = time.monotonic() + 60
        while not os.path.exists(port_file) or not open(port_file).read().strip():
            if time.monotonic() > deadline or self.process.poll() is not None:
                self.close()
                raise RuntimeError("chromium did not start (exit code %s)" % self.process.poll())
            time.sleep(0.1)
        self.port = int(open(port_file).read().split()[0])
        return self

    def open(self, url, timeout=60.0):
        """A new tab on `url`, with console errors collected from before the page loads."""
        import urllib.request

        from websockets.sync.client import connect
        request = urllib.request.Request("http://127.0.0.1:%d/json/new?about:blank" % self.port, method="PUT")
        with urllib.request.urlopen(request, timeout=10) as response:
            target = json.load(response)
        socket = connect(target["webSocketDebuggerUrl"], max_size=None, open_timeout=10)
        self.sockets.append(socket)
        page = Page(self, target["id"], socket)
        for domain in ("Runtime", "Log", "Page"):
            page.send(domain + ".enable")
        navigated = page.send("Page.navigate", {"url": url}, timeout)
        if navigated.get("errorText"):
            page.errors.append("navigation: %s" % navigated["errorText"])
        page.wait_for("Page.loadEventFired", timeout)
        return page

    def close(self):
        for socket in self.sockets:
            try:
                socket.close()
            except Exception:
                pass
        if self.process is not None and self.process.poll() is None:
            os.killpg(self.process.pid, 9)
            self.process.wait()
        shutil.rmtree(self.profile, ignore_errors=True)

    def __exit__(self, *exc):
        self.close()
