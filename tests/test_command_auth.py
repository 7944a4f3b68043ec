"""messages/auth.py, the signing protocol's one definition: the committed golden vector (which the C++ runtime
is held to in runtime/tests/test_command_auth.cpp) is what this code writes; key files open to others are
refused; timestamps only increase; a default-constructed message is a whole unsigned one; the per-run key stays
private and goes with the run."""
from __future__ import annotations

import json
import os
import stat
import subprocess
from pathlib import Path

import pytest
from t1 import joystick_t, runtime_cmd_t

from messages import auth, contract

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "golden" / auth.GOLDEN_FILE


def test_golden_vector_regenerates_identically():
    assert json.loads(GOLDEN.read_text()) == auth.golden_document(), f"stale golden: run `{auth.GOLDEN_COMMAND}`"


def test_the_tag_covers_every_byte_before_tag_size_and_the_channel():
    sender = auth.new_sender(3)
    data = auth.Signer(sender).sign(contract.CH_RUNTIME_CMD, _cmd("set_mode", "policy"))
    body, tag = auth.signed_body(data), data[-auth.TAG_BYTES:]
    assert data == body + auth.TAG_BYTES.to_bytes(auth.TAG_SIZE_BYTES, "big") + tag
    assert tag == auth.tag(sender.key, contract.CH_RUNTIME_CMD, body)
    assert tag != auth.tag(sender.key, contract.CH_JOYSTICK, body), "the channel is not bound"
    decoded = runtime_cmd_t.decode(data)
    assert (decoded.sender_id, decoded.argument, decoded.tag_size, decoded.tag) == (3, "policy", auth.TAG_BYTES, tag)
    same_fields_untagged = _cmd("set_mode", "policy")
    same_fields_untagged.sender_id, same_fields_untagged.timestamp_us = 3, decoded.timestamp_us
    assert body == same_fields_untagged.encode()[:-auth.TAG_SIZE_BYTES], "the tag covers the fields before tag_size"


def test_timestamps_strictly_increase_per_channel_even_when_the_clock_steps_back():
    clock = iter([5_000_000_000, 5_000_000_000, 4_000_000_000, 9_000_000_000])
    signer = auth.Signer(auth.new_sender(1), clock_ns=lambda: next(clock))
    stamps = [runtime_cmd_t.decode(signer.sign(contract.CH_RUNTIME_CMD, _cmd("reset"))).timestamp_us for _ in range(3)]
    assert stamps == [5_000_000, 5_000_001, 5_000_002]
    assert joystick_t.decode(signer.sign(contract.CH_JOYSTICK, joystick_t())).timestamp_us == 9_000_000
    with pytest.raises(ValueError, match="not a signed channel"):
        signer.sign(contract.CH_JOINT_CMD, joystick_t())


def test_a_default_constructed_message_is_a_whole_unsigned_one():
    for msg in (_cmd("estop"), joystick_t()):
        data = msg.encode()                                  # as any program with lcm-gen's types sends it
        decoded = type(msg).decode(data)
        assert (decoded.sender_id, decoded.tag_size, decoded.tag) == (auth.UNSIGNED_SENDER, 0, b"")
        channel = contract.CH_RUNTIME_CMD if isinstance(msg, runtime_cmd_t) else contract.CH_JOYSTICK
        signed = auth.Signer(auth.new_sender(1)).sign(channel, msg)
        assert len(signed) == len(data) + auth.TAG_BYTES


def test_key_files_open_to_others_or_malformed_are_refused(tmp_path):
    path = tmp_path / "k"
    auth.write_key_file(path, [auth.new_sender(4), auth.new_sender(9)])
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert [s.sender_id for s in auth.read_key_file(path)] == [4, 9]
    with pytest.raises(FileExistsError):
        auth.write_key_file(path, [auth.new_sender(1)])              # never overwrites a key
    for mode in (0o640, 0o604):
        path.chmod(mode)
        with pytest.raises(auth.KeyFileError, match="chmod 600"):
            auth.read_key_file(path)
    for text, why in (("4 abcd\n", "line 1"), ("0 " + "00" * 32 + "\n", "line 1"), ("", "no sender"),
                      ("4 " + "00" * 32 + "\n4 " + "11" * 32 + "\n", "listed twice")):
        bad = tmp_path / f"bad{len(why)}{len(text)}"
        bad.write_text(text)
        bad.chmod(0o600)
        with pytest.raises(auth.KeyFileError, match=why):
            auth.read_key_file(bad)
    path.chmod(0o600)
    sender = auth.read_key_file(path)[0]
    assert sender.key.hex() not in repr(sender) and repr(sender) == "Sender(sender_id=4)"


def test_key_file_that_is_not_text_is_refused_in_one_line(tmp_path):
    """Found by tests/fuzz/fuzz_auth.py: a non-UTF-8 byte raised UnicodeDecodeError (a traceback in sim_hil and
    the teleop, which print KeyFileError in one line)."""
    bad = tmp_path / "k"
    bad.write_bytes(b"0 " + b"ab" * 15 + b"a\x95" + b"ab" * 16 + b"\n12 zz\n")
    bad.chmod(0o600)
    with pytest.raises(auth.KeyFileError, match="byte 33 is not UTF-8 text") as refused:
        auth.read_key_file(bad)
    assert "\n" not in str(refused.value)


def test_a_run_key_is_private_and_removed_with_the_run():
    run = auth.RunKey()
    assert stat.S_IMODE(run.dir.stat().st_mode) == 0o700 and stat.S_IMODE(run.key_path.stat().st_mode) == 0o600
    second = run.add_sender()
    assert [s.sender_id for s in auth.read_key_file(run.key_path)] == [1, second.sender_id]
    run.close()
    assert not run.dir.exists()


def test_the_cli_makes_a_key_and_approves_with_it(tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "build" / "gen" / "python")]))
    key, approvals = tmp_path / "laptop.key", tmp_path / "approvals"
    artifact = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
    made = subprocess.run([str(ROOT / "tools" / "t1key"), "new-key", str(key), "--sender", "12"],
                          capture_output=True, text=True, env=env)
    assert made.returncode == 0 and "sender 12" in made.stdout, made.stderr
    assert auth.read_key_file(key)[0].key.hex() not in made.stdout + made.stderr, "the key was printed"
    subprocess.run([str(ROOT / "tools" / "t1key"), "approve", "--key", str(key), "--approvals", str(approvals),
                    str(artifact)], check=True, capture_output=True, env=env)
    sender = auth.read_key_file(key)[0]
    digest = auth.file_sha256(artifact)
    assert approvals.read_text().split()[:3] == [digest.hex(), "12", auth.approval_tag(sender.key, digest).hex()]


def _cmd(verb: str, argument: str = "") -> runtime_cmd_t:
    c = runtime_cmd_t()
    c.verb, c.argument = verb, argument
    return c
