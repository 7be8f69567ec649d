"""A server relays /sim's goal states as feedback in sim-time order (nodes.servers.server.feedback_due)."""

from __future__ import annotations

import math

from nodes.servers.server import feedback_due

PERIOD_S = 0.2


def test_the_first_state_is_relayed_then_one_per_period_and_every_new_milestone():
    assert feedback_due(-math.inf, -1, 0.0, 0, PERIOD_S)
    assert not feedback_due(1.0, 0, 1.1, 0, PERIOD_S)
    assert feedback_due(1.0, 0, 1.25, 0, PERIOD_S)
    assert feedback_due(1.0, 0, 1.01, 1, PERIOD_S), "a new milestone at once"


def test_a_state_older_than_the_last_relayed_is_never_relayed_even_with_another_milestone():
    # The goal's first state (APPROACH, milestone 0), published again for a START sent again, after LIFT (milestone 3).
    assert not feedback_due(12.5, 3, 0.4, 0, PERIOD_S)
    assert not feedback_due(12.5, 3, 12.49, 2, PERIOD_S)
    assert feedback_due(12.5, 3, 12.5, 4, PERIOD_S), "the same sim time, a new milestone"
