"""Only the operator commands the robot: the built `t1-runtime` in POLICY (the student, --autostart, lockstep
against the fake robot of tests/runtime_peer.py, inside tools/netns), its operator signing with the run's key,
and a second program on the LCM group that is not the operator, trying what an outside program would: unsigned
commands, another key, an altered argument, captured bytes sent again, an old timestamp, artifacts outside the
policy folder or not approved, a joystick stream, a tag_size of neither kind and bytes no decoder should be
given; estop from it (a plain default-constructed message) is obeyed, its reset is not. Also a second operator
with its own key and id, and the two modes without a key (estop only, --unauthenticated)."""
from __future__ import annotations

import shutil
import time

import lcm
import pytest
from t1 import runtime_cmd_t

from messages import contract
from messages.auth import TAG_BYTES, TAG_SIZE_BYTES, RunKey, Sender, Signer, new_sender
from sim_hil.launch import ROOT
from tests.runtime_peer import MODE, RuntimePeer

STUDENT = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
OTHER_POLICY = ROOT / "policies" / "joystick" / "joystick.safetensors"     # valid, another name and hash
OUTSIDE_POLICY = ROOT / "policies" / "joystick_handover" / "joystick_handover.safetensors"
FAST_PREPARE = ("--prepare-s", "0.02")
TICKS = 200                       # lockstep ticks a refused command is given to (not) take effect
STALE_S = 10.0                    # older than the runtime's freshness window (t1rt::AuthConfig, 2 s)


@pytest.fixture
def runtime(netns, tmp_path):
    """start(*args, policy=…) -> a RuntimePeer in POLICY whose policy folder is tmp_path (the student copied in)."""
    peers: list[RuntimePeer] = []

    def start(*args: str, sign: bool = True, policy_mode: str = "POLICY") -> RuntimePeer:
        policy = tmp_path / STUDENT.name
        shutil.copy(STUDENT, policy)
        peers.append(RuntimePeer(policy, "--autostart", *FAST_PREPARE, *args, sign=sign))
        peers[-1].until_mode(policy_mode)
        return peers[-1]

    yield start
    for peer in peers:
        peer.close()


class Outsider:
    """Another program on the LCM group: publishes whatever bytes it has; unsigned, a message as lcm-gen's
    Python type encodes it with only its verb and argument set."""

    def __init__(self):
        self.lc = lcm.LCM(contract.lcm_url())

    def command(self, verb: str, argument: str = "", signer: Signer | None = None) -> bytes:
        c = runtime_cmd_t()
        c.verb, c.argument = verb, argument
        data = signer.sign(contract.CH_RUNTIME_CMD, c) if signer else c.encode()
        self.send(data)
        return data

    def send(self, data: bytes, channel: str = contract.CH_RUNTIME_CMD) -> None:
        self.lc.publish(channel, data)


def modes(peer: RuntimePeer, ticks: int = TICKS) -> set[int]:
    return {c.mode for c in peer.steps(ticks)}


def refused(peer: RuntimePeer, field: str, at_least: int = 1):
    """The newest status once its refused_<field> counter reaches at_least (a liveness bound, no sleep)."""
    for _ in range(40):
        status = peer.last_status()
        if getattr(status, f"refused_{field}") >= at_least:
            return status
    raise AssertionError(f"refused_{field} stayed below {at_least}: {status.info}")


def test_unsigned_wrong_key_and_altered_commands_change_nothing(runtime):
    peer, outsider = runtime(), Outsider()
    hash_before = peer.last_status().policy_hash
    outsider.command("set_mode", "passive")                              # unsigned
    status = refused(peer, "unsigned")
    assert "set_mode passive" in status.info and "unsigned" in status.info, status.info
    forged = Signer(Sender(peer.signer.sender.sender_id, new_sender().key))   # the operator's id, another key
    outsider.command("set_mode", "passive", signer=forged)
    assert "tag does not verify" in refused(peer, "bad_tag").info
    captured = runtime_cmd_t.decode(peer.signed(contract.CH_RUNTIME_CMD, peer.command_msg("set_mode", "policy")))
    captured.argument = "passive"                                        # altered on the way, tag kept
    outsider.send(captured.encode())
    refused(peer, "bad_tag", 2)
    outsider.command("set_mode", "damping", signer=Signer(new_sender()))     # a sender the runtime does not know
    assert "sender not in the key file" in refused(peer, "unknown_sender").info
    assert modes(peer) == {MODE["POLICY"]}
    status = peer.last_status()
    assert status.policy_hash == hash_before and status.command_auth == "signed (1 senders)", status.command_auth


def test_replayed_bytes_and_an_old_timestamp_are_refused(runtime):
    peer, outsider = runtime(), Outsider()
    passive = peer.signed(contract.CH_RUNTIME_CMD, peer.command_msg("set_mode", "passive"))
    peer.publish(contract.CH_RUNTIME_CMD, passive)                       # the operator's: obeyed
    peer.until_mode("PASSIVE", max_ticks=50)
    peer.command("reset")                                                # the operator's: autostart climbs again
    peer.until_mode("POLICY")
    outsider.send(passive)                                               # captured bytes, sent again
    status = refused(peer, "replayed")
    assert "replayed" in status.info, status.info
    old = Signer(peer.signer.sender, clock_ns=lambda: time.time_ns() - int(STALE_S * 1e9))
    outsider.command("set_mode", "passive", signer=old)                  # the operator's key, an old timestamp
    assert "stale timestamp" in refused(peer, "stale").info
    assert modes(peer) == {MODE["POLICY"]}


def test_a_plain_default_estop_is_obeyed_and_the_same_reset_or_set_mode_is_not(runtime):
    peer, script = runtime(), lcm.LCM(contract.lcm_url())
    estop = runtime_cmd_t()                                              # lcm-gen's defaults but the verb
    estop.verb = "estop"
    script.publish(contract.CH_RUNTIME_CMD, estop.encode())
    peer.until_mode("DAMPING", max_ticks=5)
    for verb, argument in (("reset", ""), ("set_mode", ""), ("set_mode", "prepare"), ("set_mode", "policy")):
        plain = runtime_cmd_t()
        plain.verb, plain.argument = verb, argument
        script.publish(contract.CH_RUNTIME_CMD, plain.encode())
    status = refused(peer, "unsigned", 4)
    assert "unsigned" in status.info and status.decode_errors == 0, (status.info, status.decode_errors)
    assert modes(peer) == {MODE["DAMPING"]}, "an unsigned command released the estop's hold"
    peer.command("reset")                                                # the operator's word
    peer.until_mode("POLICY")


def test_an_outsiders_joystick_is_not_taken_the_operators_is(runtime):
    peer, outsider = runtime(), Outsider()
    for _ in range(5):
        outsider.send(peer.joystick_msg(0.9, 0.0, 0.0).encode(), contract.CH_JOYSTICK)
        peer.steps(10)
    status = refused(peer, "unsigned", 5)
    assert status.joystick_age_ms == -1.0 and "joystick_t" in status.info, (status.joystick_age_ms, status.info)
    offset = [name for name, _ in peer.manifest["obs_terms"]].index("command")
    assert peer.obs[-1].raw[sum(size for _, size in peer.manifest["obs_terms"][:offset])] == 0.0
    peer.joystick(0.3, 0.0, 0.0)
    peer.steps(20)
    assert peer.last_status().joystick_age_ms >= 0.0


def test_a_tag_size_of_neither_kind_is_refused_and_bytes_no_decoder_should_see_change_nothing(runtime):
    peer, outsider = runtime(), Outsider()
    odd = runtime_cmd_t()
    odd.verb, odd.tag_size, odd.tag = "estop", 5, bytes(5)               # neither unsigned (0) nor signed (32)
    outsider.send(odd.encode())
    stick = peer.joystick_msg(0.9, 0.0, 0.0)
    stick.tag_size, stick.tag = TAG_BYTES + 1, bytes(TAG_BYTES + 1)
    outsider.send(stick.encode(), contract.CH_JOYSTICK)
    status = refused(peer, "tag_size", 2)
    assert "tag_size 33, neither 0 (unsigned) nor 32 (signed)" in status.info, status.info
    # What lcm-gen's C++ decoder must never be given (it sizes a string or the tag from the field unchecked):
    # a string length of 0 (no NUL), a negative tag_size, a huge one. Counted; the runtime runs on.
    plain = runtime_cmd_t()
    plain.verb = "estop"
    data = plain.encode()
    verb_length_at = 3 * 8                                               # fingerprint, utime, seq: int64 each
    outsider.send(data[:verb_length_at] + bytes(4) + data[verb_length_at + 4:])
    outsider.send(data[:-TAG_SIZE_BYTES] + b"\xff\xff")                 # tag_size -1
    outsider.send(data[:-TAG_SIZE_BYTES] + b"\x7f\xff" + bytes(0x7fff))  # tag_size 32767, with its bytes
    status = refused(peer, "tag_size", 4)                                # in order: the decode error is counted
    assert status.decode_errors == 1 and status.joystick_age_ms == -1.0, (status.decode_errors, status.info)
    assert modes(peer) == {MODE["POLICY"]} and peer.proc.poll() is None


def test_load_policy_takes_approved_names_inside_the_policy_folder_only(runtime, tmp_path):
    peer = runtime()
    hash_before = peer.last_status().policy_hash
    shutil.copy(OTHER_POLICY, tmp_path / "unapproved.safetensors")
    (tmp_path / "escape.safetensors").symlink_to(OUTSIDE_POLICY)         # approved content, outside the folder
    peer.run_key.approve(OUTSIDE_POLICY)
    for name, why in ((str(OUTSIDE_POLICY), "an absolute path"), ("../" + OUTSIDE_POLICY.name, "'..' leaves"),
                      ("escape.safetensors", "outside the policy folder"),
                      ("unapproved.safetensors", "is not approved")):
        peer.command("load_policy", name)
        for _ in range(40):
            status = peer.last_status()
            if why in status.info:
                break
        assert "REJECTED" in status.info and why in status.info, (name, status.info)
        assert status.policy_hash == hash_before and status.mode_name == "POLICY"
    peer.run_key.approve(tmp_path / "unapproved.safetensors")            # now the key holder approves it
    peer.command("load_policy", "unapproved.safetensors")
    for _ in range(40):
        status = peer.last_status()
        if "reload ok" in status.info:
            break
    assert "reload ok" in status.info and status.policy_name == "joystick", (status.policy_name, status.info)


def test_a_second_operator_signs_with_its_own_key_and_id(netns, tmp_path):
    key = RunKey()
    second = key.add_sender()
    shutil.copy(STUDENT, tmp_path / STUDENT.name)
    key.approve(tmp_path / STUDENT.name)
    peer = RuntimePeer(tmp_path / STUDENT.name, "--autostart", *FAST_PREPARE, "--key", str(key.key_path),
                       "--approvals", str(key.approvals_path))
    try:
        peer.signer = Signer(key.senders[0], clock_ns=lambda: time.time_ns() + 1_000_000_000)   # its clock 1 s ahead
        peer.until_mode("POLICY")
        peer.command("set_mode", "damping")
        peer.until_mode("DAMPING", max_ticks=50)
        Outsider().command("reset", signer=Signer(second))               # earlier timestamps, its own: taken
        peer.until_mode("POLICY")
        impostor = Signer(Sender(second.sender_id, key.senders[0].key))  # the second's id, the first's key
        Outsider().command("set_mode", "passive", signer=impostor)
        refused(peer, "bad_tag")
        assert modes(peer) == {MODE["POLICY"]}
        assert peer.last_status().command_auth == "signed (2 senders)"
    finally:
        peer.close()
        key.close()


def test_without_a_key_only_estop_is_taken(runtime):
    peer = runtime(sign=False)
    status = peer.last_status()
    assert status.command_auth == "estop only (no --key)", status.command_auth
    peer.command("set_mode", "passive")
    peer.joystick(0.5, 0.0, 0.0)
    assert refused(peer, "no_key", 2).joystick_age_ms == -1.0
    assert modes(peer) == {MODE["POLICY"]}
    peer.command("estop")
    peer.until_mode("DAMPING", max_ticks=5)


def test_unauthenticated_says_so_and_takes_unsigned_commands(netns):
    peer = RuntimePeer(STUDENT, "--unauthenticated", "--autostart", *FAST_PREPARE)
    try:
        peer.until_mode("POLICY")
        status = peer.last_status()
        assert status.command_auth == "unauthenticated" and "commands unauthenticated" in status.info, status.info
        Outsider().command("set_mode", "passive")
        peer.until_mode("PASSIVE", max_ticks=50)
    finally:
        code, err = peer.close()
    assert code == 0 and err.splitlines()[0].startswith("t1-runtime: commands unauthenticated"), err[:300]
