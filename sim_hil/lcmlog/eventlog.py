"""Read LCM event logs (the format lcm-logger writes) without trusting them.

Format of one event, big-endian: sync word 0xEDA1DA01 (u32), event number (i64), timestamp [us] (i64),
channel length (i32), data length (i32), channel bytes, data bytes. lcm's own reader stops or raises at
the first damaged byte; this one reports what is wrong (truncated tail, corrupt span skipped by scanning
for the next sync word, unknown channel, another type version) and keeps every event it can read. State
recorded before imu_t / joint_state_t were signed (messages/auth.py LEGACY_STATE_FINGERPRINTS) is read as
today's type, unsigned, and said so: such a log still replays (replay.py signs its state as the robot).
"""
from __future__ import annotations

import importlib
import struct
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from messages import contract
from messages.auth import upgrade_legacy_state

SYNC = 0xEDA1DA01
HEADER = struct.Struct(">IqqII")
MAX_CHANNEL_LEN = 256                 # LCM's own limit on channel names [bytes]
MAX_DATA_LEN = 64 * 1024 * 1024       # far above any project message; larger means a corrupt length field


@dataclass(frozen=True)
class Event:
    offset: int         # byte offset of the event in the file
    timestamp_us: int   # receive time (the logger's wall clock)
    channel: str
    data: bytes


@dataclass
class LogProblems:
    corrupt_spans: list[tuple[int, int]] = field(default_factory=list)   # [start, end) bytes skipped
    truncated_at: int | None = None       # offset of an incomplete last event
    unknown_channels: Counter = field(default_factory=Counter)           # channel -> events skipped
    wrong_version: Counter = field(default_factory=Counter)              # channel -> events skipped
    undecodable: Counter = field(default_factory=Counter)                # channel -> events skipped
    wrong_version_fingerprint: dict = field(default_factory=dict)        # channel -> (found, expected)
    legacy_state: Counter = field(default_factory=Counter)               # channel -> events read as unsigned
    legacy_fingerprint: dict = field(default_factory=dict)               # channel -> the legacy fingerprint

    def messages(self, path: Path) -> list[str]:
        """One clear sentence per problem (empty when the log is clean)."""
        out = [f"{path}: corrupt bytes {a}..{b} ({b - a} bytes) skipped, reading resumed at the next event"
               for a, b in self.corrupt_spans]
        if self.truncated_at is not None:
            out.append(f"{path}: truncated: the event at byte {self.truncated_at} is incomplete (kept every "
                       "event before it)")
        for ch, n in sorted(self.unknown_channels.items()):
            out.append(f"{path}: channel {ch!r} is not in messages/contract.json: {n} events skipped")
        for ch, n in sorted(self.wrong_version.items()):
            found, expected = self.wrong_version_fingerprint[ch]
            out.append(f"{path}: channel {ch}: {n} events of another {contract.CHANNEL_TYPES[ch]} version "
                       f"(fingerprint {found:#018x}, this build expects {expected:#018x}) skipped")
        for ch, n in sorted(self.legacy_state.items()):
            out.append(f"{path}: channel {ch}: {n} events of the {contract.CHANNEL_TYPES[ch]} version before state "
                       f"was signed (fingerprint {self.legacy_fingerprint[ch]:#018x}) read as unsigned frames of "
                       f"today's version (kept)")
        for ch, n in sorted(self.undecodable.items()):
            out.append(f"{path}: channel {ch}: {n} events do not decode as {contract.CHANNEL_TYPES[ch]} "
                       "(truncated or malformed payload) skipped")
        return out


def read_events(path: Path, problems: LogProblems) -> list[Event]:
    """Every readable event, in file order; damage is recorded in `problems`, never raised."""
    return parse_events(Path(path).read_bytes(), problems)


def parse_events(blob: bytes, problems: LogProblems) -> list[Event]:
    """read_events on a log's bytes."""
    events, pos, n = [], 0, len(blob)
    while pos < n:
        if n - pos < HEADER.size:
            problems.truncated_at = pos
            break
        sync, _num, stamp, ch_len, data_len = HEADER.unpack_from(blob, pos)
        if sync != SYNC or ch_len == 0 or ch_len > MAX_CHANNEL_LEN or data_len > MAX_DATA_LEN:
            nxt = blob.find(SYNC.to_bytes(4, "big"), pos + 1)
            end = n if nxt < 0 else nxt
            problems.corrupt_spans.append((pos, end))
            pos = end
            continue
        body = pos + HEADER.size
        if body + ch_len + data_len > n:
            problems.truncated_at = pos
            break
        channel = blob[body:body + ch_len].decode("utf-8", errors="replace")
        events.append(Event(pos, stamp, channel, blob[body + ch_len:body + ch_len + data_len]))
        pos = body + ch_len + data_len
    return events


@lru_cache(maxsize=None)
def lcm_type(channel: str):
    """The generated Python class of a contract channel (None when the channel is not a project one)."""
    name = contract.CHANNEL_TYPES.get(channel)
    return None if name is None else getattr(importlib.import_module(f"t1.{name}"), name)


@lru_cache(maxsize=None)
def _fingerprint(cls) -> int:
    return struct.unpack(">Q", cls._get_packed_fingerprint())[0]


@dataclass
class ProjectLog:
    """A log decoded on the project's channels: channel -> [(event, message)] in file order."""
    path: Path
    events: list[Event]
    messages: dict[str, list[tuple[Event, object]]]
    problems: LogProblems

    def first(self, channel: str):
        entries = self.messages.get(channel, [])
        return entries[0][1] if entries else None


def decode_events(events: list[Event], problems: LogProblems, channels=None) -> dict[str, list[tuple[Event, object]]]:
    """The events of project channels decoded (channel -> [(event, message)]); what cannot be, in `problems`.
    channels: decode only these project channels (the others' events stay undecoded); default all."""
    decoded: dict[str, list[tuple[Event, object]]] = defaultdict(list)
    for ev in events:
        if channels is not None and ev.channel in contract.CHANNEL_TYPES and ev.channel not in channels:
            continue
        cls = lcm_type(ev.channel)
        if cls is None:
            problems.unknown_channels[ev.channel] += 1
            continue
        expected = _fingerprint(cls)
        found = struct.unpack(">Q", ev.data[:8])[0] if len(ev.data) >= 8 else None
        data = ev.data
        if found is not None and found != expected:
            upgraded = upgrade_legacy_state(contract.CHANNEL_TYPES[ev.channel], ev.data, expected)
            if upgraded is not None:
                problems.legacy_state[ev.channel] += 1
                problems.legacy_fingerprint[ev.channel] = found
                data, found = upgraded, expected
        if found is not None and found != expected:
            problems.wrong_version[ev.channel] += 1
            problems.wrong_version_fingerprint[ev.channel] = (found, expected)
            continue
        try:
            decoded[ev.channel].append((ev, cls.decode(data)))
        except Exception:          # lcm-gen's decoders raise ValueError or struct.error on short data
            problems.undecodable[ev.channel] += 1
    return dict(decoded)


def open_log(path: Path | str, channels=None) -> ProjectLog:
    """Read and decode a log; raises only when the file cannot be read at all or holds no event. channels: decode
    only these project channels (the others' events are kept undecoded, in `events`); default all."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"{path}: a folder, not a log file (*.lcmlog)")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such log file")
    problems = LogProblems()
    events = read_events(path, problems)
    if not events:
        raise ValueError(f"{path}: no readable LCM event ({'; '.join(problems.messages(path)) or 'empty file'})")
    return ProjectLog(path, events, decode_events(events, problems, channels), problems)


def write_events(path: Path, events: list[Event]) -> Path:
    """A well-formed log of `events` (how a damaged log is made playable by lcm-logplayer)."""
    with open(path, "wb") as f:
        for number, ev in enumerate(events):
            channel = ev.channel.encode()
            f.write(HEADER.pack(SYNC, number, ev.timestamp_us, len(channel), len(ev.data)))
            f.write(channel)
            f.write(ev.data)
    return Path(path)
