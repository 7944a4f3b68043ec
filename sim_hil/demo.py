"""`make demo`: the deployment path end to end. Inside the project namespace: the simulated T1 (realtime,
spawned fallen) and the C++ runtime running the student from policies/, a short scripted joystick
sequence, a live status line, then a video and a plot of trunk height, waist height and forward velocity.
The student is the first shipped of POLICIES: policies/student/ (distilled from a stitched getup + joystick
teacher), else the untrained placeholder; the demo says which it runs and which teacher a student was
distilled from. No shipped student meets the seed's targets yet (policies/student/CARD.md), so the trained
experts follow one by one: the keyframe getup (policies/getup_keyframe/, a chain: roll, kneel, stand) from an
on-back start, with the kneel marked in its plot (else the student's getup expert from the same fallen start),
then the joystick expert walking the script from a standing start."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import lcm
import numpy as np
from t1 import controller_status_t, imu_t, joint_state_t, joystick_t, sim_status_t

from common import events, keyframe_chain
from common.artifact import artifact_problem, read_artifact, stitched_teacher
from messages import contract
from messages.auth import RunKey
from sim_hil.launch import ROOT, start_runtime, start_sim, stop, stop_cleanly_on_sigterm
from sim_hil.lcmlog.capture import LogCapture, RunInfo
from sim_hil.plots import plot_heights_and_velocity

POLICIES = (ROOT / "policies" / "student" / "student.safetensors",
            ROOT / "policies" / "student_untrained" / "student_untrained.safetensors")
JOYSTICK_EXPERT = ROOT / "policies" / "joystick" / "joystick.safetensors"
BASELINE_GETUP = ROOT / "policies" / "getup_baseline" / "getup_baseline.safetensors"
KEYFRAME_GETUP = ROOT / "policies" / "getup_keyframe"     # a chain's folder (common/keyframe_chain.py)
# fallen:62 lies face down, fallen:58 on its back (common/model.fallen_state)
FALLEN_SPAWN, ON_BACK_SPAWN, STANDING_SPAWN = "fallen:62", "fallen:58", "standing"
STATUS_RATE_HZ = 50.0           # T1_SIM_STATUS for the plot; a chain's runtime reads it every loop tick
# (start time [s], vx [m/s], vy [m/s], yaw rate [rad/s]): stand still while getting up, walk, turn, stop.
JOYSTICK_SCRIPT = ((0.0, 0.0, 0.0, 0.0), (6.0, 0.4, 0.0, 0.0), (12.0, 0.3, 0.0, 0.5), (15.0, 0.0, 0.0, 0.0))
JOYSTICK_RATE_HZ = 50.0
VIEWER_ARGS: list[str] = []      # ["--viewer"] with `make demo VIEWER=1`


def joystick_at(t: float) -> tuple[float, float, float]:
    current = JOYSTICK_SCRIPT[0][1:]
    for start, *cmd in JOYSTICK_SCRIPT:
        if t >= start:
            current = tuple(cmd)
    return current


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--policy", type=Path, default=None, help="artifact (default: the shipped student)")
    ap.add_argument("--seconds", type=float, default=18.0, help="sim seconds (realtime)")
    ap.add_argument("--spawn", default=FALLEN_SPAWN)
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "demo")
    ap.add_argument("--no-log", action="store_true", help="do not write OUT/demo.lcmlog")
    ap.add_argument("--viewer", action="store_true", help="MuJoCo's interactive viewer on each run (needs a display)")
    args = ap.parse_args(argv)
    global VIEWER_ARGS
    VIEWER_ARGS = ["--viewer"] if args.viewer else []
    policy = args.policy or next(p for p in POLICIES if p.exists())
    problem = artifact_problem(policy)
    if problem:
        print(f"demo: --policy {problem}", file=sys.stderr)
        return 2
    trained = _trained(policy)
    code = run(policy, args.spawn, args.seconds, args.out, "demo", log=not args.no_log)
    if code != 0 or args.policy is not None:
        return code
    if trained:
        print("demo: NOTE this student misses the seed's targets: see policies/student/CARD.md. "
              "The experts of its teacher follow, one by one.")
    else:
        print("demo: NOTE the policy is untrained — this run shows the plumbing (sim, bus, runtime, safety), "
              "not a skill. Train and ship policies/student/student.safetensors (training/README.md).")
    getup = _teacher_getup(policy)
    if code == 0 and keyframe_chain.is_chain(KEYFRAME_GETUP) and _trained(KEYFRAME_GETUP):
        print(f"\ndemo: next — the keyframe getup ({KEYFRAME_GETUP.relative_to(ROOT)}/CARD.md) from an on-back start: "
              "it rolls face down, rises to a kneel, stands up and stands still; it does not walk. The plot marks "
              "the kneel")
        code = run(KEYFRAME_GETUP, ON_BACK_SPAWN, args.seconds, args.out, "demo_keyframe", log=not args.no_log)
    elif code == 0 and _trained(getup):
        print(f"\ndemo: next — the trained getup expert {getup.parent.name} "
              f"({getup.parent.relative_to(ROOT)}/CARD.md), same fallen "
              "start. It gets up and stands; it does not walk (it ignores the joystick)")
        code = run(getup, args.spawn, args.seconds, args.out, "demo_getup", log=not args.no_log)
    if code == 0 and _trained(JOYSTICK_EXPERT):
        print("\ndemo: next — the trained joystick expert, standing start. It walks and turns; it cannot "
              "get up, stands on one leg, may stumble after the stop (policies/joystick/CARD.md)")
        code = run(JOYSTICK_EXPERT, STANDING_SPAWN, args.seconds, args.out, "demo_joystick", log=not args.no_log)
    return code


def _teacher_getup(student: Path) -> Path:
    """The getup expert a student was distilled from (its manifest's teacher, a path under policies/), else the
    baseline getup."""
    teacher = stitched_teacher(read_artifact(student)[3])
    shipped = ROOT / teacher["getup"] if teacher else None
    return shipped if shipped is not None and shipped.exists() else BASELINE_GETUP


def describe_student(manifest: dict) -> str | None:
    """What a student is, from its provenance: distilled by DAgger (how many phases) from which stitched
    teacher, and, for a PPO fine-tune of it, for how many env steps. None for a policy without a teacher."""
    teacher = stitched_teacher(manifest)
    if not teacher:
        return None
    prov = manifest["provenance"]
    source = f"the stitched teacher getup={teacher['getup']} + joystick={teacher['joystick']}"
    if "dagger_phases" in prov:
        return f"a student distilled (DAgger, {prov['dagger_phases']} phases) from {source}"
    phases = prov.get("init_dagger_phases")
    dagger = f"DAgger, {phases} phases" if phases else f"DAgger, from {prov.get('init') or 'an unnamed checkpoint'}"
    return (f"a student distilled ({dagger}) from {source}, then fine-tuned on its own outcomes by PPO for "
            f"{prov['steps'] / 1e6:.2f} M env steps")


def _trained(policy: Path) -> bool:
    """An artifact, or every member of a chain's folder, exists and is trained."""
    return policy.exists() and all(bool(read_artifact(p)[3]["trained"]) for p in keyframe_chain.artifact_files(policy))


def run(policy: Path, spawn: str, seconds: float, out: Path, name: str, log: bool) -> int:
    """One realtime run of `policy` (an artifact or a chain's folder) from `spawn` under the joystick script;
    OUT/NAME.mp4, NAME_plot.png, NAME.lcmlog. Returns 0, or 1 when the simulator or the runtime failed."""
    chain = keyframe_chain.is_chain(policy)
    manifests = [read_artifact(p)[3] for p in keyframe_chain.artifact_files(policy)]
    manifest = manifests[0]
    trained = all(bool(m["trained"]) for m in manifests)
    banner = "trained" if trained else "UNTRAINED (random-init placeholder: expect flailing, not getting up)"
    print(f"demo: policy {policy.relative_to(ROOT) if policy.is_relative_to(ROOT) else policy} — {banner}")
    student = describe_student(manifest)
    if student:
        print(f"demo: {student}")
    out.mkdir(parents=True, exist_ok=True)
    video = out / f"{name}.mp4"
    lc = lcm.LCM(contract.lcm_url())
    series = {"t": [], "trunk": [], "waist": [], "vx": [], "kneel": []}
    last: dict[str, object] = {}

    def on_sim(_c, d):
        s = sim_status_t.decode(d)
        last["sim"] = s
        for key, value in (("t", s.utime * 1e-6), ("trunk", s.trunk_height), ("waist", s.waist_height),
                           ("vx", s.forward_velocity)):
            series[key].append(value)
        series["kneel"].append(_kneeling(s.trunk_height, last.get("imu"), last.get("joints")))

    lc.subscribe(contract.CH_SIM_STATUS, on_sim)
    lc.subscribe(contract.CH_IMU, lambda _c, d: last.update(imu=imu_t.decode(d)))
    lc.subscribe(contract.CH_JOINT_STATE, lambda _c, d: last.update(joints=joint_state_t.decode(d)))
    modes: list[tuple[float, str]] = []      # (sim time [s], the runtime's mode) at each status

    def on_status(_c, d):
        last["rt"] = st = controller_status_t.decode(d)
        if "sim" in last:
            modes.append((last["sim"].utime * 1e-6, st.mode_name))

    lc.subscribe(contract.CH_CONTROLLER_STATUS, on_status)
    sim_args = ["--clock", "realtime", "--spawn", spawn, "--duration", str(seconds),
                "--status-rate", f"{1.0 / contract.LOOP_PERIOD_S if chain else STATUS_RATE_HZ:g}", "--record",
                str(video), *VIEWER_ARGS]
    runtime_args = ["--clock", "realtime", "--autostart"]
    capture = None if not log else LogCapture(
        out / f"{name}.lcmlog", contract.lcm_url(),
        RunInfo(run_name=name, producer="demo", clock="realtime", policy_path=str(policy),
                policy_hash="+".join(m["content_hash"] for m in manifests), runtime_args=runtime_args,
                sim_args=sim_args))
    run_key = RunKey()                                  # this run's keys: the operator's and the robot's
    sim = start_sim(*sim_args, run_key=run_key)         # signs its state with the robot key
    runtime = start_runtime(policy, *runtime_args, run_key=run_key)   # takes only that state; the script signs
    signer = runtime.run_key.signer()
    js, seq, next_print, final = joystick_t(), 0, 0.0, None
    stop_cleanly_on_sigterm()
    try:
        while sim.poll() is None:
            lc.handle_timeout(int(1000 / JOYSTICK_RATE_HZ))
            if "sim" not in last:
                continue                        # sim still loading; the joystick script runs on sim time
            t_sim = last["sim"].utime * 1e-6
            js.utime, js.seq = int(time.monotonic() * 1e6), seq
            js.vx, js.vy, js.yaw_rate = joystick_at(t_sim)
            lc.publish(contract.CH_JOYSTICK, signer.sign(contract.CH_JOYSTICK, js))
            seq += 1
            if t_sim >= seconds - 0.05:
                if final is None:             # the run is over: take the runtime's last word, stop it
                    final = last.get("rt")
                    code, err = stop(runtime)
                    print("\ndemo: run complete; the simulator is rendering the video ...", flush=True)
                continue
            if time.monotonic() < next_print:
                continue
            next_print = time.monotonic() + 0.2          # a 5 Hz status line
            rt, s = last.get("rt"), last["sim"]
            mode = rt.mode_name if rt else "starting"
            lat = f"{rt.lateness_us_p99:5.0f}" if rt else "  -  "
            print(f"\rt={t_sim:5.1f}s mode={mode:<8} cmd=({js.vx:.1f},{js.vy:.1f},{js.yaw_rate:.1f}) "
                  f"trunk={s.trunk_height:.2f}m waist={s.waist_height:.2f}m v={s.forward_velocity:+.2f}m/s "
                  f"lateness_p99={lat}us rtf={s.real_time_factor:.2f}  ", end="", flush=True)
    finally:
        if final is None:
            final = last.get("rt")
            code, err = stop(runtime)
        if capture is not None:
            capture.stop()
        print()
    if sim.returncode != 0:
        print(f"demo: the simulator failed:\n{sim.communicate()[1]}", file=sys.stderr)
        return 1
    if code != 0:
        print(f"demo: the runtime exited {code}:\n{err}", file=sys.stderr)
        return 1
    rt = final
    plot = plot_heights_and_velocity(
        {policy.stem: series}, out / f"{name}_plot.png",
        f"{policy.stem} ({'trained' if trained else 'UNTRAINED'}), spawn {spawn}",
        command_vx=[(t, vx) for t, vx, _, _ in JOYSTICK_SCRIPT], modes=modes)
    print(f"demo: runtime ended in {rt.mode_name if rt else '?'}; "
          f"faults: {rt.last_fault if rt and rt.last_fault else 'none'}")
    print(f"demo: video {video}\ndemo: plot  {plot}")
    if capture is not None:
        print(f"demo: log   {capture.path} (make replay LOG={capture.path}; make plot-log LOG={capture.path})")
    return 0


def _kneeling(trunk_height_m: float, imu, joints) -> bool:
    """The kneel band met in the kneeling posture (common/events), from the sim's Trunk height and the robot's
    latest IMU orientation and joint angles (False before both have arrived)."""
    if imu is None or joints is None:
        return False
    up_z = float(events.up_z_from_quat(np.asarray(imu.quat)))
    return bool(events.kneel_gate(trunk_height_m, up_z, np, events.KNEEL_BAND_UP_ERROR)
                and events.kneeling_posture(np.asarray(joints.q)))


if __name__ == "__main__":
    raise SystemExit(main())
