"""Pieces of the server nodes that need no running graph: step counting across resets, guarded goals."""

from __future__ import annotations

from nodes.locomotion_server import StepCounter


def test_step_counter_counts_on_across_a_restart_of_the_controller_count():
    steps = StepCounter()
    assert steps.update(7) == 0, "counting starts when the goal begins"
    assert steps.update(9) == 2
    assert steps.update(1) == 3, "the count restarted at 0 (a reset) and one step was taken since"
    assert steps.update(4) == 6
    assert steps.update(4) == 6


def test_a_stale_count_from_before_a_reset_never_makes_the_total_negative():
    steps = StepCounter()
    steps.update(25)  # from before the reset, arrived late
    assert steps.update(0) == 0
    assert steps.update(2) == 2
