"""Rerun's usage analytics off for this user before the project starts anything of Rerun's (the viewer asks on
its first run and would otherwise report to tel.rerun.io). `rerun analytics disable` is the documented
switch; it writes the user's analytics.json, which the SDK and the viewer both read."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path


def rerun_cli() -> str:
    """The viewer/CLI that the pinned rerun-sdk wheel installs next to this interpreter."""
    exe = Path(sys.executable).parent / "rerun"
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
