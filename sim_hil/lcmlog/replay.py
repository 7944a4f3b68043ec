"""Re-run the C++ runtime on a log's states, in lockstep, and compare its commands with the logged ones.

Only the runtime's inputs are replayed (T1_IMU, T1_JOINT_STATE, T1_JOYSTICK, T1_RUNTIME_CMD, T1_SIM_STATUS),
in the logged order, byte for byte but for the signed ones. The replay is the robot: every state frame is
signed with the replay's own robot key (the runtime gets --robot-key), so a log's state, signed by its run's
robot, unsigned, or recorded before state was signed (eventlog.py reads it as unsigned), replays alike, and
the same fields reach the runtime. A signed T1_JOYSTICK or T1_RUNTIME_CMD
is signed again with the replay's own fresh key (its logged tag was made with a key of the logged run and its
timestamp is old: the runtime would take neither); an unsigned one goes as logged, refused again as it was
(one signed with a key the logged runtime did not hold cannot be told apart: it is taken in the replay);
after each joint state the replay waits for the command answering
it (state_seq), exactly as the lockstep simulator does. With the logged policy and a lockstep log this
reproduces the logged T1_JOINT_CMD stream bit for bit (same inputs, same binary); with another policy the
report says where and by how much the new commands differ — what to look at before loading new weights
on a robot. A realtime log is replayed the same way, but its commands were computed on the runtime's own
clock from whichever state was newest, so small differences there are timing, not the policy.
"""
from __future__ import annotations

import math
import shlex
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import lcm
import numpy as np
from t1 import joint_command_t, joystick_t, runtime_cmd_t

from messages import contract
from messages.auth import STATE_CHANNELS, UNSIGNED_SENDER, RunKey
from sim_hil.launch import runtime_reason, start_runtime, stop, wait_until_listening
from sim_hil.lcmlog.eventlog import ProjectLog

RUNTIME_INPUTS = (contract.CH_IMU, contract.CH_JOINT_STATE, contract.CH_JOYSTICK, contract.CH_RUNTIME_CMD,
                  contract.CH_SIM_STATUS)
SIGNED_INPUTS = {contract.CH_JOYSTICK: joystick_t, contract.CH_RUNTIME_CMD: runtime_cmd_t}   # re-signed
COMMAND_FIELDS = ("q_des", "dq_des", "kp", "kd", "tau_ff")
REPLAY_PORT_OFFSET = 151        # replay LCM port: contract port + this (apart from the eval workers' ports)
ANSWER_TIMEOUT_S = 2.0          # a state the runtime does not answer within this is counted, replay goes on
DEFAULT_RUNTIME_ARGS = ("--autostart",)   # for logs without a run_info_t runtime line (e.g. `make sim`)


def replay_lcm_url(base: str | None = None) -> str:
    return contract.lcm_url_on_port(REPLAY_PORT_OFFSET, base)


@dataclass
class Comparison:
    log: str
    policy: str
    logged_policy: str
    log_clock: str
    states_replayed: int = 0
    unanswered_states: int = 0           # states the replayed runtime did not answer in time
    compared_ticks: int = 0              # states with a command in both streams
    only_in_log: int = 0
    only_in_replay: int = 0
    identical: bool = False              # the same stream: every state answered in both, every command equal
                                         # in every field, bit for bit
    first_diverging_state_seq: int | None = None
    first_diverging_time_s: float | None = None   # the state's utime (sim time in lockstep) [s]
    first_diverging_field: str = ""
    max_abs_dq_des_rad: dict[str, float] = field(default_factory=dict)   # per joint, max |Δq_des| [rad]
    mode_mismatches: int = 0

    def text(self) -> str:
        lines = [f"replay of {self.log} ({self.log_clock} log) with {self.policy} "
                 f"(logged policy: {self.logged_policy or 'unknown'})",
                 f"states replayed {self.states_replayed}, unanswered {self.unanswered_states}; commands "
                 f"compared {self.compared_ticks}, only in log {self.only_in_log}, only in replay "
                 f"{self.only_in_replay}, mode mismatches {self.mode_mismatches}"]
        if self.identical:
            lines.append("IDENTICAL: every compared T1_JOINT_CMD equals the logged one in every field")
        elif self.first_diverging_state_seq is not None:
            lines.append(f"first divergence: state_seq {self.first_diverging_state_seq} "
                         f"(t = {self.first_diverging_time_s:.3f} s), field {self.first_diverging_field}")
        else:
            lines.append("DIFFERENT: the compared commands are equal, but the streams are not the same "
                         "(see unanswered / only in log / only in replay above)")
        lines.append("per joint max |Δq_des| [rad]:")
        lines += [f"  {name:<20} {value:.6f}" for name, value in self.max_abs_dq_des_rad.items()]
        return "\n".join(lines)


def runtime_invocation(log: ProjectLog, policy: Path | None) -> tuple[Path, list[str]]:
    """The policy and runtime arguments of the replay: the logged ones unless a policy is given."""
    info = log.first(contract.CH_RUN_INFO)
    logged = Path(info.policy_path) if info is not None and info.policy_path else None
    chosen = policy or logged
    if chosen is None:
        raise ValueError(f"{log.path}: the log does not name its policy (no run_info_t with a policy): "
                         "give one with POLICY=…")
    args = shlex.split(info.runtime_args) if info is not None and info.runtime_args else list(DEFAULT_RUNTIME_ARGS)
    cleaned, skip = [], False
    for a in args:                       # the replay always runs lockstep
        if skip:
            skip = False
        elif a == "--clock":
            skip = True
        else:
            cleaned.append(a)
    return chosen, ["--clock", "lockstep", *cleaned]


def replay(log: ProjectLog, policy: Path | None = None, url: str | None = None) -> tuple[Comparison, dict]:
    """Run the runtime on the log's inputs. Returns the comparison and the replayed commands by state_seq."""
    chosen, args = runtime_invocation(log, policy)
    url = url or replay_lcm_url()
    info = log.first(contract.CH_RUN_INFO)
    states = log.messages.get(contract.CH_JOINT_STATE, [])
    if not states:
        raise ValueError(f"{log.path}: no T1_JOINT_STATE in the log: nothing to replay")
    inputs = sorted((pair for ch in RUNTIME_INPUTS for pair in log.messages.get(ch, [])), key=lambda p: p[0].offset)
    answers: dict[int, joint_command_t] = {}
    lc = lcm.LCM(url)
    lc.subscribe(contract.CH_JOINT_CMD, lambda _c, d: _keep(answers, joint_command_t.decode(d)))
    run_key = RunKey()                       # the replay's keys: its robot signs the state
    runtime = start_runtime(chosen, *args, "--lcm-url", url, run_key=run_key)
    signer = None if "--unauthenticated" in args else runtime.run_key.signer()   # as the logged runtime took commands
    robot = run_key.robot_signer()
    unanswered = 0
    try:
        wait_until_listening(runtime)
        for ev, msg in inputs:
            lc.publish(ev.channel, robot.sign(ev.channel, msg) if ev.channel in STATE_CHANNELS
                       else _resigned(ev.channel, ev.data, signer))
            if ev.channel != contract.CH_JOINT_STATE:
                continue
            seq = msg.seq
            deadline = time.monotonic() + ANSWER_TIMEOUT_S
            while seq not in answers and time.monotonic() < deadline and runtime.poll() is None:
                lc.handle_timeout(50)
            unanswered += seq not in answers
            if runtime.poll() is not None:
                raise RuntimeError(f"t1-runtime exited {runtime.returncode} during the replay: "
                                   f"{runtime_reason(runtime.communicate()[1])}")
    finally:
        stop(runtime)
    comparison = compare(log, answers, str(chosen), info.policy_path if info else "",
                         info.clock if info else "unknown")
    comparison.states_replayed, comparison.unanswered_states = len(states), unanswered
    comparison.identical = comparison.identical and unanswered == 0
    return comparison, answers


def _resigned(channel: str, data: bytes, signer) -> bytes:
    kind = SIGNED_INPUTS.get(channel)
    msg = kind.decode(data) if kind and signer else None
    return signer.sign(channel, msg) if msg is not None and msg.sender_id != UNSIGNED_SENDER else data


def _keep(answers: dict, cmd: joint_command_t) -> None:
    answers.setdefault(cmd.state_seq, cmd)      # the first answer to a state is the one the sim used


def compare(log: ProjectLog, replayed: dict[int, joint_command_t], policy: str, logged_policy: str,
            log_clock: str) -> Comparison:
    logged: dict[int, joint_command_t] = {}
    for _ev, cmd in log.messages.get(contract.CH_JOINT_CMD, []):
        logged.setdefault(cmd.state_seq, cmd)
    state_time = {m.seq: m.utime * 1e-6 for _ev, m in log.messages.get(contract.CH_JOINT_STATE, [])}
    c = Comparison(str(log.path), policy, logged_policy, log_clock)
    common = sorted(set(logged) & set(replayed))
    c.compared_ticks, c.only_in_log = len(common), len(set(logged) - set(replayed))
    c.only_in_replay = len(set(replayed) - set(logged))
    max_dq = np.zeros(contract.NUM_JOINTS)
    for seq in common:
        a, b = logged[seq], replayed[seq]
        c.mode_mismatches += a.mode != b.mode
        max_dq = np.maximum(max_dq, np.abs(np.asarray(a.q_des) - np.asarray(b.q_des)))
        if c.first_diverging_state_seq is None:
            differing = [f for f in COMMAND_FIELDS if list(getattr(a, f)) != list(getattr(b, f))]
            differing += ["mode"] if a.mode != b.mode else []
            if differing:
                c.first_diverging_state_seq = seq
                c.first_diverging_time_s = state_time.get(seq, math.nan)
                c.first_diverging_field = ", ".join(differing)
    # a command missing from either stream is a difference too, not only a differing one
    c.identical = (bool(common) and c.first_diverging_state_seq is None
                   and c.only_in_log == 0 and c.only_in_replay == 0)
    c.max_abs_dq_des_rad = {name: float(v) for name, v in zip(contract.JOINT_NAMES, max_dq)}
    return c


def write_report(c: Comparison, out_stem: Path) -> tuple[Path, Path]:
    import json
    out_stem.parent.mkdir(parents=True, exist_ok=True)
    js, txt = out_stem.with_suffix(".replay.json"), out_stem.with_suffix(".replay.txt")
    js.write_text(json.dumps(asdict(c), indent=1))
    txt.write_text(c.text() + "\n")
    return js, txt
