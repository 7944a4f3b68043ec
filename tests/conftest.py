"""Shared pytest set-up: every test that touches LCM must run inside the project namespace (make test
wraps pytest in tools/netns); refuse to run otherwise instead of sending multicast on real interfaces."""
import os

import pytest


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: long-running (seconds of wall time); still part of make test")


@pytest.fixture(scope="session")
def netns():
    if os.environ.get("T1_NETNS_INSIDE") != "1":
        pytest.skip("needs the project network namespace: run through `make test` (tools/netns)")
    return os.environ["T1_LCM_URL"]
