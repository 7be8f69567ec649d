"""The scenario model: a scenario file read into typed values, and every kind of step, measure and action it may use.

- :mod:`.schema`: a file into a :class:`~.schema.Scenario` (robot, scene, steps, expectations), cross-checked;
- :mod:`.steps`, :mod:`.measures`, :mod:`.conditions`, :mod:`.actions`: the kinds a file may name, each defined once;
- :mod:`.fields`: YAML with line numbers and typed key access, for errors as ``file:line: what``;
- :mod:`.robots`: what a file may ask of a robot, read from ``robot_models``;
- :mod:`.series`: recorded state over sim time, what measures evaluate.

Nothing here talks to ROS: a run (:mod:`sim_client.scenario.running`) carries the model out.
"""
