"""The robot's DDS types for Python (cyclonedds), built at import time from messages/dds/booster_low.idl:
the one definition the C side's idlc also compiles, so the two cannot drift apart.

cyclonedds-python's own generator (`idlc -l py`) crashes here (../shared/DEPENDENCIES.md), so this module
reads the small IDL subset the file keeps to (modules, enums, structs, fixed arrays, unbounded sequences,
octet / float / unsigned long) and builds the classes with cyclonedds' make_idl_struct / make_idl_enum.
Anything outside that subset is refused with the line named, never guessed.
"""
from __future__ import annotations

import re
from pathlib import Path

from cyclonedds.idl import make_idl_enum, make_idl_struct, types

IDL_PATH = Path(__file__).with_name("dds") / "booster_low.idl"

_PRIMITIVES = {"octet": types.byte, "float": types.float32, "double": types.float64,
               "unsigned long": types.uint32, "long": types.int32, "boolean": bool}
_TOKEN = re.compile(r"\s*(module|struct|enum)\s+(\w+)\s*\{|\s*\}\s*;|\s*([^;{}]+);")
_MEMBER = re.compile(r"^(sequence<\s*(\w+)\s*>|unsigned long|\w+)\s+(\w+)(?:\[(\d+)\])?$")


class IdlSubsetError(ValueError):
    pass


def _strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def load(path: Path = IDL_PATH) -> dict[str, type]:
    """Every struct and enum of the file, keyed by its plain name (LowState_, LowCmd_, ...)."""
    text = _strip_comments(path.read_text())
    scopes: list[str] = []            # module path
    open_kinds: list[str] = []        # what each '{' opened: module | struct | enum
    current: tuple[str, str] | None = None   # (kind, name) of the struct/enum being read
    members: list[str] = []
    out: dict[str, type] = {}
    pos = 0
    while pos < len(text):
        if not text[pos:].strip():
            break
        m = _TOKEN.match(text, pos)
        if not m:
            line = text.count("\n", 0, pos) + 1
            raise IdlSubsetError(f"{path.name}:{line}: outside the IDL subset dds_types.py reads: "
                                 f"{text[pos:pos + 60].strip()!r}")
        pos = m.end()
        if m.group(1):                                  # module / struct / enum opens
            open_kinds.append(m.group(1))
            if m.group(1) == "module":
                scopes.append(m.group(2))
            else:
                current, members = (m.group(1), m.group(2)), []
                if m.group(1) == "enum":             # enum E { A, B };  the labels have no ';'
                    close = text.index("}", pos)
                    members, pos = [text[pos:close]], close
        elif m.group(0).strip().startswith("}"):        # a scope closes
            kind = open_kinds.pop()
            if kind == "module":
                scopes.pop()
            else:
                out[current[1]] = _build(current, members, scopes, out, path)
                current = None
        else:                                           # a member line (or enum body)
            if current is None:
                raise IdlSubsetError(f"{path.name}: declaration outside a struct: {m.group(3).strip()!r}")
            members.append(m.group(3).strip())
    return out


def _build(current, members, scopes, known, path):
    kind, name = current
    typename = "::".join([*scopes, name])
    if kind == "enum":
        labels = [label.strip() for label in " ".join(members).split(",") if label.strip()]
        return make_idl_enum(name, typename, {label: i for i, label in enumerate(labels)})
    fields = {}
    for text in members:
        mm = _MEMBER.match(" ".join(text.split()))
        if not mm:
            raise IdlSubsetError(f"{path.name}: member {text!r} of {name} is outside the subset")
        type_text, seq_of, field, count = mm.groups()
        if seq_of:
            if seq_of not in known:
                raise IdlSubsetError(f"{path.name}: {name}.{field}: unknown element type {seq_of}")
            t = types.sequence[known[seq_of]]
        elif type_text in _PRIMITIVES:
            t = _PRIMITIVES[type_text]
        elif type_text in known:
            t = known[type_text]
        else:
            raise IdlSubsetError(f"{path.name}: {name}.{field}: unknown type {type_text}")
        fields[field] = types.array[t, int(count)] if count else t
    return make_idl_struct(name, typename, fields)


_TYPES = load()
ImuState = _TYPES["ImuState_"]
MotorState = _TYPES["MotorState_"]
LowState = _TYPES["LowState_"]
CmdType = _TYPES["CmdType_"]
MotorCmd = _TYPES["MotorCmd_"]
LowCmd = _TYPES["LowCmd_"]
