"""Running scenarios: bring up the nodes, drive sim time, carry out the steps, judge, report; sweeps over many runs.

- :mod:`.runner`: :func:`~.runner.run`, one scenario from bring-up to the files it leaves;
- :mod:`.scenario_run`: :class:`~.scenario_run.ScenarioRun`, the run against nodes reachable through a session;
- :mod:`.sim_time`: lock-stepped or free-running sim time;
- :mod:`.report`: verdicts, the result and ``report.json``;
- :mod:`.progress`: the status line;
- :mod:`.sweep`: one scenario over a grid of values and seeds, on Ray.
"""
