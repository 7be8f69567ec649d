"""Fixtures shared by the cross-process ROS tests."""

from __future__ import annotations

import pytest

from sim_client import RosSession


@pytest.fixture(scope="module")
def client():
    """A client node in the test process (a different process from the nodes under test)."""
    with RosSession("test_client", use_sim_time=False) as session:
        yield session
