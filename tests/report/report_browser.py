"""Load a page in headless Chromium and record what went wrong, through the DevTools protocol.

Why the protocol and not ``--enable-logging=stderr`` or ``--dump-dom``: Chromium's stderr mixes
console messages with its own noise (D-Bus, GPU, sandbox), its format changes between versions
and it has no reliable line for a failed request; ``--dump-dom`` says nothing about either.
The DevTools protocol reports each event as data. Chromium is started with
``--remote-debugging-pipe`` (commands on fd 3, events and replies on fd 4, JSON messages ending
in NUL), so no port is opened and no websocket library is needed. While the page loads we
record:

- ``Runtime.consoleAPICalled`` (console.error / warning / assert) and ``Runtime.exceptionThrown``;
- ``Log.entryAdded`` at level error or warning: Chromium's own messages, among them every
  failed resource load and every Content-Security-Policy violation;
- ``Network.requestWillBeSent`` for every URL the page asks for (anything but ``file:`` and
  ``data:`` is a remote resource) and ``Network.loadingFailed``;
- ``Page.javascriptDialogOpening``: an ``alert()`` that ran (an injection that got through).

Then it checks that every image decoded, takes screenshots and prints the page to PDF.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import queue
import shutil
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--disable-default-apps",
    "--mute-audio",
    "--hide-scrollbars",
)


def find_chromium() -> str | None:
    explicit = os.environ.get("ODELAB_CHROMIUM")
    if explicit:
        return explicit if Path(explicit).exists() else None
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None


@dataclass
class PageReport:
    """What happened while a page loaded."""

    url: str
    console: list[str] = field(default_factory=list)  # console errors, warnings and exceptions
    log: list[str] = field(default_factory=list)  # browser log errors and warnings
    requests: list[str] = field(default_factory=list)  # every URL requested
    failed_requests: list[str] = field(default_factory=list)
    dialogs: list[str] = field(default_factory=list)
    broken_images: list[str] = field(default_factory=list)
    loaded: bool = False
    screenshot: bytes = b""
    full_screenshot: bytes = b""
    pdf: bytes = b""
    narrow_screenshot: bytes = b""
    evaluations: dict = field(default_factory=dict)

    @property
    def pdf_pages(self) -> int:
        """Pages of the printed PDF (Chromium writes each page object uncompressed)."""
        import re

        return len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", self.pdf))

    @property
    def remote_requests(self) -> list[str]:
        return [u for u in self.requests if not u.startswith(("file:", "data:", "about:"))]

    @property
    def problems(self) -> list[str]:
        return ([f"console: {m}" for m in self.console] + [f"log: {m}" for m in self.log]
                + [f"failed request: {u}" for u in self.failed_requests]
                + [f"remote request: {u}" for u in self.remote_requests]
                + [f"dialog: {m}" for m in self.dialogs] + [f"broken image: {m}" for m in self.broken_images]
                + ([] if self.loaded else ["the page never fired its load event"]))


class Chromium:
    """One headless Chromium driven over --remote-debugging-pipe."""

    def __init__(self, binary: str, profile: Path, timeout: float = 60.0):
        self.timeout = timeout
        to_chrome_r, self._to_chrome_w = os.pipe()
        self._from_chrome_r, from_chrome_w = os.pipe()

        def wire_fds():  # in the child: the protocol's fds 3 (commands in) and 4 (messages out)
            a = fcntl.fcntl(to_chrome_r, fcntl.F_DUPFD, 10)
            b = fcntl.fcntl(from_chrome_w, fcntl.F_DUPFD, 10)
            os.dup2(a, 3)
            os.dup2(b, 4)

        self.proc = subprocess.Popen(
            [binary, *FLAGS, "--remote-debugging-pipe", f"--user-data-dir={profile}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            close_fds=False, preexec_fn=wire_fds)
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._next_id = 0
        self._replies: dict[int, dict] = {}
        self._events: queue.Queue = queue.Queue()
        self._cond = threading.Condition()
        self._stderr: list[bytes] = []
        threading.Thread(target=self._read, daemon=True).start()
        threading.Thread(target=self._drain_stderr, daemon=True).start()

    def _drain_stderr(self) -> None:
        for line in self.proc.stderr:
            self._stderr.append(line)

    def _read(self) -> None:
        buf = b""
        while True:
            chunk = os.read(self._from_chrome_r, 1 << 16)
            if not chunk:
                with self._cond:
                    self._cond.notify_all()
                return
            buf += chunk
            while b"\0" in buf:
                raw, buf = buf.split(b"\0", 1)
                message = json.loads(raw)
                if "id" in message:
                    with self._cond:
                        self._replies[message["id"]] = message
                        self._cond.notify_all()
                else:
                    self._events.put(message)

    def send(self, method: str, params: dict | None = None, session: str | None = None) -> dict:
        self._next_id += 1
        mid = self._next_id
        message = {"id": mid, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self._to_chrome_w, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + self.timeout
        with self._cond:
            while mid not in self._replies:
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None:
                    raise RuntimeError(f"Chromium did not answer {method}; stderr:\n"
                                       + b"".join(self._stderr[-20:]).decode(errors="replace"))
                self._cond.wait(min(left, 0.5))
            reply = self._replies.pop(mid)
        if "error" in reply:
            raise RuntimeError(f"{method}: {reply['error']}")
        return reply.get("result", {})

    def events(self, wait: float) -> list[dict]:
        """Events received so far, waiting up to ``wait`` seconds for the first one."""
        out = []
        try:
            out.append(self._events.get(timeout=wait))
            while True:
                out.append(self._events.get_nowait())
        except queue.Empty:
            pass
        return out

    def close(self) -> None:
        try:
            self.send("Browser.close")
        except (RuntimeError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for fd in (self._to_chrome_w, self._from_chrome_r):
            try:
                os.close(fd)
            except OSError:
                pass


def _record(report: PageReport, event: dict) -> None:
    method, params = event.get("method"), event.get("params", {})
    if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "warning", "assert"):
        text = " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", []))
        report.console.append(f"{params['type']}: {text}")
    elif method == "Runtime.exceptionThrown":
        details = params.get("exceptionDetails", {})
        report.console.append(f"exception: {details.get('exception', {}).get('description') or details.get('text')}")
    elif method == "Log.entryAdded":
        entry = params.get("entry", {})
        if entry.get("level") in ("error", "warning"):
            report.log.append(f"{entry.get('source')}: {entry.get('text')} {entry.get('url', '')}".strip())
    elif method == "Network.requestWillBeSent":
        report.requests.append(params.get("request", {}).get("url", ""))
    elif method == "Network.loadingFailed":
        if not params.get("canceled"):
            report.failed_requests.append(f"{params.get('errorText')} ({params.get('requestId')})")
    elif method == "Page.javascriptDialogOpening":
        report.dialogs.append(params.get("message", ""))
    elif method == "Page.loadEventFired":
        report.loaded = True


# Every <details> shows its content when printing (the stylesheet's print rules): measured with
# the print media type emulated, each closed <details> must lay out its content.
PRINT_CHECK = """(() => {
  // sections the print stylesheet leaves out on purpose (.no-print: the screen-only appendix) do not count
  const closed = [...document.querySelectorAll('details:not([open])')].filter(d => !d.closest('.no-print'));
  const hidden = closed.filter(d => {
    const content = [...d.children].filter(c => c.tagName !== 'SUMMARY');
    return content.length && content.every(c => c.getBoundingClientRect().height === 0);
  });
  return {closed: closed.length, hidden: hidden.length};
})()"""
# Where figures and tables sit: a figure is clipped if it reaches past the page's width or is
# drawn at another aspect ratio than its PNG; a table is clipped if it reaches past the page
# and is not inside a frame that scrolls it (.table-wrap).
LAYOUT_CHECK = """(() => {
  const page = document.documentElement.clientWidth;
  const out = {width: page, scrollWidth: document.documentElement.scrollWidth, figures: [], tables: []};
  for (const img of document.querySelectorAll('figure img')) {
    const r = img.getBoundingClientRect();
    if (r.width === 0) continue;
    const natural = img.naturalWidth / img.naturalHeight, shown = r.width / r.height;
    out.figures.push({alt: img.alt, left: r.left, right: r.right, height: r.height,
                      squashed: Math.abs(natural - shown) > 0.02 * natural});
  }
  for (const t of document.querySelectorAll('table')) {
    const r = t.getBoundingClientRect();
    if (r.width === 0) continue;
    const wrap = t.closest('.table-wrap');
    const framed = wrap !== null && ['auto', 'scroll'].includes(getComputedStyle(wrap).overflowX)
      && wrap.getBoundingClientRect().right <= page + 1;
    out.tables.push({id: t.className || (t.querySelector('th') || {}).textContent || '', right: r.right,
                     framed: framed});
  }
  return out;
})()"""
# A4 with the report's print margins (12 mm each side), in CSS pixels: the width printing lays out.
A4_CONTENT_WIDTH = round((210 - 24) / 25.4 * 96)
A4_CONTENT_HEIGHT = round((297 - 28) / 25.4 * 96)
IMAGE_CHECK = """[...document.images].filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.alt || i.src.slice(0, 60))"""


def load_page(binary: str, page: Path, profile: Path, *, width: int = 1280, height: int = 4000,
              settle: float = 1.0, narrow: int = 400) -> PageReport:
    """Open ``page`` from disk, record problems, screenshot it and print it to PDF.

    ``evaluations`` gets ``"print"`` (collapsed sections laid out in print), ``"layout"``
    (figures and tables at ``width``), ``"print_layout"`` (the same under the print stylesheet
    at the width of an A4 page's content) and ``"narrow"`` (at ``narrow`` px, a phone, with
    ``narrow_screenshot``).
    """
    url = page.resolve().as_uri()
    report = PageReport(url)
    browser = Chromium(binary, profile)
    try:
        target = browser.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = browser.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            browser.send(f"{domain}.enable", session=session)
        browser.send("Emulation.setDeviceMetricsOverride",
                     {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}, session=session)
        browser.send("Page.navigate", {"url": url}, session=session)
        deadline = time.monotonic() + browser.timeout
        while not report.loaded and time.monotonic() < deadline:
            for event in browser.events(0.5):
                if event.get("sessionId") == session:
                    _record(report, event)
                if event.get("method") == "Page.javascriptDialogOpening":
                    browser.send("Page.handleJavaScriptDialog", {"accept": True}, session=session)
        end = time.monotonic() + settle  # late console messages and requests
        while time.monotonic() < end:
            for event in browser.events(0.2):
                if event.get("sessionId") == session:
                    _record(report, event)
        broken = browser.send("Runtime.evaluate", {"expression": IMAGE_CHECK, "returnByValue": True},
                              session=session)
        report.broken_images = broken.get("result", {}).get("value", [])
        shot = browser.send("Page.captureScreenshot", {"format": "png"}, session=session)
        report.screenshot = base64.b64decode(shot["data"])
        size = browser.send("Page.getLayoutMetrics", session=session)["cssContentSize"]
        clip = {"x": 0, "y": 0, "width": size["width"], "height": min(size["height"], 30000), "scale": 1}
        full = browser.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True, "clip": clip},
                            session=session)
        report.full_screenshot = base64.b64decode(full["data"])

        def evaluate(expression):
            value = browser.send("Runtime.evaluate", {"expression": expression, "returnByValue": True},
                                 session=session)
            return value.get("result", {}).get("value")

        def viewport(w, h, mobile=False):
            browser.send("Emulation.setDeviceMetricsOverride",
                         {"width": w, "height": h, "deviceScaleFactor": 1, "mobile": mobile}, session=session)

        report.evaluations["layout"] = evaluate(LAYOUT_CHECK)
        browser.send("Emulation.setEmulatedMedia", {"media": "print"}, session=session)
        report.evaluations["print"] = evaluate(PRINT_CHECK)
        viewport(A4_CONTENT_WIDTH, A4_CONTENT_HEIGHT)
        report.evaluations["print_layout"] = evaluate(LAYOUT_CHECK)
        browser.send("Emulation.setEmulatedMedia", {"media": ""}, session=session)
        viewport(narrow, 900, mobile=True)
        report.evaluations["narrow"] = evaluate(LAYOUT_CHECK)
        shot = browser.send("Page.captureScreenshot", {"format": "png"}, session=session)
        report.narrow_screenshot = base64.b64decode(shot["data"])
        viewport(width, height)
        pdf = browser.send("Page.printToPDF", {"printBackground": True, "preferCSSPageSize": True},
                           session=session)
        report.pdf = base64.b64decode(pdf["data"])
        for event in browser.events(0.2):
            if event.get("sessionId") == session:
                _record(report, event)
    finally:
        browser.close()
    return report
