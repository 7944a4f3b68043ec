"""Write the fuzz harnesses' seed corpora from the project's own encoders (committed; rerun after a contract
change): LCM messages and datagrams as the sim and the operator tools send them, rt/low_state samples as
sim_hil's DDS robot serialises them, CAN frames packed by firmware_like, small policy artifacts from the
exporter's writer, LCM event logs and key files.

    python tools/fuzz_seeds.py          (PYTHONPATH=.:build/gen/python, after make build)
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
from t1 import imu_t, joint_state_t, joystick_t, runtime_cmd_t, sim_status_t

from common import observation as obsdef
from common.artifact import encode_artifact
from common.golden import base_manifest, random_policy
from messages import contract, dds_types
from messages.auth import SIGNED_CHANNELS, Signer, new_sender
from sim_hil import firmware
from sim_hil.lcmlog.eventlog import HEADER, SYNC, Event

ROOT = Path(__file__).resolve().parents[1]
RUNTIME = ROOT / "runtime" / "fuzz" / "corpus"
FIRMWARE = ROOT / "firmware_like" / "fuzz" / "corpus"
PYTHON = ROOT / "tests" / "fuzz" / "corpus"
SIGN, UNAUTHENTICATED, LOCKSTEP, RAW_DATAGRAM = 1, 2, 4, 8   # runtime/fuzz/fuzz_lcm_channel.cpp's flags
N = contract.NUM_JOINTS


def _write(folder: Path, name: str, data: bytes) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)


def _datagram(channel: str, payload: bytes) -> bytes:
    return b"LC02" + struct.pack(">I", 1) + channel.encode() + b"\0" + payload


def lcm_messages(rng) -> dict[str, list]:
    imu = imu_t()
    imu.utime, imu.seq, imu.quat = 2_000, 1, [1.0, 0.0, 0.0, 0.0]
    imu.gyro, imu.accel = [0.01, -0.02, 0.0], [0.0, 0.0, 9.81]
    joint = joint_state_t()
    joint.utime, joint.seq = 2_000, 1
    joint.q = [float(v) for v in rng.normal(0, 0.3, N)]
    joint.dq = [float(v) for v in rng.normal(0, 1.0, N)]
    joint.tau_est = [float(v) for v in rng.normal(0, 5.0, N)]
    joint.motor_status = [0] * N
    stick = joystick_t()
    stick.utime, stick.seq, stick.vx, stick.vy, stick.yaw_rate = 2_000, 3, 0.5, 0.0, 0.2
    commands = []
    for verb, argument in (("set_mode", "policy"), ("set_mode", "damping"), ("estop", ""), ("reset", ""),
                           ("load_policy", "policies/joystick/joystick.safetensors")):
        c = runtime_cmd_t()
        c.utime, c.verb, c.argument = 2_000, verb, argument
        commands.append(c)
    status = sim_status_t()
    status.utime, status.step, status.real_time_factor = 2_000, 4, 1.0
    status.scenario, status.clock, status.active_faults = "flat", "lockstep", "imu_dropout:0.1"
    status.trunk_height, status.waist_height, status.base_pos = 0.68, 0.55, [0.0, 0.0, 0.68]
    return {"imu": [imu], "joint_state": [joint], "joystick": [stick], "runtime_cmd": commands,
            "sim_status": [status]}


def lcm_seeds(rng) -> None:
    signer = Signer(new_sender(1))     # a throwaway key: the harness signs with its own
    for name, messages in lcm_messages(rng).items():
        channel = contract.CHANNELS[name]
        folder = RUNTIME / f"fuzz_lcm_{name}"
        for i, msg in enumerate(messages):
            plain = msg.encode()
            _write(folder, f"unsigned_{i}", bytes([0]) + plain)
            _write(folder, f"bench_{i}", bytes([UNAUTHENTICATED | LOCKSTEP]) + plain)
            _write(folder, f"datagram_{i}", bytes([RAW_DATAGRAM]) + _datagram(channel, plain))
            if hasattr(msg, "tag_size"):
                _write(folder, f"signed_{i}", bytes([SIGN]) + signer.sign(channel, msg))


def dds_seeds(rng) -> None:
    q, dq, tau = rng.normal(0, 0.3, N), rng.normal(0, 1.0, N), rng.normal(0, 5.0, N)
    for i, lost in enumerate((0, 3)):
        imu = dds_types.ImuState(rpy=[0.01, -0.02, 0.3], gyro=[0.0, 0.1, 0.0], acc=[0.0, 0.0, 9.81])
        motors = [dds_types.MotorState(mode=0, q=float(q[k]), dq=float(dq[k]), ddq=0.0, tau_est=float(tau[k]),
                                       temperature=40, lost=lost, reserve=[0, 0]) for k in range(N)]
        sample = dds_types.LowState(imu_state=imu, motor_state_parallel=[], motor_state_serial=motors)
        _write(RUNTIME / "fuzz_dds_low_state", f"low_state_{i}", sample.serialize())


def can_seeds(rng) -> None:
    q_des, dq_des = rng.normal(0, 0.3, N), rng.normal(0, 1.0, N)
    kp, kd, tau_ff = np.full(N, 50.0), np.full(N, 2.0), rng.normal(0, 1.0, N)
    frames = firmware.pack_commands(q_des, dq_des, kp, kd, tau_ff)
    for start in (0, 12):
        seed = b"".join(struct.pack("<HB", firmware.cmd_can_id(i), 8) + frames[8 * i:8 * i + 8]
                        for i in range(start, min(start + 12, N)))
        _write(FIRMWARE / "fuzz_can_command", f"commands_{start}", seed + struct.pack("<ff", 0.1, -0.5))
    motors = firmware.MotorArray()
    motors.receive_all(frames, now_us=1_000)
    q, dq = rng.normal(0, 0.3, N), rng.normal(0, 1.0, N)
    tau = motors.step(q, dq, now_us=1_000)
    replies = motors.replies(q, dq, tau)
    for name, send, drop, delay in (("all", 0x7FFFFF, 0, 0), ("lossy", 0x7FFFFF, 0x10204, 2)):
        _write(FIRMWARE / "fuzz_can_reply", f"replies_{name}", replies + struct.pack("<IIBB", send, drop, delay, 7))


def artifact_seeds(rng) -> None:
    terms = obsdef.TERMS_UNION
    for name, rule, activation, hidden in (("tanh_normal_swish", "tanh_normal", "swish", (8, 8)),
                                           ("linear_elu", "linear", "elu", (6,))):
        layers, mean, std = random_policy(rng, terms, hidden=hidden)
        if rule == "linear":
            w, b = layers[-1]
            layers[-1] = (w[:N], b[:N])
        manifest = base_manifest(name=name, output_rule=rule, activation=activation)
        _write(RUNTIME / "fuzz_artifact", name, encode_artifact(layers, mean, std, manifest))


def log_and_key_seeds(rng) -> None:
    events = []
    for channel_key, msgs in lcm_messages(rng).items():
        for msg in msgs:
            events.append(Event(0, 1_700_000_000_000_000 + len(events), contract.CHANNELS[channel_key], msg.encode()))
    events.append(Event(0, 1_700_000_000_000_100, "NOT_A_PROJECT_CHANNEL", b"\x00" * 12))
    blob = b"".join(HEADER.pack(SYNC, i, ev.timestamp_us, len(ev.channel.encode()), len(ev.data))
                    + ev.channel.encode() + ev.data for i, ev in enumerate(events))
    _write(PYTHON / "fuzz_lcmlog", "project_log", blob)
    _write(PYTHON / "fuzz_lcmlog", "truncated_log", blob[: len(blob) * 2 // 3])
    key = "ab" * int(contract.AUTH["key_bytes"])    # a made-up key: these are key-file texts, never a real key
    _write(PYTHON / "fuzz_auth", "key_file", b"\0" + f"# operator laptop\n12345 {key}\n7 {key[::-1]}\n".encode())
    _write(PYTHON / "fuzz_auth", "bad_key_file", b"\0" + f"0 {key}\n12 zz\n".encode())
    signer, signed = Signer(new_sender(1)), sorted(SIGNED_CHANNELS)
    for name, msgs in lcm_messages(rng).items():
        channel = contract.CHANNELS[name]
        if channel in signed:
            _write(PYTHON / "fuzz_auth", f"signed_{name}", b"\1" + bytes([signed.index(channel)])
                   + signer.sign(channel, msgs[0]))
    legacy = int(next(iter(contract.AUTH["legacy_fingerprints"].values())), 16)
    _write(PYTHON / "fuzz_auth", "legacy_state", b"\2" + legacy.to_bytes(8, "big") + bytes(40))


def main() -> None:
    rng = np.random.default_rng(20251207)
    lcm_seeds(rng)
    dds_seeds(rng)
    can_seeds(rng)
    artifact_seeds(rng)
    log_and_key_seeds(rng)
    for root in (RUNTIME, FIRMWARE, PYTHON):
        for folder in sorted(p for p in root.iterdir() if p.is_dir()):
            files = list(folder.iterdir())
            print(f"{folder.relative_to(ROOT)}: {len(files)} seeds, {sum(f.stat().st_size for f in files)} bytes")


if __name__ == "__main__":
    main()
