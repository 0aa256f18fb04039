"""An example SIL test to copy: fly the whole hierarchy in separate processes and check the vehicle.

To test your own velocity controller: add it to a copy of
``seapup_bringup/launch/hierarchy.launch.yaml`` as a lifecycle node publishing on
``/seapup/<name>/thrusters/command``, list it under the controller manager's
``controllers``, pass the copy as ``SilGraph(graph=path, ...)`` and switch to
it with ``sil.switch(activate=[name], deactivate=["mfol_fixed"])``.
"""
import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.graph


@pytest.fixture(scope="session")
def controller_file(tmp_path_factory):
    """The self-test's result for the baseline Seapup (flown in process: 0 and 0.7 m/s)."""
    from seapup_runs.self_test_flight import fly_self_test
    from seapup_control.self_test import result_document
    path = tmp_path_factory.mktemp("controller") / "controller.yaml"
    path.write_text(yaml.safe_dump(result_document(fly_self_test("baseline", {"operating_points": [0.0, 0.7]}).test)))
    return path


def test_goto_arrives_within_tolerance(controller_file, tmp_path):
    from seapup_bringup.graph.sil import SilGraph

    with SilGraph(arguments={"controller_file": controller_file}, out_dir=tmp_path) as sil:
        start = sil.logs()["truth_position"][-1]
        target = start + np.array([8.0, 6.0, 1.0])
        result = sil.goal("goto", x=target[0], y=target[1], z=target[2], yaw=np.pi / 2, tolerance=0.5)
        logs = sil.logs()
    assert result["status"] == "succeeded", result
    assert result["distance"] <= 0.5
    # the truth, not only the estimate: where the vehicle really is at the end
    miss = np.linalg.norm(logs["truth_position"][-1] - target)
    assert miss < 1.0, f"truly {miss:.2f} m from the target (estimate said {result['distance']:.2f} m)"
    assert abs(np.angle(np.exp(1j * (logs["truth_attitude"][-1, 2] - np.pi / 2)))) < np.radians(5)
