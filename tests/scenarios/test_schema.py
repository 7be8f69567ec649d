"""Scenario files: every shipped one validates; bad ones are reported with file, line and what is wrong."""

from __future__ import annotations

import pathlib
import textwrap

import pytest

from sim_client.scenario import schema

SHIPPED = schema.all_files()

GOOD = """\
name: ok
robot: panda
steps:
  - wait: {duration: 0.5}
expect:
  - name: box on the table
    measure: {object_position: {object: box_0, axis: z}}
    near: 0.02
    tol: 0.01
"""


def write(tmp_path: pathlib.Path, text: str) -> pathlib.Path:
    path = tmp_path / "case.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def test_the_shipped_scenarios_exist_for_both_robots():
    names = {p.stem for p in SHIPPED}
    assert {"reset_and_stand_g1", "reset_and_stand_panda", "walk_2m", "walking_speed_change", "navigate_around_obstacle",
            "move_arm_sequence", "pick_place_box", "reset_mid_walk"} <= names
    robots = {schema.load(p).robot for p in SHIPPED}
    assert robots == {"g1", "panda"}


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_every_shipped_scenario_validates(path):
    scenario = schema.load(path)
    assert scenario.name == path.stem
    assert scenario.expectations, "a scenario without expectations judges nothing"
    assert scenario.robot in schema.ROBOTS


def test_a_good_file_loads_into_typed_values(tmp_path):
    scenario = schema.load(write(tmp_path, GOOD))
    assert scenario.robot == "panda" and scenario.keyframe == "home" and scenario.rtf == 0.0
    assert isinstance(scenario.steps[0], schema.WaitStep) and scenario.steps[0].duration == 0.5
    expectation = scenario.expectations[0]
    assert expectation.measure.kind == "object_position" and expectation.comparison.holds(0.025)
    assert not expectation.comparison.holds(0.04)


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        (GOOD.replace("robot: panda", "robot: atlas"), 2, "robot 'atlas' is not one of: g1, panda"),
        (GOOD.replace("duration: 0.5", "duration: soon"), 4, "duration must be a number"),
        (GOOD.replace("duration: 0.5", "duration: -1"), 4, "duration must be >= 0.0"),
        (GOOD.replace("  - wait: {duration: 0.5}", "  - jump: {height: 1}"), 4, "unknown key 'jump'"),
        (GOOD.replace("object: box_0", "object: box_7"), 7, "has no object 'box_7'"),
        (GOOD.replace("    tol: 0.01\n", ""), 8, "near needs exactly one of tol"),
        (GOOD.replace("    near: 0.02\n    tol: 0.01\n", ""), 6, "give exactly one comparison"),
        (GOOD.replace("axis: z", "axis: w"), 7, "axis 'w' is not one of: x, y, z"),
        (GOOD + "colour: red\n", 10, "unknown key 'colour'"),
        (GOOD.replace("  - wait: {duration: 0.5}", "  - send_goal: {id: w, action: walk, goal: {distance: 1}}"), 4,
         "robot panda has no walk action"),
        (GOOD.replace("  - wait: {duration: 0.5}", "  - send_goal: {id: m, action: move_arm, goal: {position: [1, 2]}}"), 4,
         "position must be a list of 3 numbers"),
        (GOOD.replace("  - wait: {duration: 0.5}", "  - cancel: {goal: nope}"), 4, "goal 'nope' is not sent by an earlier step"),
        (GOOD.replace("  - wait: {duration: 0.5}", "  - push: {force: [1, 2], duration: 0.1}"), 4,
         "force must be a list of 3 numbers [N]"),
        (GOOD.replace("  - wait: {duration: 0.5}", "  - push: {force: [1, 2, 3]}"), 4, "missing required key 'duration'"),
        (GOOD.replace("    measure: {object_position: {object: box_0, axis: z}}",
                      "    measure: {duration: {from: nowhere}}"), 7, "unknown mark 'nowhere'"),
        (GOOD.replace("robot: panda", "robot: [panda"), 3, "not valid YAML"),  # where the parser notices
        ("robot: g1\nrobot: panda\n", 2, "duplicate key 'robot'"),
        (GOOD.replace("steps:\n", "steps:\n  - wait: {duration: 1}\n    mark: a\n  - wait: {duration: 1}\n    mark: a\n"), 6,
         "mark 'a' is defined twice"),
    ],
)
def test_errors_name_the_file_and_line_and_what_is_wrong(tmp_path, text, line, message):
    path = write(tmp_path, text)
    with pytest.raises(schema.ScenarioError) as error:
        schema.load(path)
    text_of_error = str(error.value)
    assert text_of_error.startswith(f"{path}:{line}: "), text_of_error
    assert message in text_of_error


def test_the_schema_tables_agree_with_the_robot_models():
    import robot_models

    for name, table in schema.ROBOTS.items():
        robot = robot_models.load(name)
        assert tuple(robot.keyframes) == table["keyframes"]
        assert robot.scene == table["scenes"][0], "the first scene listed is the robot's default"
        for scene in table["scenes"]:
            assert robot_models.load(name, scene).scene == scene
        assert tuple(robot.objects) == table["objects"]
        assert set(robot.end_effector_sites) == set(table["arms"])


def test_a_scenario_is_found_by_name_and_unknown_names_list_the_known_ones():
    assert schema.find("walk_2m").name == "walk_2m.yaml"
    with pytest.raises(schema.ScenarioError, match="known: .*reset_and_stand_g1"):
        schema.find("no_such_scenario")
