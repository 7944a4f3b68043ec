"""State -> command latency of `make bench` (sections 3 and 4 of runtime_bench.py): t1-runtime --clock lockstep
over LCM against a raw LCM echo, its joystick signed (--key) and unsigned (--unauthenticated); the signed and
the unsigned runtime side by side, the peer alternating between them exchange by exchange and all three on one
core, so both meet the same load and the same scheduler (unpinned, each process's place on a shared 2-core VM
moved its median 27 <-> 67 us from run to run); and over DDS (Cyclone, the T1's own topics) next to the LCM row."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np

from messages import contract
from messages.auth import RunKey
from tests.bench.bench_tools import RUNTIME_BIN, bench_binary, ratio, run_json

JOYSTICK_EVERY = 10                # the peer's joystick every 10th state: a gamepad's 50 Hz at 500 Hz states
PAIRED_CPU = 1                     # the side-by-side runs share this core: one scheduler queue for all three
SIGNING_ROUNDS = 6                 # signed and unsigned runtime side by side, each first in turn (even)


# ------------------------------------------------------------------------------------ 3. LCM latency
def _echo_url(url: str) -> str:
    """The echo's own LCM URL: the runtime's with the port + 1, so both run at once and the peer alternates."""
    return contract.lcm_url_on_port(1, url)


def _runtime_cmd(policy: Path, url: str, key: RunKey | None, budget_s: float) -> list:
    """t1-runtime --clock lockstep --autostart with --key KEY, else --unauthenticated."""
    auth = ["--key", key.key_path, "--approvals", key.approvals_path] if key else ["--unauthenticated"]
    return [RUNTIME_BIN, "--clock", "lockstep", "--policy", policy, "--autostart", "--quiet", "--duration", budget_s,
            "--lcm-url", url, *auth]


def _lcm_run(policy: Path, count: int, url: str, key: RunKey | None, second: str, second_key: RunKey | None,
             cpu: int | None = None) -> dict:
    """A runtime on `url` (signed joystick with KEY, else unsigned to a --unauthenticated one) and, on the next
    port, the echo (second "echo") or another runtime (second "runtime", SECOND_KEY likewise); the peer alternates
    between them exchange by exchange, a joystick to each every JOYSTICK_EVERY states. cpu: all three pinned
    to that core (taskset), so none is placed apart from the others."""
    echo_url, budget_s = _echo_url(url), 300.0
    other = ([bench_binary("t1rt_bench_lcm_echo"), "--seconds", budget_s, "--lcm-url", echo_url] if second == "echo"
             else _runtime_cmd(policy, echo_url, second_key, budget_s))
    pin = ["taskset", "-c", cpu] if cpu is not None else []
    servers = [subprocess.Popen([str(c) for c in pin + cmd], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
               for cmd in (other, _runtime_cmd(policy, url, key, budget_s))]
    keys = [*(["--key", key.key_path] if key else []), *(["--echo-key", second_key.key_path] if second_key else [])]
    try:
        return run_json(pin + [bench_binary("t1rt_bench_lcm_peer"), "--count", count, "--wait-policy", "--lcm-url", url,
                               "--echo-url", echo_url, "--joystick-every", JOYSTICK_EVERY, *keys], budget_s)
    finally:
        for server in servers:
            server.terminate()
            _, err = server.communicate(timeout=10)
            if server.returncode not in (0, -15):
                raise RuntimeError(f"{server.args[0]} exited {server.returncode}: {err.strip()[-400:]}")


def bench_lcm(policy: Path, count: int) -> dict:
    print(f"\n== State -> command latency over LCM, lockstep, {count} exchanges a run, two answering processes "
          f"alternating exchange by exchange (µs); a joystick every {JOYSTICK_EVERY}th state, signed to a runtime "
          f"with --key, unsigned to one with --unauthenticated ==")
    url = os.environ.get("T1_LCM_URL")
    if url is None:
        raise RuntimeError("T1_LCM_URL unset: run inside tools/netns (make bench does)")
    key = RunKey()
    try:
        key.approve(policy)
        against_echo = {name: _lcm_run(policy, count, url, k, "echo", None) for name, k in (("signed", key),
                                                                                           ("unsigned", None))}
        # The two runtimes side by side, each first in turn (a process's place on the cores is its own).
        paired = [_lcm_run(policy, count, url, key, "runtime", None, PAIRED_CPU) if i % 2 == 0 else
                  _lcm_run(policy, count, url, None, "runtime", key, PAIRED_CPU) for i in range(SIGNING_ROUNDS)]
    finally:
        key.close()
    rows = [("t1-runtime lockstep, all ticks", "latency_us"), ("  ticks without policy or joystick", "plain_tick_us"),
            ("  joystick ticks (without policy)", "joystick_tick_us"),
            ("  policy ticks (MLP, every 10th)", "policy_tick_us")]
    print(f"{'against the raw LCM echo (C++)':<44}{'n':>7}{'median':>9}{'p99':>9}{'max':>9}"
          "   ratio to the echo median / p99")
    for name, r in against_echo.items():
        for label, k in [("raw LCM echo (C++)", "echo_us")] + rows:
            print(f"{label + f' [{name}]':<44}{int(r[k + '_count']):>7}{r[k + '_median']:>9.1f}{r[k + '_p99']:>9.1f}"
                  f"{r[k + '_max']:>9.1f}   {ratio(r[k + '_median'], r['echo_us_median'])} / "
                  f"{ratio(r[k + '_p99'], r['echo_us_p99'])}")
    signed_over = []
    for i, r in enumerate(paired):          # even runs: the signed runtime is the peer's target, odd: its echo side
        s_, u_ = ("latency_us", "echo_us") if i % 2 == 0 else ("echo_us", "latency_us")
        signed_over.append((r[s_ + "_median"] / r[u_ + "_median"], r[s_ + "_p99"] / r[u_ + "_p99"]))
        print(f"side by side, run {i + 1}: signed runtime median / p99 "
              f"{r[s_ + '_median']:.1f} / {r[s_ + '_p99']:.1f} µs, "
              f"unsigned {r[u_ + '_median']:.1f} / {r[u_ + '_p99']:.1f} µs")
    # The geometric mean over runs that put each runtime first equally often: a bias of the position cancels.
    gm = np.exp(np.mean(np.log(np.asarray(signed_over)), axis=0))
    print(f"signed / unsigned runtime, all ticks, side by side (geometric mean of {SIGNING_ROUNDS} runs, each runtime "
          f"first in half): median {gm[0]:.2f}x, p99 {gm[1]:.2f}x")
    print(f"(peer publishes T1_IMU + T1_JOINT_STATE k, times until the T1_JOINT_CMD with state_seq k arrives; the "
          f"T1_JOYSTICK follows the state inside its exchange; runtimes in POLICY after --autostart, on {url} and "
          f"{_echo_url(url)})")
    return against_echo["signed"]


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
