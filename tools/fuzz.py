"""Run every fuzz harness for a while and say, per harness, how many inputs it ran, how many coverage edges it
reached and what it found (`make fuzz FUZZ_S=N`; `make test` runs a short pass).

Harnesses: the libFuzzer binaries of a T1_FUZZ build (<build>/fuzz/harnesses.txt: name, seed corpus,
dictionary) and the atheris harnesses tests/fuzz/fuzz_*.py (seeds in tests/fuzz/corpus/<name>). Each runs
on a working corpus under out/fuzz/<name>/corpus seeded from its committed one (which it never writes);
an input that crashed, hung, leaked or tripped a sanitizer is saved as out/fuzz/<name>/crash-* (leak-,
timeout-, oom-) and makes this exit 1: reproduce it with `<harness> FILE`, then fix it and add it to the
ordinary tests.

    python tools/fuzz.py --build build-asan --seconds 60 [--only fuzz_artifact,fuzz_lcmlog]
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PY_HARNESSES = ROOT / "tests" / "fuzz"
FINDING_PREFIXES = ("crash-", "leak-", "timeout-", "oom-")
HANG_S = 10          # one input running longer than this is a hang (libFuzzer -timeout)
RSS_LIMIT_MB = 2048  # a harness above this has a memory blow-up (libFuzzer -rss_limit_mb)
COV = re.compile(r"^#(\d+)\s+\S+\s+cov: (\d+) ft: (\d+)", re.M)
STAT = re.compile(r"^stat::(\w+):\s+(\d+)", re.M)


@dataclass
class Harness:
    name: str
    command: list[str]   # the harness itself, before libFuzzer's flags
    seeds: Path
    dictionary: Path | None


@dataclass
class Result:
    name: str
    executions: int
    edges: int
    features: int
    findings: list[Path]
    status: str


def harnesses(build: Path) -> list[Harness]:
    out = []
    listing = build / "fuzz" / "harnesses.txt"
    if not listing.is_file():
        sys.exit(f"fuzz: {listing} missing: configure {build} with -DT1_FUZZ=ON (make build-asan)")
    for line in listing.read_text().splitlines():
        name, seeds, dictionary = line.split()
        out.append(Harness(name, [str(build / "fuzz" / name)], Path(seeds),
                           None if dictionary == "-" else Path(dictionary)))
    for script in sorted(PY_HARNESSES.glob("fuzz_*.py")):
        dictionary = script.with_suffix(".dict")
        out.append(Harness(script.stem, [sys.executable, "-m", f"tests.fuzz.{script.stem}"],
                           PY_HARNESSES / "corpus" / script.stem, dictionary if dictionary.is_file() else None))
    return out


def run(h: Harness, seconds: int, out_root: Path) -> Result:
    out = out_root / h.name
    work = out / "corpus"
    work.mkdir(parents=True, exist_ok=True)
    before = {p.name for p in out.iterdir()}
    flags = [f"-max_total_time={seconds}", "-print_final_stats=1", f"-artifact_prefix={out}/",
             f"-timeout={HANG_S}", f"-rss_limit_mb={RSS_LIMIT_MB}", "-close_fd_mask=3"]
    if h.dictionary:
        flags.append(f"-dict={h.dictionary}")
    proc = subprocess.run(h.command + flags + [str(work), str(h.seeds)], capture_output=True, text=True,
                          errors="replace", cwd=ROOT, timeout=seconds + 300)
    log = proc.stderr
    (out / "last_run.log").write_text(log)
    covs = COV.findall(log)
    stats = dict(STAT.findall(log))
    findings = sorted(p for p in out.iterdir() if p.name not in before and p.name.startswith(FINDING_PREFIXES))
    status = "ok" if proc.returncode == 0 and not findings else f"FINDING (exit {proc.returncode})"
    return Result(h.name, int(stats.get("number_of_executed_units", covs[-1][0] if covs else 0)),
                  int(covs[-1][1]) if covs else 0, int(covs[-1][2]) if covs else 0, findings, status)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", type=Path, default=ROOT / "build-asan")
    ap.add_argument("--seconds", type=int, default=60, help="per harness")
    ap.add_argument("--only", default="", help="comma-separated harness names")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "fuzz")
    args = ap.parse_args(argv)
    chosen = [h for h in harnesses(args.build) if not args.only or h.name in args.only.split(",")]
    print(f"{'harness':24} {'executions':>12} {'exec/s':>8} {'edges':>7} {'features':>9}  findings")
    failed = False
    for h in chosen:
        r = run(h, args.seconds, args.out)
        failed |= r.status != "ok"
        found = ", ".join(str(p.relative_to(ROOT) if p.is_relative_to(ROOT) else p) for p in r.findings)
        print(f"{r.name:24} {r.executions:>12} {r.executions // max(args.seconds, 1):>8} {r.edges:>7} "
              f"{r.features:>9}  {len(r.findings)} {r.status}{': ' + found if found else ''}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
