"""The SIL harness and the graph runners: a launch document started as processes in a private domain, held and
stepped in lockstep (:mod:`~seapup_bringup.graph.sil`, its probe, pacing and readiness), and what is flown on it
-- a run spec (:mod:`~seapup_bringup.graph.graph_runner`), a mission (:mod:`~seapup_bringup.graph.mission_graph`),
the open-loop run and the graph benchmarks."""
