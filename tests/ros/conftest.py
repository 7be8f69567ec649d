"""Fixtures shared by the cross-process ROS tests."""

from __future__ import annotations

import pytest

from sim_client import RosSession


@pytest.fixture(scope="module")
def client():
    """A client node in the test process (a different process from the nodes under test)."""
    with RosSession("test_client", use_sim_time=False) as session:
        yield session


@pytest.fixture(autouse=True)
def _recorders_end_with_their_test(request):
    """The topic recorders a test (or its function-scoped fixtures) made stop when it ends.

    A module's client lives across its tests: a recorder left subscribed keeps taking every message of
    its topic from the next tests' nodes too, and a few of them at 100 Hz each starve the client on a
    loaded machine (its latest /odom then lags the sim by seconds). Recorders of module-scoped fixtures
    were made before this fixture and are left alone.
    """
    if "client" not in request.fixturenames:
        yield
        return
    session = request.getfixturevalue("client")
    made_before = len(session.recorders)
    yield
    for recorder in session.recorders[made_before:]:
        recorder.stop()
    del session.recorders[made_before:]
