"""atheris harness: messages/auth.py on bytes it did not write.
Input: byte 0 picks the part, the rest is its input:
  0  a key file's contents -> read_key_file (a list of senders, or KeyFileError: the one refusal its callers
     catch and print in one line);
  1  an encoded message of a signed channel -> decoded by its type, its tag checked with auth.tag over
     auth.signed_body under a known key (a forged one never verifies), then signed by Signer and checked
     again (it verifies, and one flipped byte does not);
  2  a recorded state frame -> upgrade_legacy_state (None, or today's unsigned frame).

    python -m tests.fuzz.fuzz_auth [libFuzzer flags] [corpus dirs]   (tools/fuzz.py runs it)
"""
import hmac
import os
import sys
import tempfile

import atheris

with atheris.instrument_imports():
    import t1  # noqa: F401  lcm-gen's Python decoders of every project type (lcm_type imports them from here)
    from t1 import imu_t, joint_state_t, joystick_t, runtime_cmd_t  # noqa: F401

    from messages import auth
    from sim_hil.lcmlog.eventlog import lcm_type

SIGNED = sorted(auth.SIGNED_CHANNELS)
SENDER = auth.new_sender(7)
KEY_DIR = tempfile.mkdtemp(prefix="t1_fuzz_auth_")   # 0700; the key file inside is 0600
KEY_FILE = os.path.join(KEY_DIR, "keys")


def verifies(key: bytes, channel: str, data: bytes) -> bool:
    return len(data) > auth.TAG_SIZE_BYTES + auth.TAG_BYTES and hmac.compare_digest(
        auth.tag(key, channel, auth.signed_body(data)), data[-auth.TAG_BYTES:])


def key_file(text: bytes) -> None:
    fd = os.open(KEY_FILE, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(text)
    try:
        senders = auth.read_key_file(KEY_FILE)
    except auth.KeyFileError as e:
        assert "\n" not in str(e), str(e)
        return
    assert senders and all(s.sender_id > 0 and len(s.key) == auth.KEY_BYTES for s in senders)


def signed_message(channel: str, data: bytes) -> None:
    assert not verifies(SENDER.key, channel, data)   # this process's key: no input can carry its tag
    try:
        msg = lcm_type(channel).decode(data)
    except Exception:  # lcm-gen's decoders: ValueError / struct.error on a short or foreign payload
        return
    signed = auth.Signer(SENDER).sign(channel, msg)
    assert verifies(SENDER.key, channel, signed)
    forged = bytearray(signed)
    forged[len(forged) // 2] ^= 0x01
    assert not verifies(SENDER.key, channel, bytes(forged))


def legacy_state(data: bytes) -> None:
    for name in auth.LEGACY_STATE_FINGERPRINTS:
        fingerprint = 0x1234_5678_9ABC_DEF0
        out = auth.upgrade_legacy_state(name, data, fingerprint)
        assert out is None or (len(out) == len(data) + len(auth.UNSIGNED_TAIL)
                               and out[:8] == fingerprint.to_bytes(8, "big"))


def test_one_input(data: bytes) -> None:
    if not data:
        return
    part, rest = data[0] % 3, data[1:]
    if part == 0:
        key_file(rest)
    elif part == 1 and rest:
        signed_message(SIGNED[rest[0] % len(SIGNED)], rest[1:])
    else:
        legacy_state(rest)


def main() -> None:
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
