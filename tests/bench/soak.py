"""`make bench-soak`: the worst case of the realtime loops under load. The runtime in POLICY against
the realtime simulated T1, both --rt, while the other core runs a CPU and memory load; then cyclictest alone
on the runtime's core, same priority, same load. Reports, side by side: the lateness histograms (PNG), max,
p99.99 and overruns, and the simulator's state stream |period − 2 ms| (kernel receive timestamps, as
state_jitter.py). Targets: runtime max ≤ 2 × cyclictest's max and 0 overruns; sim max |period − 2 ms| ≤ 0.5 ms.

  python -m tests.bench.soak --minutes 10 [--out out/bench/soak]     (inside tools/netns)
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

from messages import contract
from sim_hil.launch import ROOT, start_runtime, start_sim, stop, wait_until_listening
from tests.bench import state_jitter

RT_CPU = 1                     # the runtime's --rt core (its default) and cyclictest's
LOAD_CPU = 0                   # the other core
FIFO_PRIO = 80                 # t1-runtime --rt and cyclictest -p
PERIOD_US = 2000
HIST_MAX_US = 20000            # histogram range, as the runtime's LatenessHistogram
LOAD_MATRIX = 256              # load: float64 matmul size (CPU) ...
LOAD_CHURN_MB = 64             # ... and this much memory allocated, touched and freed each round
TARGET_RATIO = 2.0
TARGET_SIM_MAX_MS = 0.5
STUDENT = ROOT / "policies" / "student" / "student.safetensors"


def _load(stop_at: float) -> None:
    os.sched_setaffinity(0, {LOAD_CPU})
    a = np.random.default_rng(0).standard_normal((LOAD_MATRIX, LOAD_MATRIX))
    while time.time() < stop_at:
        a = np.tanh(a @ a.T / LOAD_MATRIX)
        churn = np.ones(LOAD_CHURN_MB * 2 ** 20 // 8)
        churn[::512] += 1.0
        del churn


class Load:
    """A CPU and memory load process on LOAD_CPU for the duration of a `with` block."""

    def __init__(self, seconds: float):
        self.proc = mp.get_context("spawn").Process(target=_load, args=(time.time() + seconds,), daemon=True)

    def __enter__(self):
        self.proc.start()
        return self

    def __exit__(self, *exc):
        self.proc.terminate()
        self.proc.join()


def summary(bins_us: np.ndarray, counts: np.ndarray, overruns: int) -> dict:
    order = np.argsort(bins_us)
    bins_us, counts = bins_us[order], counts[order]
    cum = np.cumsum(counts) / counts.sum()
    return {"ticks": int(counts.sum()), "max_us": float(bins_us[-1]),
            "p99_us": float(bins_us[np.searchsorted(cum, 0.99)]),
            "p9999_us": float(bins_us[np.searchsorted(cum, 0.9999)]),
            "overruns": int(overruns), "bins_us": bins_us, "counts": counts}


def runtime_soak(seconds: float, out: Path) -> tuple[dict, dict]:
    """The runtime's lateness histogram and the sim's state-stream period deviations [ms]."""
    hist = out / "runtime_lateness.json"
    sock = state_jitter._socket(contract.lcm_url())
    runtime = start_runtime(STUDENT, "--clock", "realtime", "--autostart", "--rt", "--rt-cpu", str(RT_CPU),
                            "--lateness-histogram", str(hist), "--prepare-s", "0.1")
    wait_until_listening(runtime)
    sim = start_sim("--clock", "realtime", "--rt", "--spawn", "standing",
                    "--duration", str(seconds + 2 * state_jitter.SETTLE_S))
    try:
        time.sleep(state_jitter.SETTLE_S)
        arrivals = state_jitter.arrival_times(sock, contract.CH_JOINT_STATE, seconds)
    finally:   # the runtime first: a sim gone first would leave it a stale state to fault on
        code, err = stop(runtime)
        stop(sim)
        sock.close()
    if code != 0:
        raise RuntimeError(f"t1-runtime exited {code}: {err[-800:]}")
    fault = re.search(r"last fault: (.*)$", err.strip().splitlines()[-1])
    r = json.loads(hist.read_text())
    rt = summary(np.array(r["lateness_us"]["bin_us"]), np.array(r["lateness_us"]["count"]), r["overruns"])
    rt["fault"] = fault.group(1) if fault else "?"
    dev_ms = np.abs(np.diff(arrivals) - PERIOD_US * 1e-6) * 1e3
    sim = {"n": int(dev_ms.size), "max_ms": float(dev_ms.max()), "p9999_ms": float(np.percentile(dev_ms, 99.99)),
           "p99_ms": float(np.percentile(dev_ms, 99))}
    return rt, sim


def cyclictest_soak(seconds: float) -> dict:
    exe = shutil.which("cyclictest")
    if exe is None:
        raise RuntimeError("cyclictest not found (Debian package rt-tests, installed by tools/setup.sh)")
    proc = subprocess.run([exe, "-q", "-m", "-D", f"{int(seconds)}", "-i", str(PERIOD_US), "-p", str(FIFO_PRIO),
                           "-a", str(RT_CPU), "-t", "1", "--policy=fifo", "-h", str(HIST_MAX_US)],
                          capture_output=True, text=True, timeout=seconds + 60)
    if proc.returncode != 0:
        raise RuntimeError(f"cyclictest exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    rows = [line.split() for line in proc.stdout.splitlines() if line and line[0].isdigit()]
    bins = np.array([int(r[0]) for r in rows if int(r[1]) > 0])
    counts = np.array([int(r[1]) for r in rows if int(r[1]) > 0])
    overflow = re.search(r"# Histogram Overflows: (\d+)", proc.stdout)
    over = int(overflow.group(1)) if overflow else 0
    if over:   # beyond the histogram: at its edge, as the runtime's last bin
        bins, counts = np.append(bins, HIST_MAX_US), np.append(counts, over)
    mx = re.search(r"# Max Latencies: (\d+)", proc.stdout)
    s = summary(bins, counts, overruns=0)
    s["max_us"] = float(mx.group(1)) if mx else s["max_us"]
    s["overruns"] = int(counts[bins >= PERIOD_US].sum())   # woke a whole period late
    return s


def plot(rt: dict, ct: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 4))
    for name, s in (("t1-runtime --rt (POLICY vs realtime sim)", rt), ("cyclictest -p 80 -m", ct)):
        ax.step(s["bins_us"], s["counts"], where="mid", label=f"{name}: max {s['max_us']:.0f} µs")
    ax.set(xscale="log", yscale="log", xlabel="wake-up lateness [µs]", ylabel="ticks",
           title=f"500 Hz loops on CPU {RT_CPU}, CPU {LOAD_CPU} loaded")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=float, default=10.0, help="each of the two runs (default 10)")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench" / "soak")
    args = ap.parse_args(argv)
    if not args.minutes > 0:
        ap.error(f"--minutes {args.minutes}: must be > 0")
    if os.cpu_count() is None or os.cpu_count() <= RT_CPU:
        ap.error(f"needs at least {RT_CPU + 1} cores (the loop on CPU {RT_CPU}, the load on CPU {LOAD_CPU})")
    seconds = args.minutes * 60.0
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"== soak: {args.minutes:g} min of t1-runtime --rt against the realtime sim --rt, then {args.minutes:g} min "
          f"of cyclictest, CPU {LOAD_CPU} loaded (matmul {LOAD_MATRIX}² + {LOAD_CHURN_MB} MB churn) ==", flush=True)
    with Load(seconds + 30):
        rt, sim = runtime_soak(seconds, args.out)
    with Load(seconds + 30):
        ct = cyclictest_soak(seconds)
    plot(rt, ct, args.out / "lateness.png")
    ratio = rt["max_us"] / ct["max_us"] if ct["max_us"] else float("inf")
    for name, s in (("t1-runtime --rt", rt), ("cyclictest", ct)):
        print(f"{name:<16} {s['ticks']} ticks: lateness p99 {s['p99_us']:.0f} µs, p99.99 {s['p9999_us']:.0f} µs, "
              f"max {s['max_us']:.0f} µs, overruns {s['overruns']}")
    print(f"runtime max / cyclictest max = {ratio:.2f} (target ≤ {TARGET_RATIO}), runtime overruns {rt['overruns']} "
          f"(target 0), runtime fault: {rt['fault']}")
    print(f"sim state stream {sim['n']} periods: |period − 2 ms| p99 {sim['p99_ms']:.3f} ms, "
          f"p99.99 {sim['p9999_ms']:.3f} "
          f"ms, max {sim['max_ms']:.3f} ms (target ≤ {TARGET_SIM_MAX_MS} ms)")
    print(f"histograms: {args.out / 'lateness.png'}")
    return {"runtime": rt, "cyclictest": ct, "sim": sim, "ratio": ratio}


if __name__ == "__main__":
    main()
