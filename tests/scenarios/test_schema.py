"""Scenario files: every shipped one validates; bad ones are reported with file, line and what is wrong."""

from __future__ import annotations

import pathlib
import textwrap

import numpy as np
import pytest

import robot_models
from sim_client.scenario.model import schema, steps

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
    assert scenario.robot in robot_models.ROBOT_NAMES


def test_a_good_file_loads_into_typed_values(tmp_path):
    scenario = schema.load(write(tmp_path, GOOD))
    assert scenario.robot == "panda" and scenario.keyframe == "home" and scenario.rtf == 0.0
    assert isinstance(scenario.steps[0], steps.WaitStep) and scenario.steps[0].duration == 0.5
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
        (GOOD.replace("robot: panda", "robot: panda\nscene: course"), 3, "unknown scene 'course' for panda; scenes: table"),
        (GOOD.replace("    measure: {object_position: {object: box_0, axis: z}}",
                      "    measure: {base_displacement: {}}"), 7, "needs a walking robot; panda has a fixed base"),
        (GOOD.replace("  - wait: {duration: 0.5}", "  - cmd_vel: {vx: 0.1, duration: 1}"), 4, "robot panda has none"),
        (GOOD.replace("  - wait: {duration: 0.5}",
                      "  - send_goal: {id: p, action: pick_place, goal: {object: box_0, place: [0, 0, 0]}}")
         + "  - name: no path\n    outcome: {goal: p, error_code: NO_VALID_PATH}\n", 10,
         "pick_place has no error code 'NO_VALID_PATH'; it has: SUCCESS"),
        (GOOD.replace("    measure: {object_position: {object: box_0, axis: z}}", "    measure: {feedback: {field: x}}"), 7,
         "measure feedback: missing required key 'goal'"),
        (GOOD.replace("  - wait: {duration: 0.5}", "  - wait: {durration: 0.5}"), 4,
         "unknown key 'durration'; allowed: duration, goal, timeout, until"),
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


def test_a_scene_s_objects_may_be_measured(tmp_path):
    text = GOOD.replace("robot: panda", "robot: g1\nscene: tables").replace("box_0", "can")
    assert schema.load(write(tmp_path, text)).scene == "tables"
    with pytest.raises(schema.ScenarioError, match="no object 'can'"):
        schema.load(write(tmp_path, GOOD.replace("robot: panda", "robot: g1").replace("box_0", "can")))


def test_robot_facts_and_error_codes_come_from_their_sources_not_copies():
    from sim_client.scenario.model import actions, robots
    from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, Walk

    for name in robot_models.ROBOT_NAMES:
        spec, facts = robot_models.load(name), robots.robot_facts(name)
        assert facts.keyframes == tuple(spec.keyframes) and facts.objects == tuple(spec.objects)
        assert facts.default_scene == spec.scene and facts.arms == tuple(spec.end_effector_sites)
    assert actions.actions_of(robots.robot_facts("g1")) == ("walk", "navigate", "move_arm")
    assert actions.actions_of(robots.robot_facts("panda")) == ("move_arm", "pick_place")
    tables = robots.robot_facts("g1", "tables")
    assert tables.objects == robot_models.load("g1", "tables").objects and tables.default_scene == "open"
    assert actions.actions_of(tables) == ("walk", "navigate", "move_arm", "pick_place"), "objects and palms: a fetch"
    for action, action_type in (("walk", Walk), ("navigate", NavigateToPose), ("move_arm", MoveArm), ("pick_place", PickPlace)):
        names = actions.ACTIONS[action].error_names
        assert names[0] == "SUCCESS" and "INVALID_GOAL" in names
        assert all(getattr(action_type.Result, n) == i for i, n in enumerate(names)), "error codes in value order"
    assert "GOAL_IN_OBSTACLE" in actions.ACTIONS["navigate"].error_names
    assert "PLACEMENT_FAILED" in actions.ACTIONS["pick_place"].error_names and "FELL" in actions.ACTIONS["pick_place"].error_names


EVERY_STEP = """\
name: every_step
robot: g1
steps:
  - reset: {keyframe: stand}
  - send_goal: {id: w, action: walk, goal: {distance: 1.0}, wait: false}
  - wait: {duration: 0.5}
  - wait: {until: {measure: {feedback: {goal: w, field: distance_walked}}, gte: 0.2}, timeout: 5}
  - cancel: {goal: w}
  - wait: {goal: w}
  - set_param: {node: locomotion, name: walking_speed, value: 0.4}
  - cmd_vel: {vx: 0.2, duration: 1.0}
  - push: {force: [10, 0, 0], duration: 0.1}
expect:
  - name: walk canceled
    outcome: {goal: w, status: CANCELED}
"""


class StepRecorder:
    """A run (``steps.StepRunner``) that notes what each step asks of it."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def reset(self, keyframe):
        self.calls.append(("reset", keyframe))

    def wait_sim(self, duration):
        self.calls.append(("wait_sim", duration))

    def wait_until(self, predicate, timeout, what, line, checks_measures=True):
        self.calls.append(("wait_until", predicate(), timeout, what))

    def condition_holds(self, condition):
        return condition.measure.kind == "feedback"

    def goal_done(self, goal_id):
        return goal_id == "w"

    def cancel_goal(self, goal_id):
        self.calls.append(("cancel_goal", goal_id))

    def send_goal(self, step):
        self.calls.append(("send_goal", step.id))

    def set_param(self, step):
        self.calls.append(("set_param", step.name, step.value))

    def push(self, step):
        self.calls.append(("push", step.force))

    def drive(self, step):
        self.calls.append(("drive", step.vx, step.duration))


def test_every_step_kind_carries_the_function_that_runs_it_and_every_kind_is_described():
    from sim_client.scenario.model import measures

    scenario = schema.parse(EVERY_STEP)
    assert {steps.step_kind(step).name for step in scenario.steps} == set(steps.STEPS)
    run = StepRecorder()
    for step in scenario.steps:
        steps.step_kind(step).run(run, step)
    assert run.calls == [
        ("reset", "stand"), ("send_goal", "w"), ("wait_sim", 0.5),
        ("wait_until", True, 5.0, "until feedback(goal=w, field=distance_walked, reduce=last) >= 0.2"),
        ("cancel_goal", "w"), ("wait_until", True, 60.0, "for goal w to end"), ("set_param", "walking_speed", 0.4),
        ("drive", 0.2, 1.0), ("push", (10.0, 0.0, 0.0)),
    ]
    for kind in steps.STEPS.values():
        assert steps.step_kind(kind.type(line=1, mark=None)) is kind
    for kind in measures.MEASURES.values():
        assert kind.about and callable(kind.evaluate), kind.name
    for path in SHIPPED:
        for step in schema.load(path).steps:
            assert steps.describe_step(step)


def test_a_measure_evaluates_on_recorded_data_alone():
    from sim_client.scenario.model import fields, measures
    from sim_client.scenario.model.series import Series

    class Recorded:
        def mark_time(self, name, default):
            marks = {"start": 0.0, "end": 2.0, "half": 1.0}
            if (name or default) not in marks:
                raise KeyError(f"mark {name or default!r} was not reached")
            return marks[name or default]

        def odom_series(self):
            t = np.array([0.0, 1.0, 2.0])
            return Series(t, np.array([[0.0, 0.0, 0.7, 0.0], [0.3, 0.4, 0.6, 0.1], [1.0, 0.0, 0.75, 0.2]]))

    recorded = Recorded()
    ctx = fields.Ctx("<test>")
    measure = measures.parse_measure(ctx, {"base_displacement": {"to": "half"}}, 1)
    assert measure.evaluate(recorded) == pytest.approx(0.5)
    assert measures.parse_measure(ctx, "base_height_min", 1).evaluate(recorded) == pytest.approx(0.6)
    assert measures.parse_measure(ctx, "mean_speed", 1).evaluate(recorded) == pytest.approx(0.5)
    yaw = measures.parse_measure(ctx, {"base_position": {"axis": "yaw", "at": "half"}}, 1)
    assert yaw.evaluate(recorded) == pytest.approx(0.1) and yaw.unit == "rad"
    with pytest.raises(KeyError, match="not reached"):
        measures.parse_measure(ctx, {"duration": {"from": "later"}}, 1).evaluate(recorded)


def test_a_scenario_is_found_by_name_and_unknown_names_list_the_known_ones():
    assert schema.find("walk_2m").name == "walk_2m.yaml"
    with pytest.raises(schema.ScenarioError, match=r"known: .*reset_and_stand_g1"):
        schema.find("no_such_scenario")


def test_every_registered_kind_is_documented_and_listed(capsys):
    from sim_client.scenario import cli
    from sim_client.scenario.model import actions, measures

    readme = (schema.SCENARIO_DIR / "README.md").read_text()
    assert cli.main(["kinds"]) == 0
    listed = capsys.readouterr().out
    for name in (*steps.STEPS, *measures.MEASURES, *actions.ACTIONS):
        assert name in readme, f"{name} is not in scenarios/README.md"
        assert f"  {name} " in listed, f"{name} is not listed by `scenario kinds`"
