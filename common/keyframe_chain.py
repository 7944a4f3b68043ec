"""The shipped keyframe getup: a folder of member artifacts and its manifest chain.json, the switched chain
roll → rise → stand that common/events.keyframe_stage runs (one file format for training's evaluation, the
simulator's evaluation and the runtime's chain mode, runtime/src/keyframe_chain.cpp).

chain.json:
    {"format": "t1-keyframe-chain/1",
     "stages": {"roll": "<file>.safetensors", "rise": "<file>.safetensors", "stand": "<file>.safetensors"},
     "handover": "kneel_band"}
`stages`: each member's artifact, a file in the same folder; `handover`: the rise → stand hand-over, by its name in
HANDOVERS (the upright bounds are the message contract's; the other hand-overs are keyframe_stage's fixed rules).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from common import events

MANIFEST = "chain.json"
FORMAT = "t1-keyframe-chain/1"
# the rise → stand hand-over by name: §4.8's gate, or the kneel band (‖u − e_z‖ bounds of events.kneel_gate)
HANDOVERS = {"kneel_gate": events.KNEEL_GATE_UP_ERROR, "kneel_band": events.KNEEL_BAND_UP_ERROR}


class ChainError(ValueError):
    """A chain folder or manifest that cannot be run, with what is wrong in it."""


@dataclass(frozen=True)
class KeyframeChain:
    folder: Path
    members: tuple[Path, Path, Path]   # in events.KEYFRAME_STAGES order
    handover: str                      # a key of HANDOVERS

    @property
    def handover_up_error(self) -> float:
        return HANDOVERS[self.handover]


def is_chain(path) -> bool:
    """Whether `path` is a folder with a chain manifest."""
    return Path(path).is_dir() and (Path(path) / MANIFEST).is_file()


def artifact_files(policy) -> list[Path]:
    """The artifact files a --policy runs: a chain folder's members (read: checked), else `policy` itself."""
    return list(read(policy).members) if is_chain(policy) else [Path(policy)]


def read(folder) -> KeyframeChain:
    """The chain in `folder`; raises ChainError naming the folder and what is missing or malformed."""
    folder = Path(folder)
    path = folder / MANIFEST
    if not path.is_file():
        raise ChainError(f"{folder}: not a keyframe chain (no {MANIFEST})")
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ChainError(f"{path}: not readable JSON ({e})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        got = data.get("format") if isinstance(data, dict) else data
        raise ChainError(f"{path}: format must be {FORMAT!r}, got {got!r}")
    stages = data.get("stages")
    if not isinstance(stages, dict) or set(stages) != set(events.KEYFRAME_STAGES):
        raise ChainError(f"{path}: stages must name exactly {', '.join(events.KEYFRAME_STAGES)}")
    members = []
    for stage in events.KEYFRAME_STAGES:
        name = stages[stage]
        if not isinstance(name, str) or not name or Path(name).name != name:
            raise ChainError(f"{path}: stages.{stage} must be a file name in the chain's folder, got {name!r}")
        if not (folder / name).is_file():
            raise ChainError(f"{path}: stages.{stage}: {folder / name} does not exist")
        members.append(folder / name)
    handover = data.get("handover")
    if handover not in HANDOVERS:
        raise ChainError(f"{path}: handover must be one of {', '.join(HANDOVERS)}, got {handover!r}")
    return KeyframeChain(folder, tuple(members), handover)


def write(folder, members: dict[str, str], handover: str) -> Path:
    """Write `folder`/chain.json naming `members` (stage → file name in `folder`) and the hand-over; checked by
    reading it back."""
    if handover not in HANDOVERS:
        raise ChainError(f"handover must be one of {', '.join(HANDOVERS)}, got {handover!r}")
    path = Path(folder) / MANIFEST
    path.write_text(json.dumps({"format": FORMAT, "stages": {s: members[s] for s in events.KEYFRAME_STAGES},
                                "handover": handover}, indent=1) + "\n")
    read(folder)
    return path
