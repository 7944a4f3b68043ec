"""The project's own tools: the network namespace (multicast never leaves loopback) and lcm-spy decoding
every project type."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BUILD = Path(os.environ.get("T1_BUILD", ROOT / "build"))


def test_namespace_has_only_loopback_with_multicast_routed(netns):
    links = subprocess.run(["ip", "-o", "link"], capture_output=True, text=True, check=True).stdout
    assert [line.split(":")[1].strip() for line in links.strip().splitlines()] == ["lo"]
    routes = subprocess.run(["ip", "route"], capture_output=True, text=True, check=True).stdout
    assert "224.0.0.0/4 dev lo" in routes
    assert "ttl=0" in netns


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="needs xvfb-run (Debian xvfb, installed by make setup)")
def test_lcm_spy_finds_every_project_type(netns):
    jar = BUILD / "gen" / "java" / "t1_lcmtypes.jar"
    assert jar.exists(), "make build did not produce the lcm-spy type jar"
    n_types = len(list((ROOT / "messages" / "t1").glob("*.lcm")))
    env = dict(os.environ, CLASSPATH=str(jar))
    proc = subprocess.Popen(["xvfb-run", "-a", str(Path(sys.executable).parent / "lcm-spy"), f"--lcm-url={netns}"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    out = ""
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and f"Found {n_types} LCM types" not in out:
            line = proc.stdout.readline()
            if not line:
                break
            out += line
    finally:
        os.killpg(proc.pid, 15)
        proc.wait(timeout=10)
    assert f"Found {n_types} LCM types" in out, out[-2000:]


# ------------------------------------------------------------------ make bench's reference
def _bench_env(*args: str, venv: Path, inside: bool) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "T1_NETNS_INSIDE"}
    env["BENCH_VENV"] = str(venv)
    if inside:
        env["T1_NETNS_INSIDE"] = "1"
    return subprocess.run([str(ROOT / "tools" / "bench_env.sh"), *args], env=env, capture_output=True, text=True,
                          timeout=120)


def test_bench_env_never_runs_pip_inside_the_namespace(netns, tmp_path):
    venv = tmp_path / "venv-bench"
    proc = _bench_env(venv=venv, inside=True)
    assert proc.returncode == 1 and "make bench-env" in proc.stderr, proc.stderr
    assert not venv.exists(), "bench_env.sh started an install where no registry is reachable"
    proc = _bench_env("--check", venv=venv, inside=False)
    assert proc.returncode == 1 and "make bench-env" in proc.stderr, proc.stderr
    # An up-to-date venv (python + requirements stamp) is found by --check, which installs nothing.
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").symlink_to(sys.executable)
    import hashlib
    req = (ROOT / "tests" / "bench" / "requirements-bench.txt").read_bytes()
    (venv / ".requirements.sha").write_text(hashlib.sha256(req).hexdigest() + "\n")
    proc = _bench_env("--check", venv=venv, inside=True)
    assert proc.returncode == 0 and proc.stdout.strip().endswith("venv-bench/bin/python"), proc.stderr


def test_make_bench_installs_its_reference_before_entering_the_namespace(netns, tmp_path, monkeypatch):
    out = subprocess.run(["make", "-n", "bench"], cwd=ROOT, capture_output=True, text=True, timeout=120).stdout
    lines = out.splitlines()
    install = [i for i, line in enumerate(lines) if "tools/bench_env.sh" in line and "--check" not in line]
    bench = [i for i, line in enumerate(lines) if "tools/netns" in line and "tests.bench" in line]
    assert install and bench and install[0] < bench[0], out
    assert "tools/netns" not in lines[install[0]]
    # Inside the namespace the benchmark only checks: a missing venv gives a reason, not a pip run.
    from tests.bench import runtime_bench
    monkeypatch.setenv("BENCH_VENV", str(tmp_path / "missing"))
    python, why = runtime_bench._bench_python()
    assert python is None and "make bench-env" in why and not (tmp_path / "missing").exists()
