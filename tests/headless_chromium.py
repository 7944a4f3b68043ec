"""Headless Chromium driven over its DevTools pipe (--remote-debugging-pipe: JSON messages, NUL-terminated, on
fds 3 and 4), so a test can open a page and take screenshots until what it waits for is drawn. No driver and
no websocket: Debian's chromium and the standard library. WebGL runs on SwiftShader (no GPU needed)."""
from __future__ import annotations

import base64
import io
import json
import os
import shutil
import subprocess
import time

import numpy as np

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")
START_TIMEOUT_S = 30.0


def chromium_path() -> str | None:
    return next((p for p in map(shutil.which, CHROMIUM_NAMES) if p), None)


class Chromium:
    def __init__(self, width: int, height: int, exe: str | None = None):
        exe = exe or chromium_path()
        if exe is None:
            raise FileNotFoundError("no chromium: install Debian's chromium (tools/setup.sh)")
        to_r, self._to_w = os.pipe()
        self._from_r, from_w = os.pipe()
        flags = ["--headless", "--no-sandbox", "--remote-debugging-pipe", "--enable-unsafe-swiftshader",
                 "--use-angle=swiftshader", "--no-first-run", "--no-default-browser-check",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--metrics-recording-only", "--disable-default-apps", f"--window-size={width},{height}",
                 f"--user-data-dir={os.environ.get('TMPDIR', '/tmp')}/t1-chromium-{os.getpid()}", "about:blank"]
        self.proc = subprocess.Popen(["bash", "-c", f'exec "$0" "$@" 3<&{to_r} 4>&{from_w}', exe, *flags],
                                     pass_fds=(to_r, from_w), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(to_r)
        os.close(from_w)
        self._buf, self._id, self.session = b"", 0, None

    def call(self, method: str, timeout_s: float = START_TIMEOUT_S, session: bool = True, **params) -> dict:
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params}
        if session and self.session:
            msg["sessionId"] = self.session
        os.write(self._to_w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            while b"\0" in self._buf:
                raw, self._buf = self._buf.split(b"\0", 1)
                reply = json.loads(raw)
                if reply.get("id") == self._id:
                    if "error" in reply:
                        raise RuntimeError(f"chromium {method}: {reply['error']}")
                    return reply["result"]
            chunk = os.read(self._from_r, 1 << 20)
            if not chunk:
                raise RuntimeError(f"chromium exited ({self.proc.wait()}) during {method}")
            self._buf += chunk
        raise TimeoutError(f"chromium {method}: no answer within {timeout_s} s")

    def open(self, url: str) -> None:
        target = self.call("Target.createTarget", session=False, url=url)["targetId"]
        self.session = self.call("Target.attachToTarget", session=False, targetId=target, flatten=True)["sessionId"]

    def screenshot(self) -> np.ndarray:
        """The page as an (H, W, 3) float array in [0, 1]."""
        import matplotlib.image as mpimg
        png = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return mpimg.imread(io.BytesIO(png), format="png")[..., :3], png

    def close(self) -> None:
        for fd in (self._to_w, self._from_r):
            os.close(fd)
        self.proc.terminate()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
