"""A control law from another package, registered by an entry point alone, flies everywhere a law flies:
the in-process runner, the graph runner (the generic velocity_controller node) and a runtime swap by the
controller manager -- with no edit of seapup.

The toy law is a plain proportional loop about the hover setting, so what it commands is known in
closed form from what it measured: ``hover + K (r - y)`` with surge on the main thrusters and heave
on the vectored ones.
"""
import textwrap

import numpy as np
import pytest
import yaml

from seapup_common.controllers import ControllerSpec
from seapup_runs.runner import design, run, start_pitch
from seapup_runs.spec import ReferenceSteps, RunSpec, SelfTestDesign

TOY = '''
import numpy as np
from seapup_common.contract import Command
from seapup_common.controllers import ControllerType


class Proportional:
    def __init__(self, hover, k_surge, k_heave, sample_period):
        self.hover, self.k = np.array(hover), (k_surge, k_heave)
        self.sample_period = sample_period
        self.applied_seen = 0

    def reset(self, applied):
        pass

    def applied(self, t, command):
        self.applied_seen += 1

    def update(self, t, measurement, reference):
        error = reference.velocity - measurement.body_velocity()
        step = np.array([self.k[0] * error[0]] * 2 + [self.k[1] * error[2]] * 2)
        return Command(np.clip(self.hover + step, -0.6, 0.6), stamp=t)

    def diagnostics(self):
        return {"applied_seen": self.applied_seen}


TOY = ControllerType("toy_proportional",
                     lambda p, d, T: Proportional(p["hover"], p["k_surge"], p["k_heave"], T),
                     {"hover": [0.0, 0.0, 0.0, 0.0], "k_surge": 1.0, "k_heave": 1.0},
                     "a proportional loop about the hover setting (test package)")
'''


@pytest.fixture
def toy_package(tmp_path, monkeypatch):
    """Installs the toy law as a distribution of its own: a module and an entry point, on PYTHONPATH."""
    root = tmp_path / "site"
    root.mkdir()
    (root / "toy_seapup_law.py").write_text(TOY)
    info = root / "toy_seapup_law-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: toy-seapup-law\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(textwrap.dedent("""\
        [seapup.velocity_controllers]
        toy_proportional = toy_seapup_law:TOY
        """))
    monkeypatch.syspath_prepend(str(root))
    monkeypatch.setenv("PYTHONPATH", f"{root}:" + __import__("os").environ.get("PYTHONPATH", ""))
    yield ControllerSpec("toy_proportional", {"hover": start_pitch(RunSpec()).tolist(), "k_surge": 1.5,
                                              "k_heave": 2.0})
    from seapup_common import controllers
    controllers._REGISTERED.pop("toy_proportional", None)


def _spec(controller) -> RunSpec:
    return RunSpec(name="toy", duration=12.0, controller=controller, environment={"sensors": "ideal"},
                   reference=ReferenceSteps.from_list([[0.0, 0.2, 0.0, 0.0, 0.0], [6.0, 0.1, 0.0, 0.05, 0.0]]),
                   metrics=("step_response",))


def _expected(series, k_surge=1.5, k_heave=2.0):
    """What the toy law commands from what it measured and the reference it was given."""
    hover = start_pitch(RunSpec())
    e_u = series.reference["u"] - series.measured["u"]
    e_w = series.reference["w"] - series.measured["w"]
    step = np.column_stack([k_surge * e_u, k_surge * e_u, k_heave * e_w, k_heave * e_w])
    return np.clip(hover + step, -0.6, 0.6)


@pytest.mark.graph
def test_a_registered_law_flies_in_process_and_through_the_graph_alike(toy_package, tmp_path):
    from seapup_bringup.graph.graph_runner import run_on_graph
    from tests.test_scenarios import assert_same_run

    spec = _spec(toy_package)
    local = run(spec)
    np.testing.assert_allclose(local.series.command[:-1], _expected(local.series)[:-1], atol=1e-12)
    assert 0.05 < local.series.truth["u"][30] < 0.2     # it really flies: surge builds up under the P loop
    graph = run_on_graph(spec, out_dir=tmp_path / "graph")
    assert_same_run(graph, local)


@pytest.mark.graph
def test_the_controller_manager_swaps_to_a_registered_law_at_runtime(toy_package, tmp_path):
    """simulator + mfol and toy velocity_controller nodes under the controller manager: a switch request
    hands the thrusters to the toy law, which then commands exactly its law."""
    from seapup_bringup.graph.sil import SilGraph

    mfol = design(RunSpec(controller=ControllerSpec("mfol", {"schedule": False}), design=SelfTestDesign()))
    controller_file = tmp_path / "mfol.yaml"
    controller_file.write_text(yaml.safe_dump(dict(mfol.controller.document)))
    toy = dict(toy_package.parameters)
    common = {"lockstep": True, "applied_wait": 0.25}
    from seapup_common.ros.launch_graph import launch_document
    graph = launch_document([
        {"package": "seapup_sim", "executable": "simulator", "required": True,
         # who hears the first sample (the probe, both controllers, the manager) the harness's roster derives
         "parameters": [{"mode": "lockstep", "start_depth": 30.0, "lockstep_timeout": 10.0,
                         "environment": {"sensors": "ideal"}}]},
        {"package": "seapup_control", "executable": "velocity_controller", "name": "mfol_fixed",
         "parameters": [{"controller_type": "mfol", "controller_file": str(controller_file), "schedule": False,
                         **common}],
         "remappings": {"thrusters/command": "/seapup/mfol_fixed/thrusters/command"}},
        {"package": "seapup_control", "executable": "velocity_controller", "name": "toy",
         "parameters": [{"controller_type": "toy_proportional", "sample_period": 0.2, **toy, **common}],
         "remappings": {"thrusters/command": "/seapup/toy/thrusters/command"}},
        {"package": "seapup_control", "executable": "controller_manager", "required": True,
         "parameters": [{"controllers": ["mfol_fixed", "toy"], "types": ["mfol", "toy_proportional"],
                         "fallback": "mfol_fixed", "initial": "mfol_fixed", "command_deadline": 0.5}]}])
    path = tmp_path / "swap.launch.yaml"
    path.write_text(yaml.safe_dump(graph, sort_keys=False))
    with SilGraph(path, out_dir=tmp_path / "logs", ready_status=None, instruments=True) as sil:
        sil.run_for(4.0)
        answer = sil.switch(activate=["toy"], deactivate=["mfol_fixed"])
        assert answer.ok, answer.message
        switched = sil.t
        sil.run_for(4.0)
        logs = sil.logs()
        # hostile switches (regressions): a timeout too short to do anything is refused and changes
        # nothing; a switch that plans but fails after a successful one (its controller is gone) rolls
        # back and the manager lives on (it died on its log line: "Logger severity cannot be changed")
        for timeout in (1e-9, -1.0, float("nan"), 1e300):
            answer = sil.call("/seapup/controller_manager/switch_controller", "seapup_msgs/srv/SwitchController",
                              {"activate_controllers": ["mfol_fixed"], "deactivate_controllers": ["toy"],
                               "strictness": 2, "timeout": timeout})
            assert not answer.ok and "refused" in answer.message, (timeout, answer.message)
        sil.kill("mfol_fixed")
        answer = sil.switch(activate=["mfol_fixed"], deactivate=["toy"], timeout=0.5)
        assert not answer.ok and "rolled back to toy" in answer.message, answer.message
        # (listing asks each controller its state: the dead one's query times out, slowly on a loaded machine)
        listing = sil.call("/seapup/controller_manager/list_controllers", "seapup_msgs/srv/ListControllers",
                           timeout=60.0)
        assert listing.active == "toy" and sil.processes["controller_manager"].running
    after = logs["command_t"] > switched + 0.5
    assert after.sum() >= 15
    stamps = logs["command_t"][after]
    measured = {round(t, 6): v for t, v in zip(logs["velocity_t"], logs["velocity"])}
    hover = np.array(toy["hover"])
    for t, command in zip(stamps, logs["command"][after]):
        u, w = measured[round(t, 6)][0], measured[round(t, 6)][2]
        expected = np.clip(hover + np.array([-1.5 * u, -1.5 * u, -2.0 * w, -2.0 * w]), -0.6, 0.6)
        np.testing.assert_allclose(command, expected, atol=1e-12)   # the toy's law, forwarded by the manager
