"""Capture a run's LCM traffic with t1-lcm-logger (sim_hil/core/lcm_logger.cpp: a process of its own, so
logging costs the simulator and the runtime nothing; LCM's event-log format, as lcm-logger writes it) and
stamp the log with a run_info_t.

Only the project's channels are logged (the list is messages/contract.json's). The logger is
ready when the run_info_t it was sent is on disk: the run's first state can then not be missed, which a
replay needs (the runtime's PREPARE ramp starts from the first state it sees). At the end the same marker
is sent again and waited for, so the run's last messages are on disk before the logger is stopped."""
from __future__ import annotations

import os
import shlex
import signal
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import lcm
from t1 import run_info_t

from messages import contract
from sim_hil.launch import LOGGER
from sim_hil.lcmlog.eventlog import LogProblems, read_events

FLUSH_INTERVAL_MS = 20        # the logger's disk flush period: how soon readiness is visible
MARK_TIMEOUT_S = 10.0         # a logger that has not written the run_info_t marker by then is broken
MARK_POLL_S = 0.05            # run_info_t re-sent at this period until it shows up in the file
STOP_TIMEOUT_S = 10.0         # SIGINT -> the logger writes what it holds and exits


def logger_path() -> str:
    if not LOGGER.exists():
        raise FileNotFoundError(f"{LOGGER} is not built: run `make build`")
    return str(LOGGER)


def lcm_tool(name: str) -> str:
    """The C executable of an lcm tool. Not the wheel's console script of the same name: that is a Python
    wrapper which does not pass SIGINT on, so stopping it would orphan the real logger mid-write."""
    exe = Path(lcm.LCM_BIN_DIR) / name
    if not exe.exists():
        raise FileNotFoundError(f"{name} not found in {exe.parent} (it comes with the pinned lcm wheel: run "
                                "`make setup`)")
    return str(exe)


@dataclass
class RunInfo:
    run_name: str
    producer: str
    clock: str
    policy_path: str = ""
    policy_hash: str = ""
    runtime_args: list[str] = field(default_factory=list)
    sim_args: list[str] = field(default_factory=list)

    def message(self) -> run_info_t:
        m = run_info_t()
        m.utime = int(time.time() * 1e6)
        m.run_name, m.producer, m.clock = self.run_name, self.producer, self.clock
        m.policy_path, m.policy_hash = self.policy_path, self.policy_hash
        m.runtime_args, m.sim_args = shlex.join(self.runtime_args), shlex.join(self.sim_args)
        return m


class LogCapture:
    """t1-lcm-logger on `url` writing `path` (overwritten), started and stamped; stop() ends it cleanly."""

    def __init__(self, path: Path | str, url: str, info: RunInfo):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.path.unlink(missing_ok=True)
        self.proc = subprocess.Popen(
            [logger_path(), f"--flush-interval={FLUSH_INTERVAL_MS}", f"--lcm-url={url}",
             f"--channels={','.join(sorted(contract.CHANNELS.values()))}", str(self.path)],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        self._info, self._lc = info, lcm.LCM(url)
        if not self._stamp_and_wait(0):
            self.stop()
            raise RuntimeError(f"t1-lcm-logger wrote nothing to {self.path} within {MARK_TIMEOUT_S} s")

    def _stamp_and_wait(self, since_byte: int) -> bool:
        """Publish run_info_t until the logger has written one past `since_byte`. At the start this proves
        it is subscribed; at the end, that everything sent before (the run has stopped) is on disk."""
        stamp = self._info.message().encode()
        deadline = time.monotonic() + MARK_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"t1-lcm-logger exited {self.proc.returncode}: {self.proc.stderr.read().strip()}")
            self._lc.publish(contract.CH_RUN_INFO, stamp)
            time.sleep(MARK_POLL_S)
            if self.path.exists() and contract.CH_RUN_INFO.encode() in self._bytes_from(since_byte):
                return True
        return False

    def _bytes_from(self, offset: int) -> bytes:
        """The log from `offset` on (the end marker is looked for only in what the run wrote last)."""
        with open(self.path, "rb") as f:
            f.seek(offset)
            return f.read()

    def stop(self) -> Path:
        """End marker, SIGINT, then cut a partly written last event (a logger killed mid-write leaves one)."""
        if self.proc.poll() is None:
            self._stamp_and_wait(self.path.stat().st_size if self.path.exists() else 0)
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.path.exists():
            problems = LogProblems()
            read_events(self.path, problems)
            if problems.truncated_at is not None:
                os.truncate(self.path, problems.truncated_at)
        return self.path

    def __enter__(self) -> "LogCapture":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
