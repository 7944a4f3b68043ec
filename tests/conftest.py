"""Shared pytest set-up: every test that touches LCM must run inside the project namespace (make test
wraps pytest in tools/netns); refuse to run otherwise instead of sending multicast on real interfaces."""
import os

import pytest

# The tests run MJX/JAX programs for a handful of steps: XLA at -O0 compiles ~2.5x faster and runs ~3.5x
# slower, the right trade for CI (it must be set before jax initialises its backend, hence here).
os.environ.setdefault("XLA_FLAGS", "--xla_backend_optimization_level=0")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: long-running (seconds of wall time); still part of make test")


@pytest.fixture(scope="session")
def netns():
    if os.environ.get("T1_NETNS_INSIDE") != "1":
        pytest.skip("needs the project network namespace: run through `make test` (tools/netns)")
    return os.environ["T1_LCM_URL"]
