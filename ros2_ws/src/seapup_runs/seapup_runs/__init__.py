"""seapup_runs: runs as data -- a run specification in, a run result out (no ROS).

- :mod:`seapup_runs.spec`: :class:`~seapup_runs.spec.RunSpec` and its parts (reference profile,
  events, the self-test that designs a controller);
- :mod:`seapup_runs.result`: :class:`~seapup_runs.result.RunResult`, the one JSON shape of a run;
- :mod:`seapup_runs.runner`: :func:`~seapup_runs.runner.run`, the in-process runner;
- :mod:`seapup_runs.run_graph`: the ROS graph of a spec as data (started by ``seapup_bringup.graph.graph_runner``);
- :mod:`seapup_runs.metrics`: named metrics of a result;
- :mod:`seapup_runs.scenarios`: the thesis's closed-loop cases as specs;
- :mod:`seapup_runs.self_test_flight`: the self-test flown in process.
"""
