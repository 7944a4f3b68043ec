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
    proc = subprocess.Popen(["xvfb-run", "-a", str(Path(sys.executable).parent / "lcm-spy"), f"--lcm-url={netns}"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
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
