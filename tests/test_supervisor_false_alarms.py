"""A healthy robot is never faulted by its own supervisor. Every shipped policy, in lockstep
against the simulated T1 (LCM), in each situation where a healthy encoder repeats its count under load or
a joint is pressed past its stop: standing still 60 s, standing still 60 s after a getup from a fallen
seed, lying while something holds its getup down, a kneeling start, leaning on a wall it is pushed
against, a joint held at its stop while it is shoved, the push test's shoves; and a test stand that
replays one standing pose. Zero faults of any rule: the runtime's exit line says "last fault: none" (a
FAULT latches until a reset, and nobody resets). The runs go two at a time, each pair on its own LCM port."""
from __future__ import annotations

import queue
from concurrent.futures import ThreadPoolExecutor

import pytest

from common.artifact import read_artifact
from messages.auth import RunKey
from sim_hil.eval import plans
from sim_hil.eval.trial import trial_lcm_url
from sim_hil.launch import ROOT, start_runtime, start_sim, stop, wait_until_listening
from tests.runtime_peer import MODE, RuntimePeer

SHIPPED = sorted(p for p in ROOT.glob("policies/*/*.safetensors") if read_artifact(p)[3]["trained"])
WORKERS = 2                   # lockstep pairs at once (one core each)
PORT_BASE = 40                # trial_lcm_url worker slots of this module, clear of the evaluations'
GETUP_SEEDS = (62, 5, 7, 3, 1, 9, 11, 13)   # one per policy, in SHIPPED order
STAND_S = 60.0
SHORT_S = 10.0
LIVENESS_S = 600.0            # bound on one run (not a timing check)
TEST_STAND_TICKS = 5000       # 10 s of one standing pose at 500 Hz


def _push(index: int, at_s: float) -> str:
    return plans.push_fault(plans.push_draw(index, index), at_s)


def situations(seed: int) -> dict[str, tuple[list[str], float, float]]:
    """name -> (sim arguments, seconds, PREPARE ramp [s]); zero joystick command throughout."""
    stand, fallen = ["--spawn", "standing"], ["--spawn", f"fallen:{seed}"]
    return {
        "standing 60 s": (stand, STAND_S, plans.STANDING_PREPARE_S),
        "standing 60 s after a getup": (fallen, plans.GETUP_SECONDS + STAND_S, 2.0),
        "lying, its getup held down": (fallen + ["--faults", "load:z=-400@0-8"], SHORT_S, 2.0),
        "kneeling start": (["--spawn", "kneeling"], SHORT_S, 2.0),
        "leaning on a wall": (stand + ["--scenario", "tall_wall", "--faults", "load:x=60@1"], SHORT_S,
                              plans.STANDING_PREPARE_S),
        "a joint held at its stop, shoved": (stand + ["--faults",
                                                      f"press:joint=Left_Elbow_Yaw,tau=25@1;{_push(0, 4.0)}"],
                                             SHORT_S, plans.STANDING_PREPARE_S),
        "shoved forward and backward": (stand + ["--faults", f"{_push(0, 2.0)};{_push(2, 5.0)}"], SHORT_S,
                                        plans.STANDING_PREPARE_S),
    }


def _run(slots: queue.Queue, policy: str, sim_args: list[str], seconds: float, prepare_s: float) -> str:
    """One lockstep run on a free LCM port; the runtime's last fault ("none" when it never faulted)."""
    slot = slots.get()
    try:
        return _run_on(trial_lcm_url(PORT_BASE + slot), policy, sim_args, seconds, prepare_s)
    finally:
        slots.put(slot)


def _run_on(url: str, policy: str, sim_args: list[str], seconds: float, prepare_s: float) -> str:
    run_key = RunKey()                  # as the launcher runs a robot: its state signed, the runtime takes only it
    runtime = start_runtime(ROOT / policy, "--clock", "lockstep", "--autostart", "--prepare-s", f"{prepare_s:g}",
                            "--lcm-url", url, run_key=run_key)
    wait_until_listening(runtime)
    sim = start_sim(*sim_args, "--clock", "lockstep", "--duration", str(seconds), "--lcm-url", url, run_key=run_key)
    try:
        _, sim_err = sim.communicate(timeout=LIVENESS_S)
    finally:
        if sim.poll() is None:
            sim.kill()
        code, err = stop(runtime)
    assert sim.returncode == 0, f"sim: {sim_err[-2000:]}"
    assert code == 0, f"runtime exit {code}: {err[-2000:]}"
    return err.strip().splitlines()[-1].partition("last fault: ")[2]


CASES = [(str(p.relative_to(ROOT)), name, *situation)
         for p, seed in zip(SHIPPED, GETUP_SEEDS) for name, situation in situations(seed).items()]


@pytest.fixture(scope="module")
def last_faults(netns) -> dict[tuple[str, str], str]:
    slots: queue.Queue = queue.Queue()
    for slot in range(WORKERS):
        slots.put(slot)
    with ThreadPoolExecutor(WORKERS) as pool:
        futures = {(policy, name): pool.submit(_run, slots, policy, args, seconds, prepare)
                   for policy, name, args, seconds, prepare in CASES}
        return {key: future.result() for key, future in futures.items()}


def test_every_shipped_policy_is_in_the_matrix():
    names = {p.parent.name for p in SHIPPED}
    assert {"student", "getup_knockdown", "getup_baseline", "joystick", "joystick_handover"} <= names, names
    assert len(SHIPPED) <= len(GETUP_SEEDS), "give the new policy a fallen seed"


@pytest.mark.slow
@pytest.mark.parametrize("policy, situation", [(c[0], c[1]) for c in CASES],
                         ids=[f"{c[0].split('/')[1]}-{c[1].replace(' ', '_')}" for c in CASES])
def test_no_fault_of_any_rule(last_faults, policy, situation):
    assert last_faults[(policy, situation)] == "none", f"{policy}, {situation}: {last_faults[(policy, situation)]}"


@pytest.mark.parametrize("policy", [str(p.relative_to(ROOT)) for p in SHIPPED], ids=[p.parent.name for p in SHIPPED])
def test_a_test_stand_replaying_one_standing_pose_is_never_faulted(netns, policy):
    """An outside client publishes the policy's standing pose, still IMU, for 10 s at 500 Hz (lockstep), the
    policy in POLICY commanding whatever it likes: every reading repeats under load, and the body is still."""
    peer = RuntimePeer(ROOT / policy, "--autostart", "--prepare-s", "0.02")
    try:
        peer.until_mode("POLICY")
        modes = {cmd.mode for cmd in peer.steps(TEST_STAND_TICKS)}
        assert modes == {MODE["POLICY"]}, peer.last_status().last_fault
    finally:
        peer.close()
