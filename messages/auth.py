"""Who may command the runtime and whose state it takes: the signing of runtime_cmd_t and joystick_t (the
operator's key) and of imu_t and joint_state_t (the robot key), key files, artifact approvals.
The one definition of the protocol; C++ verifies it in runtime/include/t1rt/command_auth.hpp, held to this
file by the golden vector tests/golden/command_auth.json (`python -m messages.auth golden tests/golden`).

Signed message (MAVLink 2 signing as the model): sender_id (its line in the key file, > 0; 0 = unsigned),
timestamp_us (the sender's wall clock [us since the epoch], strictly increasing per sender and channel), and
the last two fields tag_size = TAG_BYTES and tag = HMAC-SHA256(key, channel name + NUL + the message's LCM
encoding before tag_size), i.e. every payload byte but the last 2 + TAG_BYTES, the type's fingerprint
included. An unsigned message has tag_size 0 and no tag: what lcm-gen's types encode by default, so any
program's plain runtime_cmd_t is a whole datagram; any other tag_size is refused. The runtime takes a message
only when its tag verifies under the sender's key, its timestamp is after the last one taken from that sender
on that channel, and it lies within the runtime's freshness window (t1rt::AuthConfig) and not before the
runtime started. estop is the exception: obeyed from anyone, signed or not.

State (STATE_CHANNELS): the robot signs each imu_t / joint_state_t it publishes in the same way with the robot
key, a key file of its own (never the operator's: who holds one may neither command as the other nor publish
state). The runtime started with --robot-key FILE takes state only when it verifies under FILE's keys, fresh
and after the last one per channel, as above; every other frame is refused and counted by reason. Without
--robot-key (a bench) state is unsigned and only a second sequence stream is detected (safety rule R12).

Key file: text, one sender a line, "<sender_id> <key: 64 hex digits>", '#' comments; open to its owner only
(mode 0600: the runtime and these tools refuse anything else). The runtime's file lists every sender it
takes (one line per operator laptop); a sender's own file holds its own line (the first line signs).

Approval: a line "<sha256 of the artifact file, hex> <sender_id> <tag, hex> [name]" in the runtime's
approvals file, tag = HMAC-SHA256(key, approval_context + NUL + the file's SHA-256 digest): the key holder's
word that these bytes may run. Only the key holder can write one, so the file itself needs no protection.

  python -m messages.auth new-key FILE [--sender ID]           a fresh key file (mode 0600), one sender
  tools/t1key approve --key FILE --approvals OUT ARTIFACT...  append approvals to OUT (valid artifacts only)
  python -m messages.auth golden DIR                           write the golden vector
(tools/t1key runs this CLI through common/t1key.py, which checks an artifact before approving it.)
"""
from __future__ import annotations

import argparse
import hashlib
import hmac
import json
import os
import secrets
import shutil
import stat
import sys
import tempfile
import threading
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path

from messages import contract

TAG_BYTES = 32                                   # tag_size of a signed message (0: unsigned)
TAG_SIZE_BYTES = 2                               # the int16_t tag_size field, just before the tag
KEY_BYTES = int(contract.AUTH["key_bytes"])
APPROVAL_CONTEXT = contract.AUTH["approval_context"].encode()
STATE_CHANNELS = frozenset(contract.CHANNELS[k] for k in contract.AUTH["state_channels"])     # the robot key's
SIGNED_CHANNELS = frozenset(contract.CHANNELS[k] for k in contract.AUTH["signed_channels"]) | STATE_CHANNELS
UNSIGNED_SENDER = 0
NEW_SENDER_ID_MAX = 2**31 - 1                    # new-key's random ids lie in [1, this]
GOLDEN_FILE = "command_auth.json"
GOLDEN_COMMAND = "python -m messages.auth golden tests/golden"


class KeyFileError(ValueError):
    """A key file that cannot be used: open to others, malformed, or a duplicate sender."""


@dataclass(frozen=True)
class Sender:
    sender_id: int
    key: bytes = field(repr=False)               # never printed


def tag(key: bytes, channel: str, body: bytes) -> bytes:
    """HMAC-SHA256(key, channel + NUL + body): body is the message's encoding before tag_size (signed_body)."""
    return hmac.new(key, channel.encode() + b"\0" + body, hashlib.sha256).digest()


def signed_body(data: bytes) -> bytes:
    """The bytes of a signed encoding that its tag covers: all but tag_size and the tag at its end."""
    return data[:-(TAG_SIZE_BYTES + TAG_BYTES)]


def approval_tag(key: bytes, artifact_sha256: bytes) -> bytes:
    return hmac.new(key, APPROVAL_CONTEXT + b"\0" + artifact_sha256, hashlib.sha256).digest()


def new_sender(sender_id: int | None = None) -> Sender:
    sender_id = secrets.randbelow(NEW_SENDER_ID_MAX) + 1 if sender_id is None else sender_id
    if not 0 < sender_id <= 2**63 - 1:
        raise KeyFileError(f"sender id {sender_id}: must be a positive 64-bit integer (0 means unsigned)")
    return Sender(sender_id, secrets.token_bytes(KEY_BYTES))


def read_key_file(path: str | os.PathLike) -> list[Sender]:
    """The senders of a key file, refusing one that its group or others may open (as the runtime does)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError as e:
        raise KeyFileError(f"key file {path}: {e.strerror}") from None
    with os.fdopen(fd) as f:
        mode = os.fstat(f.fileno()).st_mode
        if not stat.S_ISREG(mode) or mode & 0o077:
            raise KeyFileError(f"key file {path}: mode {stat.filemode(mode)} lets its group or others at the key; "
                               f"chmod 600 {path}")
        try:
            text = f.read()
        except UnicodeDecodeError as e:
            raise KeyFileError(f"key file {path}: byte {e.start} is not UTF-8 text; expected '<sender_id> <key: "
                               f"{2 * KEY_BYTES} hex digits>' lines") from None
    senders: list[Sender] = []
    for number, line in enumerate(text.splitlines(), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        try:
            sender_id, key = int(words[0]), bytes.fromhex(words[1])
            if len(words) != 2 or sender_id <= 0 or len(key) != KEY_BYTES:
                raise ValueError
        except (ValueError, IndexError):
            raise KeyFileError(f"key file {path} line {number}: expected '<sender_id > 0> <key: "
                               f"{2 * KEY_BYTES} hex digits>'") from None
        if any(s.sender_id == sender_id for s in senders):
            raise KeyFileError(f"key file {path} line {number}: sender {sender_id} listed twice")
        senders.append(Sender(sender_id, key))
    if not senders:
        raise KeyFileError(f"key file {path}: no sender line")
    return senders


def write_key_file(path: str | os.PathLike, senders: list[Sender]) -> None:
    """A new key file (mode 0600, created only if absent, so a key is never overwritten)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write("# t1 command key file (messages/auth.py): <sender_id> <key>; keep it mode 0600, never share it\n")
        f.writelines(f"{s.sender_id} {s.key.hex()}\n" for s in senders)


class Signer:
    """Signs what one sender sends. Its timestamps strictly increase per channel, also across a step back of
    the wall clock (they then run on from the last one, 1 us a message, until the clock catches up)."""

    def __init__(self, sender: Sender, clock_ns=time.time_ns):
        self.sender, self._clock_ns = sender, clock_ns
        self._last_us: dict[str, int] = {}
        self._lock = threading.Lock()

    def sign(self, channel: str, msg) -> bytes:
        """Sets msg's sender_id, timestamp_us, tag_size and tag; returns its signed encoding, to publish on channel."""
        if channel not in SIGNED_CHANNELS:
            raise ValueError(f"{channel} is not a signed channel ({sorted(SIGNED_CHANNELS)})")
        with self._lock:
            stamp = max(self._clock_ns() // 1000, self._last_us.get(channel, 0) + 1)
            self._last_us[channel] = stamp
        msg.sender_id, msg.timestamp_us = self.sender.sender_id, stamp
        msg.tag_size, msg.tag = TAG_BYTES, bytes(TAG_BYTES)
        data = msg.encode()
        msg.tag = tag(self.sender.key, channel, signed_body(data))
        return data[:-TAG_BYTES] + msg.tag


LEGACY_STATE_FINGERPRINTS = {name: int(fp, 16) for name, fp in contract.AUTH["legacy_fingerprints"].items()}
UNSIGNED_TAIL = bytes(8 + 8 + TAG_SIZE_BYTES)     # sender_id 0, timestamp_us 0, tag_size 0: no tag


def upgrade_legacy_state(type_name: str, data: bytes, fingerprint: int) -> bytes | None:
    """A state frame recorded before state was signed (its type's legacy fingerprint) as the same frame of
    today's type, unsigned: the old encoding is today's before sender_id, so only the fingerprint and the
    unsigned tail change. None when data is not a frame of that legacy version."""
    legacy = LEGACY_STATE_FINGERPRINTS.get(type_name)
    if legacy is None or len(data) < 8 or int.from_bytes(data[:8], "big") != legacy:
        return None
    return fingerprint.to_bytes(8, "big") + data[8:] + UNSIGNED_TAIL


def file_sha256(path: str | os.PathLike) -> bytes:
    return hashlib.sha256(Path(path).read_bytes()).digest()


def approval_line(sender: Sender, artifact: str | os.PathLike) -> str:
    digest = file_sha256(artifact)
    return f"{digest.hex()} {sender.sender_id} {approval_tag(sender.key, digest).hex()} {Path(artifact).name}\n"


def append_approvals(approvals: str | os.PathLike, sender: Sender, artifacts) -> None:
    lines = [approval_line(sender, a) for a in artifacts]       # every file read before anything is written
    fd = os.open(approvals, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)
    with os.fdopen(fd, "a") as f:
        f.writelines(lines)


class RunKey:
    """A fresh key for one run: a private temporary folder (mode 0700) holding the operator's key file (0600),
    the run's approvals file and the robot key file (0600), removed by close() or at exit. The launcher hands
    them to the runtime (--key, --approvals, --robot-key) and the robot key to the simulator (--robot-key);
    the run's clients sign with signer(). The keys never leave the folder."""

    ROBOT_SENDER_ID = 1                          # the robot key file's one line

    def __init__(self):
        self.dir = Path(tempfile.mkdtemp(prefix="t1-run-key-"))
        self.key_path, self.approvals_path = self.dir / "key", self.dir / "approvals"
        self.robot_key_path = self.dir / "robot_key"
        self.senders = [new_sender(1)]
        write_key_file(self.key_path, self.senders)
        write_key_file(self.robot_key_path, [new_sender(self.ROBOT_SENDER_ID)])
        self.approvals_path.touch(mode=0o600)
        self._finalizer = weakref.finalize(self, shutil.rmtree, self.dir, True)

    def signer(self, index: int = 0) -> Signer:
        return Signer(self.senders[index])

    def robot_signer(self) -> Signer:
        """Signs state as this run's robot does (sim_hil --robot-key)."""
        return Signer(read_key_file(self.robot_key_path)[0])

    def add_sender(self) -> Sender:
        """A second sender with its own key and id, added to the runtime's key file (read at its start)."""
        sender = new_sender(len(self.senders) + 1)
        self.senders.append(sender)
        self.key_path.unlink()
        write_key_file(self.key_path, self.senders)
        return sender

    def approve(self, *artifacts) -> None:
        append_approvals(self.approvals_path, self.senders[0], artifacts)

    def close(self) -> None:
        self._finalizer()


def golden_document() -> dict:
    """Fixed key, sender, timestamps and fields: the signed encodings and an approval tag."""
    from t1 import imu_t, joint_state_t, joystick_t, runtime_cmd_t
    key = bytes(range(KEY_BYTES))
    clock = iter([1_700_000_000_000_000, 1_700_000_000_020_000, 1_700_000_000_040_000, 1_700_000_000_042_000])
    signer = Signer(Sender(7, key), clock_ns=lambda: next(clock) * 1000)
    cmd = runtime_cmd_t()
    cmd.utime, cmd.seq, cmd.verb, cmd.argument = 123456, 5, "load_policy", "student/student.safetensors"
    stick = joystick_t()
    stick.utime, stick.seq, stick.vx, stick.vy, stick.yaw_rate = 654321, 9, 0.5, -0.25, 0.125
    imu = imu_t()
    imu.utime, imu.seq, imu.quat, imu.gyro, imu.accel = 777000, 11, [1.0, 0.0, 0.0, 0.0], [0.5, 0, 0], [0, 0, 9.81]
    joints = joint_state_t()
    joints.utime, joints.seq = 777000, 11
    joints.q = [0.01 * i for i in range(contract.NUM_JOINTS)]
    joints.motor_status = [i % 3 for i in range(contract.NUM_JOINTS)]
    messages = []
    for channel, msg in ((contract.CH_RUNTIME_CMD, cmd), (contract.CH_JOYSTICK, stick), (contract.CH_IMU, imu),
                         (contract.CH_JOINT_STATE, joints)):
        data = signer.sign(channel, msg)
        messages.append({"channel": channel, "sender_id": msg.sender_id, "timestamp_us": msg.timestamp_us,
                         "tag_size": msg.tag_size, "encoded_hex": data.hex(), "tag_hex": msg.tag.hex()})
    digest = hashlib.sha256(b"T1 golden artifact bytes\n").digest()
    return {"_comment": f"Signed runtime_cmd_t / joystick_t / imu_t / joint_state_t and an approval under a fixed "
                        f"key (messages/auth.py); "
                        f"regenerate with `{GOLDEN_COMMAND}`",
            "key_hex": key.hex(), "messages": messages,
            "approval": {"artifact_sha256_hex": digest.hex(), "sender_id": 7,
                         "tag_hex": approval_tag(key, digest).hex()}}


def main(argv: list[str] | None = None, artifact_problem=None) -> int:
    """The key tools' CLI. `artifact_problem(path)` → None or one line: approve refuses a file that is not a policy
    artifact (tools/t1key passes common.artifact's, a layer above this one); without it approve is refused."""
    p = argparse.ArgumentParser(prog="python -m messages.auth", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="what", required=True)
    new = sub.add_parser("new-key", help="write a fresh key file (mode 0600) for one sender")
    new.add_argument("file")
    new.add_argument("--sender", type=int, default=None, help="sender id > 0 (default: random)")
    ok = sub.add_parser("approve", help="append approvals of artifacts, signed with the key file's first sender")
    ok.add_argument("--key", required=True)
    ok.add_argument("--approvals", required=True, help="the runtime's approvals file (t1-runtime --approvals)")
    ok.add_argument("artifacts", nargs="+")
    gold = sub.add_parser("golden", help="write the golden vector of the protocol")
    gold.add_argument("directory")
    args = p.parse_args(argv)
    try:
        if args.what == "new-key":
            sender = new_sender(args.sender)
            write_key_file(args.file, [sender])
            print(f"{args.file}: sender {sender.sender_id} (add this line to the runtime's key file)")
        elif args.what == "approve":
            problems = ["approve: run tools/t1key, which checks each artifact first"] if artifact_problem is None \
                else [f"approve: {problem}" for problem in map(artifact_problem, args.artifacts) if problem]
            if problems:
                print(f"messages.auth: {problems[0]}", file=sys.stderr)
                return 2
            append_approvals(args.approvals, read_key_file(args.key)[0], args.artifacts)
            print(f"{args.approvals}: approved {len(args.artifacts)} artifact(s)")
        else:
            path = Path(args.directory) / GOLDEN_FILE
            path.write_text(json.dumps(golden_document(), indent=1) + "\n")
            print(path)
    except (KeyFileError, OSError) as e:
        print(f"messages.auth: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
