"""Out of process: the built `t1-runtime` as a child process, a fake robot (tests/runtime_peer.py)
talking to it over real LCM inside tools/netns, the way the outside fault client found each defect.
Lockstep where the defect needs the mode ladder; realtime in PASSIVE (which echoes the live q as q_des
every tick and checks nothing but finiteness) where the defect is in what reaches the live state."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from t1 import joystick_t

from common.artifact import _serialize_container, _tensors_from, content_hash, read_artifact
from messages import contract
from sim_hil import firmware as fw
from sim_hil.launch import ROOT, start_runtime
from tests.runtime_peer import LATCHED_FAULT_MASK, MODE, RuntimePeer

STUDENT = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
FAST_PREPARE = ("--prepare-s", "0.02")   # 10-tick ramp: keeps the ladder short
N = contract.NUM_JOINTS
ELBOW_YAW, HIP_PITCH, KNEE = 5, 11, 14
PRESSED_PAST_RAD = 0.4                   # a joint pressed past its stop, inside rule R10's 0.5 rad margin
RAMP_STEP_RAD = 0.02                     # per tick: 10 rad/s
MAX_STEP_RAD = 0.05                      # SafetyConfig::max_target_step_rad
RANGE_FRACTION = 0.95                    # SafetyConfig::joint_range_fraction


@pytest.fixture
def runtime(netns):
    peers: list[RuntimePeer] = []

    def start(*args: str, policy=STUDENT, lockstep: bool = True) -> RuntimePeer:
        peers.append(RuntimePeer(policy, *args, lockstep=lockstep))
        return peers[-1]

    yield start
    for peer in peers:
        peer.close()


def in_policy(runtime) -> RuntimePeer:
    peer = runtime("--autostart", *FAST_PREPARE)
    peer.until_mode("POLICY")
    return peer


# ---------------------------------------------------------------------------------------- item 1
def test_estop_and_passive_stand_under_autostart_until_the_operator_says_otherwise(runtime):
    peer = in_policy(runtime)
    peer.command("estop")
    assert {c.mode for c in peer.steps(300)} == {MODE["DAMPING"]}, "estop undone by autostart"
    peer.command("set_mode", "passive")
    assert {c.mode for c in peer.steps(300)} == {MODE["PASSIVE"]}, "set_mode passive undone by autostart"
    peer.command("reset")                      # the operator's word: autostart may walk the ladder again
    peer.until_mode("POLICY", max_ticks=200)


# ---------------------------------------------------------------------------------------- item 2
def test_estop_is_never_dropped_behind_a_full_command_queue(runtime):
    peer = in_policy(runtime)
    for _ in range(12):                        # the queue holds 8: four of these are dropped
        peer.command("set_mode", "policy")
    peer.command("estop")
    assert peer.step().mode == MODE["DAMPING"]
    status = peer.last_status()
    assert status.commands_dropped == 4, status.commands_dropped
    assert status.mode_name == "DAMPING"


# ---------------------------------------------------------------------------------------- item 3
def _realtime_passive(runtime) -> RuntimePeer:
    """A realtime runtime in PASSIVE whose live state is the pose at seq peer.seq (IMU likewise)."""
    peer = runtime(lockstep=False)
    for _ in range(300):
        peer.seq += 1                          # a new seq per try: no duplicates reach the runtime
        peer.publish(contract.CH_IMU, peer.imu_msg().encode())
        peer.publish(contract.CH_JOINT_STATE, peer.state_msg().encode())
        if peer.pump(lambda: any(c.state_seq == peer.seq for c in peer.cmds), 0.1):
            return peer
    raise AssertionError(f"realtime runtime never echoed a state: {peer.stderr()}")


def _next_commands(peer: RuntimePeer, n: int):
    start = len(peer.cmds)
    assert peer.pump(lambda: len(peer.cmds) >= start + n), peer.stderr()
    return peer.cmds[start:]


def test_malformed_state_datagrams_never_reach_the_live_state(runtime):
    peer = _realtime_passive(runtime)
    pose32 = np.float32(peer.q)
    live = peer.seq
    bad = peer.state_msg(seq=live + 1)
    bad.q = [float(v) + 0.37 for v in peer.q]
    bad.q[3] = float("nan")
    data = bad.encode()
    peer.publish(contract.CH_JOINT_STATE, data[: 8 + 8 + 8 + 4 * N + 40])   # cut inside dq: q decoded
    peer.publish(contract.CH_JOINT_STATE, data + b"\x00\x01")               # trailing bytes: not this type
    imu = peer.imu_msg(seq=live + 1, quat=(float("nan"), 0.0, 0.0, 1.0)).encode()
    peer.publish(contract.CH_IMU, imu[: 8 + 8 + 8 + 16 + 4])                # quat decoded, gyro cut
    for cmd in _next_commands(peer, 30):
        assert cmd.mode == MODE["PASSIVE"], "a partly decoded datagram latched FAULT"
        assert cmd.state_seq == live
        np.testing.assert_array_equal(np.float32(cmd.q_des), pose32)
    status = peer.last_status()
    assert status.decode_errors == 3 and status.fault_bits & LATCHED_FAULT_MASK == 0, \
        (status.decode_errors, status.last_fault)


def test_malformed_joystick_datagram_does_not_change_the_command(runtime):
    peer = in_policy(runtime)
    peer.joystick(0.3, 0.0, 0.0)
    peer.steps(2 * 10)
    msg = joystick_t()
    msg.utime, msg.seq, msg.vx = peer.seq * 2000, peer.seq, 0.9
    js = msg.encode()[: 8 + 8 + 8 + 4]                                        # vx decoded, vy cut
    peer.publish(contract.CH_JOYSTICK, js)
    peer.steps(2 * 10)
    offset = _command_offset(peer)
    assert peer.obs[-1].raw[offset] == pytest.approx(0.3)
    assert peer.last_status().decode_errors == 1


# ---------------------------------------------------------------------------------------- item 5
def test_older_frames_are_rejected_and_reordering_is_not_counted_as_gaps(runtime):
    peer = _realtime_passive(runtime)
    base = peer.seq
    seqs = [s for s in range(base + 1, base + 102) if s != base + 50]   # base + 50 is really lost
    for i in range(0, len(seqs) - 1, 2):                       # every pair arrives swapped
        seqs[i], seqs[i + 1] = seqs[i + 1], seqs[i]
    start = len(peer.cmds)
    for i, s in enumerate(seqs):
        peer.q[0] = 0.001 * s
        peer.publish(contract.CH_JOINT_STATE, peer.state_msg(seq=s).encode())
        if i % 2:                              # one pair per runtime tick: a burst would overflow UDP buffers
            _next_commands(peer, 1)
    newest = max(seqs)
    assert peer.pump(lambda: peer.cmds[-1].state_seq == newest), peer.stderr()
    echoed = [c.state_seq for c in peer.cmds[start:]]
    assert echoed == sorted(echoed), "an older frame replaced a newer one"
    assert np.float32(peer.cmds[-1].q_des[0]) == np.float32(0.001 * newest)
    late = sum(1 for i, s in enumerate(seqs) if s < max([base, *seqs[:i]]))
    status = peer.last_status()
    assert (status.seq_gaps_joint, status.seq_reordered_joint) == (1, late)


# ---------------------------------------------------------------------------------------- item 6
def _command_offset(peer: RuntimePeer) -> int:
    offset = 0
    for name, size in peer.manifest["obs_terms"]:
        if name == "command":
            return offset
        offset += size
    raise AssertionError("policy has no command term")


def test_joystick_is_clamped_to_the_artifact_command_ranges(runtime):
    peer = in_policy(runtime)
    peer.joystick(1e9, -1e9, 0.5)
    peer.steps(2 * 10)
    ranges = peer.manifest["command_ranges"]
    offset = _command_offset(peer)
    got = peer.obs[-1].raw[offset: offset + 3]
    assert got == pytest.approx([ranges["vx"][1], ranges["vy"][0], 0.5])


# ---------------------------------------------------------------------------------------- item 4
@pytest.mark.parametrize("bit", [0x08, 0x10], ids=["POWER_ON", "DAMPING"])
def test_motor_that_is_not_following_faults_in_policy(runtime, bit):
    peer = in_policy(runtime)
    peer.motor_status[ELBOW_YAW] = bit
    assert peer.step().mode == MODE["FAULT"]
    status = peer.last_status()
    assert "Left_Elbow_Yaw" in status.last_fault and f"0x{bit:x}" in status.last_fault, status.last_fault


# ---------------------------------------------------------------------------------------- item 8
def test_final_target_keeps_the_rate_limit_and_the_torque_limit_with_q_pressed_past_the_range(runtime):
    peer = in_policy(runtime)
    kp, kd = peer.manifest["kp"][HIP_PITCH], peer.manifest["kd"][HIP_PITCH]
    limit = fw.TORQUE_LIMIT[HIP_PITCH]
    mid, half = (fw.Q_MAX + fw.Q_MIN) / 2, (fw.Q_MAX - fw.Q_MIN) / 2 * RANGE_FRACTION
    pressed = fw.Q_MAX[HIP_PITCH] + PRESSED_PAST_RAD
    while peer.q[HIP_PITCH] < pressed:       # there at a speed a joint has (a faster step is rule R10's)
        peer.q[HIP_PITCH] = min(pressed, peer.q[HIP_PITCH] + RAMP_STEP_RAD)
        peer.step()
    prev = peer.cmds[-1].q_des[HIP_PITCH]
    prev_excess, reached = np.inf, False
    for k in range(120):
        # The encoder moves a count each tick: a still one under this torque is a frozen encoder (rule R9).
        peer.q[HIP_PITCH] = pressed + (k % 2) * 1e-4
        q_des = peer.step().q_des[HIP_PITCH]
        assert abs(q_des - prev) <= MAX_STEP_RAD + 1e-5, "a target step beyond the rate limit"
        tau = kp * (q_des - peer.q[HIP_PITCH]) - kd * peer.dq[HIP_PITCH]
        excess = abs(tau) - limit
        assert excess <= max(prev_excess, 0.0) + 1e-3, "expected torque grew"
        assert not reached or excess <= 1e-3, "expected torque left the motor limit"
        assert tau <= 1e-3, "target pulls the joint further out of its range"
        reached = reached or excess <= 1e-3
        prev, prev_excess = q_des, excess
    assert reached, f"expected torque never came down to {limit} N·m"
    assert prev <= peer.q[HIP_PITCH] and prev > mid[HIP_PITCH] + half[HIP_PITCH]  # between range and q
    assert peer.last_status().mode_name == "POLICY"


# ---------------------------------------------------------------------------------------- impossible readings (R10)
def test_every_joint_reading_3_rad_is_an_impossible_reading_that_faults_and_damps(runtime):
    """The outside client's case: every joint at 3.0 rad, beyond every joint's range by more than R10's margin."""
    peer = in_policy(runtime)
    peer.q[:] = 3.0
    cmd = peer.step()
    assert cmd.mode == MODE["FAULT"] and max(cmd.kp) == 0.0, (cmd.mode, max(cmd.kp))
    status = peer.last_status()
    assert status.fault_bits & LATCHED_FAULT_MASK
    assert "motor 0 (AAHead_yaw) impossible reading: q 3.000 rad" in status.last_fault, status.last_fault


def test_a_step_no_motor_makes_in_one_bus_cycle_faults_naming_the_motor(runtime):
    peer = in_policy(runtime)
    peer.q[KNEE] += 0.3                                  # 150 rad/s for 2 ms: beyond 3 x the knee class's 23.4
    assert peer.step().mode == MODE["FAULT"]
    assert "motor 14 (Left_Knee_Pitch) impossible reading" in peer.last_status().last_fault


# ---------------------------------------------------------------------------------------- item 9
def test_status_says_fault_and_counts_after_a_fault(runtime):
    peer = in_policy(runtime)
    peer.q[3] = float("nan")
    assert peer.step().mode == MODE["FAULT"]
    peer.q[3] = 0.0
    status = peer.last_status()
    assert status.mode_name == "FAULT"
    assert status.info.startswith("FAULT:") and "mode POLICY" not in status.info, status.info
    assert (status.decode_errors, status.commands_dropped, status.seq_reordered_joint, status.sends_dropped) == (0,) * 4


# ---------------------------------------------------------------------------------------- item 7
def write_unchecked(path, **changes):
    """The student with manifest fields replaced, written without the Python-side validation."""
    layers, mean, std, manifest = read_artifact(STUDENT)
    tensors = _tensors_from(layers, mean, std)
    fields = {**manifest, **changes, "content_hash": content_hash(tensors)}
    metadata = {k: json.dumps(v, separators=(",", ":")) for k, v in sorted(fields.items())}
    path.write_bytes(_serialize_container(tensors, metadata))
    return path


NONSENSE = {"action_scale_1e6": ({"action_scale": 1e6}, "action_scale"),
            "action_scale_negative": ({"action_scale": -0.5}, "action_scale"),
            "default_pose_10_rad": ({"default_pose": [10.0] * N}, "default_pose")}


@pytest.mark.parametrize("case", NONSENSE)
def test_nonsense_manifest_refused_at_start_up(netns, tmp_path, case):
    changes, field = NONSENSE[case]
    bad = start_runtime(write_unchecked(tmp_path / f"{case}.safetensors", **changes), "--duration", "1")
    _, err = bad.communicate(timeout=60)
    assert bad.returncode == 3 and field in err, (bad.returncode, err)


def test_nonsense_manifest_refused_at_hot_reload_in_policy(runtime, tmp_path):
    shutil.copy(STUDENT, tmp_path / STUDENT.name)              # the policy folder holds the bad files too
    peer = runtime("--autostart", *FAST_PREPARE, policy=tmp_path / STUDENT.name)
    peer.until_mode("POLICY")
    hash_before = peer.last_status().policy_hash
    for case, (changes, field) in NONSENSE.items():
        peer.run_key.approve(write_unchecked(tmp_path / f"{case}.safetensors", **changes))   # approved, still refused
        peer.command("load_policy", f"{case}.safetensors")
        for _ in range(40):
            status = peer.last_status()
            if "REJECTED" in status.info and case in status.info:
                break
        assert "REJECTED" in status.info and field in status.info, status.info
        assert status.policy_hash == hash_before and status.mode_name == "POLICY"
