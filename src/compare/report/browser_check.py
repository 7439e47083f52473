"""Check a report page in a real headless Chromium, driven over the DevTools protocol.

Uses ``--remote-debugging-pipe`` (JSON messages over file descriptors 3 and 4), so no
websocket library is needed. Checks: the page loads from file:// without console errors or
uncaught exceptions, every <img> decodes, the viewer (if any) is ready and responds to a
number-key press (and leaves Ctrl+number to the browser), a screenshot is not blank, and
nothing makes the page wider than the window (wide tables scroll on their own).

    python -m compare.report.browser_check reports/index.html reports/scene-cbox.html
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        p = shutil.which(name)
        if p:
            return p
    return None


class CDP:
    """Minimal DevTools client over --remote-debugging-pipe."""

    def __init__(self, exe: str, width: int = 1400, height: int = 1000) -> None:
        self.profile = tempfile.mkdtemp(prefix="pgi-chromium-")
        r_to_chrome, w_to_chrome = os.pipe()
        r_from_chrome, w_from_chrome = os.pipe()
        # chromium reads commands on fd 3 and writes replies on fd 4
        self.proc = subprocess.Popen(
            [
                exe,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-extensions",
                "--remote-debugging-pipe",
                f"--user-data-dir={self.profile}",
                f"--window-size={width},{height}",
                "about:blank",
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            pass_fds=(3, 4),
            preexec_fn=lambda: (os.dup2(r_to_chrome, 3), os.dup2(w_from_chrome, 4)) and None,
        )
        os.close(r_to_chrome)
        os.close(w_from_chrome)
        self.w = os.fdopen(w_to_chrome, "wb", buffering=0)
        self.r = os.fdopen(r_from_chrome, "rb", buffering=0)
        self.buf = b""
        self.next_id = 0
        self.events: list[dict[str, Any]] = []

    def _read_msg(self, deadline: float) -> dict[str, Any]:
        import select

        while b"\0" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("no reply from chromium")
            ready, _, _ = select.select([self.r], [], [], left)
            if ready:
                chunk = os.read(self.r.fileno(), 1 << 20)
                if not chunk:
                    raise RuntimeError("chromium closed the DevTools pipe")
                self.buf += chunk
        msg, self.buf = self.buf.split(b"\0", 1)
        return json.loads(msg)

    def send(
        self, method: str, params: dict | None = None, session: str | None = None, timeout=30.0
    ) -> dict[str, Any]:
        self.next_id += 1
        mid = self.next_id
        msg: dict[str, Any] = {"id": mid, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        self.w.write(json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            m = self._read_msg(deadline)
            if m.get("id") == mid:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self.events.append(m)

    def wait_event(self, name: str, timeout: float = 30.0) -> dict[str, Any]:
        for i, ev in enumerate(self.events):
            if ev.get("method") == name:
                return self.events.pop(i)
        deadline = time.monotonic() + timeout
        while True:
            m = self._read_msg(deadline)
            if m.get("method") == name:
                return m
            self.events.append(m)

    def close(self) -> None:
        try:
            self.send("Browser.close", timeout=5)
        except Exception:  # noqa: BLE001 - best effort shutdown
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.w.close()
        self.r.close()
        shutil.rmtree(self.profile, ignore_errors=True)


@dataclass
class PageCheck:
    url: str
    errors: list[str] = field(default_factory=list)
    images: int = 0
    broken_images: list[str] = field(default_factory=list)
    viewer: bool = False
    viewer_key_ok: bool | None = None
    screenshot_std: float = 0.0
    screenshot: bytes = b""
    overflow_px: int = 0  # how much wider than the window the page is
    overflowing: list[str] = field(default_factory=list)  # the elements that make it so
    values: list[Any] = field(default_factory=list)  # of the expressions asked for, in order

    @property
    def ok(self) -> bool:
        return (
            not self.errors
            and not self.broken_images
            and (self.viewer_key_ok is not False)
            and self.screenshot_std > 2.0
            and self.overflow_px <= 0
        )


def check_page(
    path: str | Path,
    exe: str | None = None,
    screenshot: str | Path | None = None,
    width: int = 1400,
    evaluate: tuple[str, ...] = (),
):
    """Load ``path`` in headless Chromium, ``width`` pixels wide, and run the checks, then
    ``evaluate`` each JavaScript expression in turn (``values``); returns a
    :class:`PageCheck`."""
    exe = exe or find_chromium()
    if exe is None:
        raise FileNotFoundError("no chromium found")
    url = Path(path).resolve().as_uri()
    res = PageCheck(url)
    cdp = CDP(exe, width=width)
    try:
        target = cdp.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        sid = cdp.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for dom in ("Page", "Runtime", "Log"):
            cdp.send(f"{dom}.enable", session=sid)
        cdp.send("Page.navigate", {"url": url}, session=sid)
        cdp.wait_event("Page.loadEventFired", timeout=60)

        def ev(expr: str) -> Any:
            r = cdp.send(
                "Runtime.evaluate",
                {"expression": expr, "returnByValue": True, "awaitPromise": True},
                session=sid,
            )
            if "exceptionDetails" in r:
                res.errors.append(f"evaluate {expr[:40]}: {r['exceptionDetails'].get('text')}")
                return None
            return r.get("result", {}).get("value")

        imgs = ev(
            "Promise.all(Array.from(document.images).map(i => i.decode().then(() => null,"
            " () => i.alt || i.src.slice(0, 60))))"
        )
        res.images = int(ev("document.images.length") or 0)
        res.broken_images = [x for x in (imgs or []) if x]
        res.broken_images += (
            ev(
                "Array.from(document.images).filter(i => !(i.naturalWidth > 0))"
                ".map(i => i.alt || 'img')"
            )
            or []
        )
        res.viewer = bool(ev("!!document.getElementById('viewer')"))
        if res.viewer:
            ready = ev("document.getElementById('viewer').dataset.ready === '1'")
            ev("document.getElementById('viewer').scrollIntoView()")  # keys act while in view
            before = ev("document.getElementById('viewer').dataset.method")

            def press(digit: int, modifiers: int = 0) -> None:  # CDP modifiers: 2 = Ctrl
                key = {"key": str(digit), "code": f"Digit{digit}", "modifiers": modifiers}
                key["windowsVirtualKeyCode"] = 48 + digit
                cdp.send("Input.dispatchKeyEvent", {"type": "keyDown", "text": str(digit), **key},
                         session=sid)  # fmt: skip
                cdp.send("Input.dispatchKeyEvent", {"type": "keyUp", **key}, session=sid)

            press(0)
            after = ev("document.getElementById('viewer').dataset.method")
            press(1, modifiers=2)  # Ctrl+1 is the browser's (a tab), not the viewer's
            kept = ev("document.getElementById('viewer').dataset.method")
            res.viewer_key_ok = (
                bool(ready) and after == "reference" and before != after and kept == after
            )
        res.overflow_px = int(
            ev("document.documentElement.scrollWidth - document.documentElement.clientWidth") or 0
        )
        if res.overflow_px > 0:
            res.overflowing = (
                ev(
                    "Array.from(document.body.querySelectorAll('*')).filter(x => "
                    "x.getBoundingClientRect().right > document.documentElement.clientWidth)"
                    ".slice(0, 5).map(x => x.tagName + '.' + x.className)"
                )
                or []
            )
        res.values = [ev(expression) for expression in evaluate]
        shot = cdp.send("Page.captureScreenshot", {"format": "png"}, session=sid)
        res.screenshot = base64.b64decode(shot["data"])
        # drain pending events, then collect console errors and exceptions
        try:
            cdp.send("Runtime.evaluate", {"expression": "1"}, session=sid, timeout=5)
        except Exception:  # noqa: BLE001
            pass
        for m in cdp.events:
            p = m.get("params", {})
            if m.get("method") == "Runtime.exceptionThrown":
                d = p.get("exceptionDetails", {})
                res.errors.append(
                    f"exception: {d.get('exception', {}).get('description') or d.get('text')}"
                )
            elif m.get("method") == "Runtime.consoleAPICalled" and p.get("type") in (
                "error",
                "assert",
            ):
                res.errors.append(
                    "console: " + " ".join(str(a.get("value", "")) for a in p.get("args", []))
                )
            elif m.get("method") == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
                en = p["entry"]
                res.errors.append(f"log: {en.get('text')} {en.get('url', '')}".strip())
    finally:
        cdp.close()
    res.screenshot_std = _png_std(res.screenshot)
    if screenshot:
        Path(screenshot).write_bytes(res.screenshot)
    return res


def _png_std(data: bytes) -> float:
    if not data:
        return 0.0
    import io

    from matplotlib.image import imread

    a = imread(io.BytesIO(data), format="png")
    return float(np.asarray(a[..., :3], dtype=np.float64).std() * 255.0)


def main(argv: list[str]) -> int:
    bad = 0
    for p in argv:
        r = check_page(p)
        status = "ok" if r.ok else "FAILED"
        print(
            f"{status}: {p}: {r.images} images ({len(r.broken_images)} broken), "
            f"viewer={'yes' if r.viewer else 'no'} key={r.viewer_key_ok}, "
            f"screenshot std {r.screenshot_std:.1f}"
        )
        if r.overflow_px > 0:
            print(f"    {r.overflow_px} px wider than the window: {', '.join(r.overflowing)}")
        for err in r.errors + [f"broken image: {b}" for b in r.broken_images]:
            print("   ", err)
        bad += not r.ok
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
