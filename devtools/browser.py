"""A real headless browser for tests: Playwright (PyPI) driving Debian's Chromium.

    with chromium() as browser:
        page, errors = open_page(browser, "file:///.../index.html")
        page.evaluate("document.title")
        errors                      # console errors and uncaught exceptions, as they come

Playwright never downloads a browser here (no `playwright install`): it drives /usr/bin/chromium
(`executable_path`), which `./robotarium test` installs when missing and it can (apt-get as root);
`find_chromium()` is None where there is none, and tests skip saying so.
"""
import contextlib
import shutil

ARGS = ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--mute-audio",
        "--autoplay-policy=no-user-gesture-required", "--allow-file-access-from-files"]


def find_chromium():
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    return None


@contextlib.contextmanager
def chromium():
    """Headless Chromium (a private profile), closed afterwards however the test ends."""
    from playwright.sync_api import sync_playwright
    executable = find_chromium()
    if executable is None:
        raise FileNotFoundError("no chromium found (./robotarium test installs Debian's package: apt-get install "
                                "chromium)")
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=executable, headless=True, args=ARGS)
        try:
            yield browser
        finally:
            browser.close()


def open_page(browser, url=None, **context_options):
    """(a new page in a context of its own, the list its console errors and uncaught exceptions go to);
    on `url` (loaded) when one is given."""
    page = browser.new_context(**context_options).new_page()
    errors = []
    page.on("console", lambda message: errors.append("console.%s: %s" % (message.type, message.text))
            if message.type in ("error", "assert") else None)
    page.on("pageerror", lambda error: errors.append("exception: %s" % error))
    if url is not None:
        page.goto(url)
    return page, errors
