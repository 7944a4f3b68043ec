"""A log's busy channels (state, IMU, commands, joystick: hundreds of messages a second) decoded a whole
channel at once into numpy columns, for the conversion to Rerun: lcm-gen's Python decoders cost tens of µs a
message, which on a 60 s log is most of the conversion.

The layout comes from the type's own .lcm file (messages/t1/, the contract's source): LCM encodes the
8-byte fingerprint, then the fields big-endian in declaration order, fixed-size arrays inline. The columns
cover the fields up to the first one of variable size (a string, or an array sized by a field). A channel
is taken this way only when every one of its events carries this build's fingerprint and the whole
prefix; otherwise it is left to the project's reader (sim_hil.lcmlog.eventlog), which names what is wrong."""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from messages import contract
from sim_hil.lcmlog.eventlog import Event, lcm_type

LCM_DIR = Path(contract.__file__).resolve().parent / "t1"
NUMPY_TYPES = {"int8_t": ">i1", "boolean": ">i1", "byte": ">u1", "int16_t": ">i2", "int32_t": ">i4",
               "int64_t": ">i8", "float": ">f4", "double": ">f8"}
FIELD = re.compile(r"^\s*(\w+)\s+(\w+)\s*(?:\[\s*(\w+)\s*\])?\s*;")


@dataclass
class Columns:
    """One channel, column-wise: receive stamps [us] and one array per fixed field (row = message)."""
    stamps: np.ndarray
    fields: np.ndarray      # structured array

    def __len__(self) -> int:
        return len(self.stamps)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.fields[name].astype(float)


@lru_cache(maxsize=None)
def prefix_dtype(type_name: str) -> np.dtype:
    """The fixed-size fields at the head of `type_name` (messages/t1/TYPE.lcm) as a big-endian numpy dtype."""
    body = (LCM_DIR / f"{type_name}.lcm").read_text().split("{", 1)[1]
    fields = []
    for line in body.splitlines():
        line = line.split("//")[0]
        if not line.strip() or line.strip().startswith(("const", "}")):
            continue
        m = FIELD.match(line)
        if m is None or m.group(1) not in NUMPY_TYPES or (m.group(3) and not m.group(3).isdigit()):
            break
        fields.append((m.group(2), NUMPY_TYPES[m.group(1)], (int(m.group(3)),) if m.group(3) else ()))
    return np.dtype(fields)


def channel_columns(events: list[Event], channel: str) -> Columns | None:
    """The channel's events as columns, or None when any of them is of another version or cut short."""
    chosen = [ev for ev in events if ev.channel == channel]
    dtype = prefix_dtype(contract.CHANNEL_TYPES[channel])
    fingerprint = lcm_type(channel)._get_packed_fingerprint()
    end = 8 + dtype.itemsize
    if not chosen or any(ev.data[:8] != fingerprint or len(ev.data) < end for ev in chosen):
        return None
    raw = b"".join(ev.data[8:end] for ev in chosen)
    return Columns(np.array([ev.timestamp_us for ev in chosen], np.int64), np.frombuffer(raw, dtype))
