"""State -> command latency of `make bench` (sections 3 and 4 of runtime_bench.py): t1-runtime --clock lockstep
over LCM against a raw LCM echo, its joystick unsigned (--unauthenticated) and signed (--key) in the same run,
and over DDS (Cyclone, the T1's own topics) next to the LCM row."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np

from messages import contract
from messages.auth import RunKey
from tests.bench.bench_tools import RUNTIME_BIN, bench_binary, ratio, run_json

JOYSTICK_EVERY = 10                # the peer's joystick every 10th state: a gamepad's 50 Hz at 500 Hz states
SIGNING_ROUNDS = 3                 # unsigned and signed runs, in turn: the median of their ratios is reported


# ------------------------------------------------------------------------------------ 3. LCM latency
def _echo_url(url: str) -> str:
    """The echo's own LCM URL: the runtime's with the port + 1, so both run at once and the peer alternates."""
    return contract.lcm_url_on_port(1, url)


def _lcm_pair(policy: Path, count: int, url: str, key: RunKey | None) -> dict:
    """One runtime (--key KEY, else --unauthenticated) and the echo, the peer alternating between them and
    sending the runtime a joystick every JOYSTICK_EVERY states (signed with KEY when given)."""
    echo_url, budget_s = _echo_url(url), 300.0
    auth = ["--key", key.key_path, "--approvals", key.approvals_path] if key else ["--unauthenticated"]
    servers = [subprocess.Popen([str(c) for c in cmd], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
               for cmd in ([bench_binary("t1rt_bench_lcm_echo"), "--seconds", budget_s, "--lcm-url", echo_url],
                           [RUNTIME_BIN, "--clock", "lockstep", "--policy", policy, "--autostart", "--quiet",
                            "--duration", budget_s, "--lcm-url", url, *auth])]
    try:
        return run_json([bench_binary("t1rt_bench_lcm_peer"), "--count", count, "--wait-policy", "--lcm-url", url,
                          "--echo-url", echo_url, "--joystick-every", JOYSTICK_EVERY,
                          *(["--key", key.key_path] if key else [])], budget_s)
    finally:
        for server in servers:
            server.terminate()
            _, err = server.communicate(timeout=10)
            if server.returncode not in (0, -15):
                raise RuntimeError(f"{server.args[0]} exited {server.returncode}: {err.strip()[-400:]}")


def bench_lcm(policy: Path, count: int) -> dict:
    print(f"\n== State -> command latency over LCM, lockstep, {count} exchanges a run, runtime and echo alternating "
          f"(µs; ratio = runtime / echo); the runtime's joystick unsigned (--unauthenticated) and signed (--key), "
          f"{SIGNING_ROUNDS} runs each in turn ==")
    url = os.environ.get("T1_LCM_URL")
    if url is None:
        raise RuntimeError("T1_LCM_URL unset: run inside tools/netns (make bench does)")
    key = RunKey()
    runs: dict[str, list[dict]] = {"unsigned": [], "signed": []}
    try:
        key.approve(policy)
        for _ in range(SIGNING_ROUNDS):      # in turn, so both see the machine's load drift alike
            runs["unsigned"].append(_lcm_pair(policy, count, url, None))
            runs["signed"].append(_lcm_pair(policy, count, url, key))
    finally:
        key.close()
    rows = [("raw LCM echo (C++)", "echo_us"), ("t1-runtime lockstep, all ticks", "latency_us"),
            ("  ticks without policy or joystick", "plain_tick_us"), ("  joystick ticks (without policy)", "joystick_tick_us"),
            ("  policy ticks (MLP, every 10th)", "policy_tick_us")]
    normalised = {name: {k: float(np.median([r[k + "_median"] / r["echo_us_median"] for r in rs])) for _, k in rows}
                  for name, rs in runs.items()}
    print(f"{'(the run of median all-ticks ratio)':<44}{'n':>7}{'median':>9}{'p99':>9}{'max':>9}   ratio median / p99")
    for name, rs in runs.items():
        r = sorted(rs, key=lambda x: x["latency_us_median"] / x["echo_us_median"])[len(rs) // 2]
        for label, k in rows:
            print(f"{label + f' [{name}]':<44}{int(r[k + '_count']):>7}{r[k + '_median']:>9.1f}{r[k + '_p99']:>9.1f}"
                  f"{r[k + '_max']:>9.1f}   {ratio(r[k + '_median'], r['echo_us_median'])} / "
                  f"{ratio(r[k + '_p99'], r['echo_us_p99'])}")
    s, u = normalised["signed"], normalised["unsigned"]
    for label, k in rows[1:]:
        print(f"signed / unsigned, {label.strip():<34} (median / echo median, median of {SIGNING_ROUNDS} runs): "
              f"{s[k]:.2f} / {u[k]:.2f} = {s[k] / u[k]:.2f}x")
    # Within one runtime process, so free of the runs' placement on the cores: a joystick tick over a plain one.
    within = {name: float(np.median([r["joystick_tick_us_median"] - r["plain_tick_us_median"] for r in rs]))
              for name, rs in runs.items()}
    print(f"joystick tick - plain tick, same run (median of {SIGNING_ROUNDS}): signed {within['signed']:+.1f} µs, "
          f"unsigned {within['unsigned']:+.1f} µs: verifying costs {within['signed'] - within['unsigned']:+.1f} µs "
          f"on a joystick tick")
    print(f"(peer publishes T1_IMU + T1_JOINT_STATE k, times until the T1_JOINT_CMD with state_seq k arrives; a "
          f"T1_JOYSTICK follows every {JOYSTICK_EVERY}th state inside its exchange; runtime in POLICY mode after "
          f"--autostart on {url}, echo on {_echo_url(url)}; the two exchanges alternate)")
    return sorted(runs["signed"], key=lambda x: x["latency_us_median"] / x["echo_us_median"])[SIGNING_ROUNDS // 2]


# ------------------------------------------------------------------------------------ 4. DDS latency
def bench_dds(policy: Path, count: int, lcm: dict | None) -> None:
    """The same runtime with --transport dds against a DDS robot peer, in the same run as the LCM rows."""
    print(f"\n== State -> command latency over DDS (Cyclone, rt/low_state -> rt/joint_ctrl) vs LCM, lockstep, "
          f"{count} exchanges (µs; ratio = DDS / LCM runtime) ==")
    if not os.environ.get("CYCLONEDDS_URI"):
        raise RuntimeError("CYCLONEDDS_URI unset: run inside tools/netns (make bench does), loopback-only DDS")
    budget_s = 300.0
    # Its own LCM port for status/telemetry, so it cannot meet the LCM section's peers.
    status_url = _echo_url(_echo_url(os.environ["T1_LCM_URL"]))
    server = subprocess.Popen([str(c) for c in (RUNTIME_BIN, "--transport", "dds", "--clock", "lockstep", "--policy",
                                                policy, "--autostart", "--quiet", "--duration", budget_s,
                                                "--lcm-url", status_url)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        r = run_json([bench_binary("t1rt_bench_dds_peer"), "--count", count], budget_s)
    finally:
        server.terminate()
        _, err = server.communicate(timeout=10)
        if server.returncode not in (0, -15):
            raise RuntimeError(f"t1-runtime --transport dds exited {server.returncode}: {err.strip()[-400:]}")
    print(f"{'':<40}{'n':>7}{'median':>9}{'p99':>9}{'max':>9}   ratio median / p99")
    rows = [("t1-runtime lockstep over DDS", r)] + ([("t1-runtime lockstep over LCM (above)", lcm)] if lcm else [])
    for label, x in rows:
        ratios = (f"{ratio(x['latency_us_median'], lcm['latency_us_median'])} / "
                  f"{ratio(x['latency_us_p99'], lcm['latency_us_p99'])}") if lcm else "-"
        print(f"{label:<40}{int(x['latency_us_count']):>7}{x['latency_us_median']:>9.1f}{x['latency_us_p99']:>9.1f}"
              f"{x['latency_us_max']:>9.1f}   {ratios}")
    print("(peer writes LowState_ and times until the next LowCmd_ arrives; runtime in POLICY mode after --autostart "
          "and 2000 warm-up exchanges; all ticks, policy ticks included)")
