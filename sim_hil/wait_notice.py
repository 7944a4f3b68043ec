"""A wait that says what it waits for: one line on stderr once it has lasted `first_s`, then one every
`period_s` while it lasts (a background thread; the waiting code itself may block in C meanwhile)."""
from __future__ import annotations

import sys
import threading
import time
from typing import Callable


class WaitNotice:
    """`waiting()` says whether the wait still holds; `line(seconds)` is what to print after that long."""

    def __init__(self, waiting: Callable[[], bool], line: Callable[[float], str], first_s: float,
                 period_s: float, out=None):
        self._waiting, self._line, self._first_s, self._period_s = waiting, line, first_s, period_s
        self._out = out if out is not None else sys.stderr
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="wait-notice", daemon=True)

    def start(self) -> WaitNotice:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join()

    def _run(self) -> None:
        started = time.monotonic()
        delay = self._first_s
        while not self._stop.wait(delay) and self._waiting():
            print(self._line(time.monotonic() - started), file=self._out, flush=True)
            delay = self._period_s
