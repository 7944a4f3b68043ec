"""A silent motor or a frozen encoder is a FAULT (supervisor rules R8, R9 of
runtime/src/safety_supervisor.cpp), out of process: `python -m sim_hil` with its `dead` / `frozen` faults and
`t1-runtime`, lockstep. Detection: the shipped student walking at 0.4 m/s on the LCM and the DDS robot link,
a frozen encoder during a getup and as a push lands (the trips within 1 s measured over a larger matrix by
tools/motor_watchdog_figures.py --matrix). No false alarm under the bus's own faults: walking 20 s, 5 % CAN
frame drop (both links), 10 ms CAN delay (standing, getups, pushes and the rest for every shipped policy:
tests/test_supervisor_false_alarms.py). The rule logic itself is in the gtest runtime/tests/test_motor_watchdog.cpp."""
from __future__ import annotations

import pytest
from t1 import joystick_t

from messages import contract
from sim_hil.eval import plans
from sim_hil.launch import ROOT, start_runtime, start_sim, stop
from tests.runtime_peer import LATCHED_FAULT_MASK
from tests.test_dds import LcmWatch

STUDENT = ROOT / "policies" / "student" / "student.safetensors"
STATUS_RATE_HZ = 50             # T1_SIM_STATUS: the joystick below follows its sim time
FAULT_AT_S = 3.0                # dead / frozen from here: the gait is established by then
SILENT_DEADLINE_S = 0.2         # R8 trips 22 ms after the last reply; the runtime's status comes at 10 Hz,
                                # and the DDS handshake may put the runtime's clock a few ticks ahead
FROZEN_DEADLINE_S = 1.1         # R9: within 1 s (README's rule table), plus the runtime's 10 Hz status period
LIVENESS_S = 300.0              # bound on waiting for a run (not a timing check)
GETUP_FREEZE_S = 3.0            # 1 s into the rise (POLICY starts after the 2 s PREPARE from a fallen start)


class Run(LcmWatch):
    """One lockstep sim + runtime pair; a gamepad on LCM that stamps each stick with the sim's time."""

    def __init__(self, link: str, seconds: float, faults: str = "", spawn: str = "standing",
                 vx: float = plans.WALK_FORWARD_MPS, policy=STUDENT):
        super().__init__()
        self.vx = vx
        self.lc.subscribe(contract.CH_SIM_STATUS, lambda _c, _d: self._stick())
        prepare = plans.STANDING_PREPARE_S if spawn == "standing" else 2.0
        dds = ["--dds"] if link == "dds" else []
        runtime = start_runtime(policy, "--transport", link, "--clock", "lockstep", "--autostart",
                                "--prepare-s", str(prepare))
        self.signer = runtime.run_key.signer()          # the gamepad is the operator's
        sim = start_sim(*dds, "--clock", "lockstep", "--spawn", spawn, "--faults", faults,
                        "--status-rate", str(STATUS_RATE_HZ), "--duration", str(seconds))
        self.pump_while(lambda: sim.poll() is None, LIVENESS_S)
        assert sim.poll() == 0, f"sim: {sim.communicate()[1][-2000:] if sim.poll() is not None else 'timeout'}"
        code, self.err = stop(runtime)
        assert code == 0, f"runtime exit {code}: {self.err[-2000:]}"
        assert self.status and self.sim, "no status from the runtime or the sim"

    def _stick(self) -> None:
        js = joystick_t()
        js.utime = self.sim[-1].utime if self.sim else 0
        js.vx = self.vx
        self.lc.publish(contract.CH_JOYSTICK, self.signer.sign(contract.CH_JOYSTICK, js))

    def first_fault(self):
        return next((s for s in self.status if s.mode_name == "FAULT"), None)

    def assert_frozen_fault(self, motor: str, frozen_at_s: float) -> None:
        fault = self.first_fault()
        assert fault is not None, f"no FAULT; last status {self.status[-1].mode_name}: {self.status[-1].info}"
        assert f"{motor} encoder frozen" in fault.last_fault, fault.last_fault
        assert frozen_at_s < fault.utime * 1e-6 <= frozen_at_s + FROZEN_DEADLINE_S, fault.utime

    def assert_no_fault(self) -> None:
        bad = [s for s in self.status if s.fault_bits & LATCHED_FAULT_MASK or s.mode_name == "FAULT"]
        assert not bad, f"false alarm at {bad[0].utime * 1e-6:.2f} s: {bad[0].last_fault}"
        assert self.status[-1].mode_name == "POLICY", [s.mode_name for s in self.status][-5:]


# ------------------------------------------------------------------------------------ the faults
@pytest.mark.parametrize("link", ["lcm", "dds"])
def test_a_dead_motor_faults_naming_it(link, netns):
    run = Run(link, FAULT_AT_S + 0.5, faults=f"dead:joint=Left_Ankle_Pitch@{FAULT_AT_S}")
    fault = run.first_fault()
    assert fault is not None, f"no FAULT; last status {run.status[-1].mode_name}: {run.status[-1].info}"
    assert "motor 15 (Left_Ankle_Pitch) silent" in fault.last_fault, fault.last_fault
    assert FAULT_AT_S < fault.utime * 1e-6 <= FAULT_AT_S + SILENT_DEADLINE_S, fault.utime
    assert all(s.mode_name == "POLICY" for s in run.status if 0.5 < s.utime * 1e-6 < FAULT_AT_S - 0.1)


@pytest.mark.parametrize("link", ["lcm", "dds"])
def test_a_frozen_encoder_faults_naming_it(link, netns):
    run = Run(link, FAULT_AT_S + FROZEN_DEADLINE_S + 0.3, faults=f"frozen:joint=Left_Knee_Pitch@{FAULT_AT_S}")
    run.assert_frozen_fault("motor 14 (Left_Knee_Pitch)", FAULT_AT_S)


@pytest.mark.parametrize("what, joint, policy", [
    ("the student", "Left_Knee_Pitch", STUDENT),
    ("the getup expert", "Right_Hip_Roll", ROOT / "policies" / "getup_knockdown" / "getup_knockdown.safetensors"),
], ids=["student", "getup_knockdown"])
def test_a_frozen_encoder_during_a_getup_faults_within_a_second(what, joint, policy, netns):
    freeze_s = GETUP_FREEZE_S
    run = Run("lcm", freeze_s + FROZEN_DEADLINE_S + 0.3, faults=f"frozen:joint={joint}@{freeze_s}",
              spawn="fallen:62", vx=0.0, policy=policy)
    run.assert_frozen_fault(f"({joint})", freeze_s)


def test_a_frozen_encoder_as_a_push_lands_faults_within_a_second(netns):
    push = plans.push_draw(0, 0)
    run = Run("lcm", push.at_s + FROZEN_DEADLINE_S + 0.3, vx=0.0,
              faults=f"{plans.push_fault(push)};frozen:joint=Right_Hip_Pitch@{push.at_s:.3f}")
    run.assert_frozen_fault("motor 17 (Right_Hip_Pitch)", push.at_s)


# ------------------------------------------------------------------------------------ no false alarm
@pytest.mark.parametrize("what, link, seconds, faults, vx", [
    ("walking 20 s at 0.4 m/s", "lcm", 20.0, "", plans.WALK_FORWARD_MPS),
    ("walking, 5 % CAN frame drop", "lcm", 6.0, "drop:rate=0.05@0", plans.WALK_FORWARD_MPS),
    ("walking, 5 % CAN frame drop", "dds", 6.0, "drop:rate=0.05@0", plans.WALK_FORWARD_MPS),
    ("walking, 10 ms CAN delay", "lcm", 6.0, "delay:ticks=5@0", plans.WALK_FORWARD_MPS),
], ids=["walk", "drop-lcm", "drop-dds", "delay"])
def test_no_false_alarm(what, link, seconds, faults, vx, netns):
    Run(link, seconds, faults=faults, vx=vx).assert_no_fault()

