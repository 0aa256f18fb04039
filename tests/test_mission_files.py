"""``./seapup demo --mission FILE``: a user's mission file is checked before any graph starts."""
import pytest
import yaml

from seapup_bringup.verbs import demo
from seapup_bringup.graph import mission_graph


def write(tmp_path, document) -> str:
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(document))
    return str(path)


def shipped() -> dict:
    return yaml.safe_load(mission_graph.mission_path().read_text())


def test_the_shipped_mission_passes_its_graphs_arguments():
    config = mission_graph.mission_config()
    assert config["mission"] == shipped()["mission"] and config["graph"] == shipped()["graph"]


@pytest.mark.parametrize("change, reason", [
    (lambda d: d["graph"].update(sensor="ideal"), "graph argument 'sensor' is not one of seapup_bringup "
                                                  "hierarchy.launch.yaml's: "),
    (lambda d: d["mission"][1]["goal"].update(duration="40"), "mission leg 2 ('hover + swap', hover) goal "
                                                              "duration must be a number, got '40'"),
    (lambda d: d["mission"][1]["switch"]["request"].update(activate=["mfol_sheduled"]),
     "leg 'hover + swap' names 'mfol_sheduled', not a velocity controller of seapup_bringup hierarchy.launch.yaml"),
    (lambda d: d["mission"][0].update(activate="pid"), "leg 'self-test' names 'pid', not a velocity controller"),
    (lambda d: d["mission"][6]["switch"].update(deactivate=["gmv", "lqr"]), "leg 'fouled thruster' names 'lqr'"),
])
def test_a_mission_that_cannot_be_flown_stops_the_demo_in_one_line_before_anything_starts(
        tmp_path, capsys, change, reason):
    document = shipped()
    change(document)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        demo.main(["--mission", write(tmp_path, document), "--out", str(out)])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("./seapup demo: error: ") and "mine.yaml" in err[-1] and reason in err[-1], err[-1]
    assert "Traceback" not in "\n".join(err)
    assert not out.exists()   # nothing flown, nothing written
