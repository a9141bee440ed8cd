"""Headless Chromium for the viewer's tests, through viewer/web/tests/driver.mjs (playwright-core on Debian's
chromium): one JSON command a line, one answer a line."""
import json
import os
import subprocess

SOURCE = os.environ.get("SS_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
DRIVER = os.path.join(SOURCE, "viewer", "web", "tests", "driver.mjs")


class BrowserError(RuntimeError):
    pass


class Browser:
    def __init__(self):
        if not os.path.isdir(os.path.join(SOURCE, "viewer", "web", "node_modules", "playwright-core")):
            raise RuntimeError("viewer/web/node_modules has no playwright-core: run deploy/install-deps.sh (it runs "
                               "`npm ci` in viewer/web)")
        self.proc = subprocess.Popen(["node", DRIVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, cwd=os.path.dirname(DRIVER))

    def call(self, op, **kw):
        self.proc.stdin.write(json.dumps({"op": op, **kw}) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise BrowserError(f"the browser driver exited ({self.proc.poll()}): {self.proc.stderr.read()}")
        answer = json.loads(line)
        if not answer["ok"]:
            raise BrowserError(f"{op}: {answer['error']}")
        return answer["value"]

    def open(self, url, width=1280, height=800):
        return Page(self, self.call("open", url=url, width=width, height=height))

    def close(self):
        if self.proc.poll() is None:
            try:
                self.call("quit")
            except BrowserError:
                pass
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


class Page:
    def __init__(self, browser, index):
        self.browser, self.index = browser, index

    def eval(self, expr):
        return self.browser.call("eval", page=self.index, expr=expr)

    def wait(self, expr, timeout_ms=30000):
        """Polls `expr` every 50 ms until it is truthy; BrowserError (with the page's console) after the timeout."""
        try:
            return self.browser.call("wait", page=self.index, expr=expr, timeout_ms=timeout_ms)
        except BrowserError as e:
            raise BrowserError(f"{e}\nwaiting for: {expr}\npage console: {self.console()}\n"
                               f"page error banner: {self.eval('window.__viewer && window.__viewer.error()')!r}")

    def fill(self, selector, value):
        return self.browser.call("fill", page=self.index, selector=selector, value=value)

    def click(self, selector):
        return self.browser.call("click", page=self.index, selector=selector)

    def files(self, selector, paths):
        return self.browser.call("files", page=self.index, selector=selector, paths=list(paths))

    def screenshot(self, path):
        return self.browser.call("screenshot", page=self.index, path=path)

    def console(self):
        return self.browser.call("console", page=self.index)
