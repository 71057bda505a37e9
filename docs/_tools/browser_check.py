"""The built site as a reader sees it: pages opened in headless chromium (Debian's), over the DevTools protocol.

For each page: every image loaded (complete, with a width), the math typeset by MathJax (served from the site's
own _static/, so no network: at least one rendered formula, none in error), no console error, no uncaught
exception, no failed request, and no request that leaves the machine (anything but file:, data:, about:).

    python docs/_tools/browser_check.py docs/_build/html [PAGE.html ...]   (default: index.html and the first tutorial)

Exit 0 when every page passes, 1 with one line per problem otherwise, 2 when chromium is missing.
"""

from __future__ import annotations

import itertools
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

PAGES = ("index.html", "tutorials/your-robot.html")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync")
LOCAL = ("file:", "data:", "about:", "chrome:", "devtools:")

PROBE = """(async () => {
  if (window.MathJax && MathJax.startup && MathJax.startup.promise) { await MathJax.startup.promise; }
  const imgs = [...document.images];
  await Promise.all(imgs.map(i => i.complete ? null : new Promise(r => { i.onload = i.onerror = r; })));
  return {
    images: imgs.map(i => ({src: i.getAttribute('src'), ok: i.complete && i.naturalWidth > 0})),
    math: document.querySelectorAll('mjx-container').length,
    math_errors: document.querySelectorAll('mjx-merror').length,
    mathjax: !!(window.MathJax && MathJax.version),
  };
})()"""


def find_chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


class _Browser:
    """One headless chromium and one page target, driven over the DevTools protocol's websocket."""

    def __init__(self, chromium: str, timeout: float) -> None:
        from websockets.sync.client import connect

        self.timeout = timeout
        self.profile = tempfile.mkdtemp(prefix="rs-chromium-")
        self.proc = subprocess.Popen([chromium, *FLAGS, f"--user-data-dir={self.profile}", "--remote-debugging-port=0",
                                      "about:blank"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + timeout
        url = None
        while url is None:
            line = self.proc.stderr.readline()
            if not line and (self.proc.poll() is not None or time.monotonic() > deadline):
                raise RuntimeError(f"chromium did not start (exit {self.proc.poll()})")
            if "DevTools listening on " in line:
                url = line.split("DevTools listening on ", 1)[1].strip()
        self._conn = connect(url, max_size=None, open_timeout=timeout)
        self.ws = self._conn.__enter__()
        self.ids = itertools.count(1)
        self.events: list[dict[str, Any]] = []
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            self.call(f"{domain}.enable", session=True)

    def call(self, method: str, session: bool = False, **params: Any) -> dict[str, Any]:
        msg: dict[str, Any] = {"id": next(self.ids), "method": method, "params": params}
        if session:
            msg["sessionId"] = self.session
        self.ws.send(json.dumps(msg))
        deadline = time.monotonic() + self.timeout
        while True:
            reply = json.loads(self.ws.recv(timeout=max(0.1, deadline - time.monotonic())))
            if reply.get("id") == msg["id"]:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_for(self, method: str) -> None:
        if any(e.get("method") == method for e in self.events):
            return
        deadline = time.monotonic() + self.timeout
        while True:
            event = json.loads(self.ws.recv(timeout=max(0.1, deadline - time.monotonic())))
            self.events.append(event)
            if event.get("method") == method:
                return

    def close(self) -> None:
        try:
            self._conn.__exit__(None, None, None)
        finally:
            self.proc.kill()
            self.proc.wait()
            shutil.rmtree(self.profile, ignore_errors=True)


def check_page(chromium: str, page: Path, timeout: float = 60.0) -> tuple[dict[str, Any], list[str]]:
    """Open ``page`` (a built HTML file); what the probe found, and the problems (empty: the page passes)."""
    b = _Browser(chromium, timeout)
    try:
        b.events.clear()
        b.call("Page.navigate", session=True, url=page.resolve().as_uri())
        b.wait_for("Page.loadEventFired")
        found = b.call("Runtime.evaluate", session=True, expression=PROBE, awaitPromise=True,
                       returnByValue=True)["result"]["value"]
        time.sleep(0.2)  # a last console message or failed request of the load
        b.call("Runtime.evaluate", session=True, expression="0")
    finally:
        b.close()
    problems = [f"image did not load: {i['src']}" for i in found["images"] if not i["ok"]]
    if not found["images"]:
        problems.append("no image on the page")
    if not found["mathjax"]:
        problems.append("MathJax did not load")
    if found["math"] == 0:
        problems.append("no formula rendered by MathJax")
    if found["math_errors"]:
        problems.append(f"{found['math_errors']} formula(s) in error")
    for e in b.events:
        p, m = e.get("params", {}), e.get("method")
        if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            problems.append("console error: " + " ".join(str(a.get("value", a.get("description", ""))) for a in p["args"]))
        elif m == "Runtime.exceptionThrown":
            problems.append("uncaught exception: " + p["exceptionDetails"].get("text", "")
                            + " " + str(p["exceptionDetails"].get("exception", {}).get("description", "")))
        elif m == "Log.entryAdded" and p["entry"].get("level") == "error":
            problems.append(f"console error: {p['entry'].get('text')} ({p['entry'].get('url', '')})")
        elif m == "Network.loadingFailed" and not p.get("canceled"):
            problems.append(f"request failed: {p.get('errorText')}")
        elif m == "Network.requestWillBeSent" and not p["request"]["url"].startswith(LOCAL):
            problems.append(f"request leaves the machine: {p['request']['url']}")
    return found, problems


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__.strip().splitlines()[-3], file=sys.stderr)
        return 2
    site, pages = Path(argv[0]), argv[1:] or list(PAGES)
    chromium = find_chromium()
    if chromium is None:
        print("docs-check: chromium is not installed (apt-get install chromium)", file=sys.stderr)
        return 2
    failed = False
    for name in pages:
        found, problems = check_page(chromium, site / name)
        print(f"{name}: {len(found['images'])} image(s), {found['math']} formula(s), "
              + ("ok" if not problems else f"{len(problems)} problem(s)"))
        for p in problems:
            print(f"  {p}")
        failed |= bool(problems)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
