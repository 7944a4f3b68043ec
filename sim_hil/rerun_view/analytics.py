"""Rerun's usage analytics off for this user before the project starts anything of Rerun's (the viewer asks on
its first run and would otherwise report to tel.rerun.io). `rerun analytics disable` is the documented
switch; it writes the user's analytics.json, which the SDK and the viewer both read."""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path


def rerun_cli() -> str:
    """The viewer/CLI binary of the pinned rerun-sdk wheel (package rerun_cli). The binary itself, not the venv's
    `rerun` script, which runs it as a child: a process stopped through the script would leave the viewer
    running."""
    spec = importlib.util.find_spec("rerun_cli")
    exe = (Path(spec.origin).parent / "rerun" if spec is not None and spec.origin
           else Path(sys.executable).parent / "rerun")
    if not exe.exists():
        raise FileNotFoundError(f"{exe}: the rerun CLI is missing (rerun-sdk in requirements.txt: run `make setup`)")
    return str(exe)


def config_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "rerun" / "analytics.json"


def analytics_disabled() -> bool:
    try:
        return json.loads(config_path().read_text()).get("analytics_enabled") is False
    except (OSError, ValueError):
        return False


def disable_analytics() -> None:
    """Idempotent: runs the CLI only while the user's config does not say disabled."""
    if analytics_disabled():
        return
    done = subprocess.run([rerun_cli(), "analytics", "disable"], capture_output=True, text=True)
    if done.returncode != 0 or not analytics_disabled():
        raise RuntimeError(f"`rerun analytics disable` failed: {done.stderr.strip() or done.stdout.strip()}")
