"""Paths and helpers the benchmarks of `make bench` share (runtime_bench.py, link_latency.py)."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("T1_BUILD", ROOT / "build"))
BENCH_BIN = BUILD / "runtime" / "bench"
RUNTIME_BIN = BUILD / "runtime" / "t1-runtime"


def bench_binary(name: str) -> Path:
    path = BENCH_BIN / name
    if not path.exists():
        raise SystemExit(f"runtime_bench: {path} missing: run `make build` (runtime/bench is part of the build)")
    return path


def run_json(cmd: list, timeout_s: float) -> dict:
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout_s)
    if proc.returncode != 0:
        raise RuntimeError(f"{Path(str(cmd[0])).name} exited {proc.returncode}: {proc.stderr.strip()[-800:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def ratio(a: float, b: float) -> str:
    return f"{a / b:.2f}" if b > 0 else "n/a"
