"""``scenario run A B C`` runs the scenarios of one robot and pace together, on one bring-up, those of one scene
together within them (one world loaded per scene), and reports them in the order given
(sim_client.scenario.running.runner.run_order)."""

from __future__ import annotations

from sim_client.scenario.model import schema
from sim_client.scenario.running.options import RunOptions
from sim_client.scenario.running.runner import run_order


def _load(*names: str) -> list[schema.Scenario]:
    return [schema.load(schema.find(name)) for name in names]


def test_scenarios_of_one_robot_and_scene_run_together_in_the_order_given():
    scenarios = _load("walk_2m", "navigate_around_obstacle", "pick_place_box", "cancel_walk", "move_arm_sequence")
    assert [(s.robot, s.scene) for s in scenarios] == [("g1", "open"), ("g1", "course"), ("panda", "table"),
                                                        ("g1", "open"), ("panda", "table")]
    assert run_order(scenarios) == [0, 3, 1, 2, 4]  # G1 open twice, then the course, then the Panda twice


def test_the_scenes_of_one_robot_run_one_after_the_other_each_in_the_order_given():
    scenarios = _load("fetch_box", "walk_2m", "fetch_cube", "navigate_around_obstacle", "cancel_walk")
    assert [s.scene for s in scenarios] == ["tables", "open", "tables", "course", "open"]
    assert run_order(scenarios) == [0, 2, 1, 4, 3]  # one bring-up: the tables, the open floor, the course


def test_a_pace_given_on_the_command_line_counts_and_attached_runs_keep_the_order_given():
    scenarios = _load("walk_2m", "navigate_around_obstacle", "cancel_walk")
    assert run_order(scenarios, RunOptions(rtf=2.0)) == [0, 2, 1]
    assert run_order(scenarios, RunOptions(launch=False)) == [0, 1, 2]  # the nodes are the user's: nothing to group
