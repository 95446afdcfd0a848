"""Headless Chromium driven over the DevTools protocol, for the browser tests.

The browser is started with ``--remote-debugging-pipe``: it reads JSON commands on its file
descriptor 3 and writes replies and events on 4, each message ending in a NUL byte (the pipe
transport of Chrome's DevTools protocol). No driver package is needed, only the browser.

:func:`find_chromium` says where the browser is. In CI (``CI`` or ``CASADRONE_REQUIRE_BROWSER``
set, as ``.ci/run`` does) a missing browser fails the test instead of skipping it.
"""

from __future__ import annotations

import base64
import json
import os
import select
import shutil
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def browser_required() -> bool:
    """Whether a missing browser is a failure (CI) rather than a skip."""
    return bool(os.environ.get("CASADRONE_REQUIRE_BROWSER") or os.environ.get("CI"))


def find_chromium() -> str:
    """The browser's path; skips the test, or fails it in CI, when there is none."""
    path = os.environ.get("CHROMIUM") or next(filter(None, map(shutil.which, NAMES)), None)
    if path is None:
        message = ("no chromium on this machine (install it: apt-get install -y chromium; "
                   ".ci/run does)")
        if browser_required():
            pytest.fail(message)
        pytest.skip(message)
    return path


@dataclass
class PageReport:
    """What one page load showed: console errors and warnings, uncaught exceptions, failed
    requests, and what the page's own script ``probe`` returned."""

    url: str
    errors: list[str] = field(default_factory=list)
    failed_requests: list[str] = field(default_factory=list)
    probe: dict = field(default_factory=dict)


class Chromium:
    """One headless browser; use as a context manager. ``load(url, probe)`` loads a page and
    evaluates the JavaScript expression ``probe`` (which must return JSON) once it has loaded."""

    def __init__(self, executable: str, profile: Path, width: int = 1280, height: int = 900):
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()

        def fds_3_and_4():  # in the child, before exec: the pipe ends on fds 3 and 4
            read, write = os.dup(to_browser_r), os.dup(from_browser_w)
            os.dup2(read, 3)
            os.dup2(write, 4)

        self.proc = subprocess.Popen(
            [executable, "--headless", "--no-sandbox", "--disable-gpu", "--remote-debugging-pipe",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--no-first-run", "--no-default-browser-check", "--mute-audio",
             f"--user-data-dir={profile}", f"--window-size={width},{height}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            preexec_fn=fds_3_and_4, close_fds=False)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buffer = b""
        self._next_id = 0
        self._events: list[dict] = []
        self.size = (width, height)
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target,
                                 flatten=True)["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            self.call(f"{domain}.enable", session=True)
        # the viewport exactly width × height (the window size includes no browser chrome then)
        self.call("Emulation.setDeviceMetricsOverride", session=True, width=width, height=height,
                  deviceScaleFactor=1, mobile=False)

    # ---- the pipe ----------------------------------------------------------------------------

    def _send(self, message: dict) -> None:
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")

    def _receive(self, timeout: float) -> dict:
        while b"\0" not in self._buffer:
            ready, _, _ = select.select([self._from_browser], [], [], timeout)
            if not ready:
                raise TimeoutError(f"no message from the browser in {timeout} s")
            chunk = os.read(self._from_browser, 1 << 20)
            if not chunk:
                raise RuntimeError("the browser closed its DevTools pipe")
            self._buffer += chunk
        raw, _, self._buffer = self._buffer.partition(b"\0")
        return json.loads(raw)

    def call(self, method: str, session: bool = False, timeout: float = 60, **params) -> dict:
        """Send one command and wait for its reply (events that arrive meanwhile are kept)."""
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params}
        if session:
            message["sessionId"] = self.session
        self._send(message)
        deadline = time.monotonic() + timeout
        while True:
            reply = self._receive(max(deadline - time.monotonic(), 0.01))
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self._events.append(reply)

    def _wait_for(self, method: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not any(e.get("method") == method for e in self._events):
            self._events.append(self._receive(max(deadline - time.monotonic(), 0.01)))

    # ---- pages -------------------------------------------------------------------------------

    def load(self, url: str, probe: str = "({})", timeout: float = 60,
             settle_s: float = 0.3) -> PageReport:
        """Load ``url``, wait for its load event (and ``settle_s`` more for late scripts), then
        evaluate ``probe``; report the console errors and failed requests seen meanwhile."""
        self._events.clear()
        self.call("Page.navigate", session=True, url=url)
        self._wait_for("Page.loadEventFired", timeout)
        end = time.monotonic() + settle_s
        while time.monotonic() < end:
            try:
                self._events.append(self._receive(max(end - time.monotonic(), 0.01)))
            except TimeoutError:
                break
        result = self.call("Runtime.evaluate", session=True, expression=probe,
                           returnByValue=True, awaitPromise=True)
        report = PageReport(url=url, probe=result.get("result", {}).get("value") or {})
        if "exceptionDetails" in result:
            report.errors.append(f"probe failed: {result['exceptionDetails']}")
        requests: dict[str, str] = {}
        for event in self._events:
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.exceptionThrown":
                details = params["exceptionDetails"]
                report.errors.append("uncaught: " + details.get("exception", {}).get(
                    "description", details.get("text", "")))
            elif method == "Runtime.consoleAPICalled" and params["type"] in ("error", "assert"):
                report.errors.append("console: " + " ".join(
                    str(a.get("value", a.get("description", ""))) for a in params["args"]))
            elif method == "Log.entryAdded" and params["entry"]["level"] == "error":
                report.errors.append("log: " + params["entry"]["text"] + " "
                                     + params["entry"].get("url", ""))
            elif method == "Network.requestWillBeSent":
                requests[params["requestId"]] = params["request"]["url"]
            elif method == "Network.responseReceived" and params["response"]["status"] >= 400:
                report.failed_requests.append(f"{params['response']['status']} "
                                              f"{params['response']['url']}")
            elif method == "Network.loadingFailed" and not params.get("canceled"):
                report.failed_requests.append(f"{params.get('errorText')} "
                                              f"{requests.get(params['requestId'], '?')}")
        return report

    def screenshot(self, path: Path, full_page: bool = True) -> Path:
        """A PNG of the current page (the whole page when ``full_page``)."""
        shot = self.call("Page.captureScreenshot", session=True, format="png",
                         captureBeyondViewport=full_page)
        path.write_bytes(base64.b64decode(shot["data"]))
        return path

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=10)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for fd in (self._to_browser, self._from_browser):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


#: Probe run on every page: figures (img and inline svg) and the links on it.
PAGE_PROBE = """(() => {
  const imgs = [...document.images].map(i => ({src: i.currentSrc || i.src,
      ok: i.complete && i.naturalWidth > 0 && i.naturalHeight > 0}));
  const svgs = [...document.querySelectorAll('svg[width]')]
      .filter(s => s.closest('.md-header, .md-nav, .md-footer, button, label, a') === null)
      .map(s => { const b = s.getBoundingClientRect();
                  const shapes = s.querySelectorAll('path, use').length;
                  return {w: b.width, h: b.height, shapes}; });
  const links = [...document.querySelectorAll('a[href]')].map(a => a.href);
  const ids = [...document.querySelectorAll('[id]')].map(e => e.id)
      .concat([...document.querySelectorAll('a[name]')].map(a => a.name));
  const main = document.querySelector('article, main, body');
  return {title: document.title, imgs, svgs, links, ids,
          text: main ? main.innerText.length : 0,
          h1: document.querySelectorAll('h1').length};
})()"""
