"""Fixtures of the scenario and command-line tests."""

from __future__ import annotations

import pytest

from sim_client import RosSession


@pytest.fixture(scope="module")
def client():
    """A client node in the test process (the nodes under test run in other processes)."""
    with RosSession("scenario_test_client", use_sim_time=False) as session:
        yield session
