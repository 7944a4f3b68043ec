"""Shared pytest set-up: every test that touches LCM must run inside the project namespace (make test
wraps pytest in tools/netns); refuse to run otherwise instead of sending multicast on real interfaces.

`make test` runs pytest on two workers (pytest-xdist): each test file goes to one worker
whole (its module fixtures are built once), each worker has its own LCM ports, and the files that speak DDS
(one domain, messages/contract.json) share one worker."""
import os
from pathlib import Path

import pytest

import common.render  # noqa: F401  (first: it picks the offscreen GL before any test module loads mujoco)
from messages import contract

DDS_FILES = {"test_dds.py", "test_dds_booster_sdk.py", "test_fastdds_shim.py", "test_motor_watchdog.py",
             "test_state_source.py"}
# The files whose module fixtures train toy runs (minutes each): scheduled first, so the many short files fill
# the workers around them instead of one worker finishing the run alone on one of these.
LONG_FILES = ("test_recipes.py", "test_training_cli.py")
WORKER_PORT_STRIDE = 1000   # LCM ports of worker k: the contract's + k × this (trial ports add < 200)


def _worker_index() -> int:
    name = os.environ.get("PYTEST_XDIST_WORKER", "")    # gw0, gw1, … under xdist
    return int(name[2:]) if name.startswith("gw") else 0


if _worker_index() and "T1_LCM_URL" in os.environ:
    os.environ["T1_LCM_URL"] = os.environ["LCM_DEFAULT_URL"] = contract.lcm_url_on_port(
        WORKER_PORT_STRIDE * _worker_index())

# The tests run MJX/JAX programs for a handful of steps: XLA at -O0 compiles ~2.5x faster and runs ~3.5x
# slower, and XLA:CPU's older emitters (no fusion emitters) compile a toy PPO epoch in half the time: the
# right trade for CI. Set before jax initialises its backend, hence here; the training subprocesses the tests
# start inherit it.
os.environ.setdefault("XLA_FLAGS", "--xla_backend_optimization_level=0 --xla_cpu_use_fusion_emitters=false")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: long-running (seconds of wall time); still part of make test")


def _file(nodeid: str) -> str:
    return Path(nodeid.split("::", 1)[0]).name


def pytest_collection_modifyitems(config, items):
    """LONG_FILES first, then the files with most tests (xdist's own order, which the scheduler below keeps)."""
    count = {}
    for item in items:
        count[_file(item.nodeid)] = count.get(_file(item.nodeid), 0) + 1
    items.sort(key=lambda item: (_file(item.nodeid) not in LONG_FILES, -count[_file(item.nodeid)]))   # stable


def pytest_xdist_make_scheduler(config, log):
    """Under xdist: each test file one work unit (its module fixtures built once), the DDS files one unit."""
    from xdist.scheduler import LoadScopeScheduling

    class FileScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return "dds" if Path(path).name in DDS_FILES else path

    config.option.loadscopereorder = False      # the collection's order (pytest_collection_modifyitems)
    return FileScheduling(config, log)


@pytest.fixture(scope="session")
def netns():
    if os.environ.get("T1_NETNS_INSIDE") != "1":
        pytest.skip("needs the project network namespace: run through `make test` (tools/netns)")
    return os.environ["T1_LCM_URL"]

