"""The shipped Foxglove layout is the generated one, and names only what the live view serves."""
import json
import re
from pathlib import Path

from seapup_live_view.live_view_node import EVENTS_TOPIC, PLOT_SCHEMA, PLOT_TOPIC, SCENE_TOPICS, SERVICES
from seapup_live_view.view_layout import layout_json

SHIPPED = Path(__file__).resolve().parents[1] / "config" / "foxglove_layout.json"


def _walk(node):
    if isinstance(node, dict):
        yield node
        for value in node.values():
            yield from _walk(value)
    elif isinstance(node, list):
        for value in node:
            yield from _walk(value)


def test_the_shipped_layout_is_generated_from_code():
    assert SHIPPED.read_text() == layout_json(), "regenerate: ./seapup view --write-layout " + str(SHIPPED)


def test_every_panel_names_a_channel_field_or_service_the_view_serves():
    panels = [n for n in _walk(json.loads(layout_json())) if n.get("type") == "panel"]
    kinds = {p["panelType"] for p in panels}
    assert kinds == {"ThreeDee", "Plot", "ServiceCall", "Parameters", "Log"}
    three_d = next(p for p in panels if p["panelType"] == "ThreeDee")
    assert set(three_d["config"]["topics"]) == set(SCENE_TOPICS) and three_d["config"]["followTf"] == "base_link"
    plotted = [s["value"] for p in panels if p["panelType"] == "Plot" for s in p["config"]["paths"]]
    assert len(plotted) == 13
    for path in plotted:
        topic, field = re.fullmatch(r"(/\w+)\.(\w+)(?:\[\d\])?", path).groups()
        assert topic == PLOT_TOPIC and field in PLOT_SCHEMA["properties"], path
    called = [p["config"]["serviceName"] for p in panels if "serviceName" in p.get("config", {})]
    assert sorted(called) == sorted(SERVICES)
    (log,) = [p for p in panels if p["panelType"] == "Log"]
    assert log["config"]["topicToRender"] == EVENTS_TOPIC


def test_every_service_button_sends_a_request_the_view_accepts():
    """A button's payload passes the view's own checks (``view_requests``): no shipped button is refused."""
    from seapup_live_view import view_requests
    check = dict(zip(SERVICES, (view_requests.switch_request, view_requests.current_request,
                                view_requests.profile_request, view_requests.goto_request)))
    panels = [n for n in _walk(json.loads(layout_json())) if n.get("type") == "panel"]
    buttons = [p["config"] for p in panels if "serviceName" in p.get("config", {})]
    assert len(buttons) == len(SERVICES)
    for button in buttons:
        check[button["serviceName"]](button["requestPayload"].encode())


def test_a_virtual_input_vehicle_s_layout_labels_its_inputs_and_their_unit():
    """``./seapup view --write-layout FILE --vehicle bluerov2_heavy``: the inputs' plot names surge, sway, heave
    and yaw in percent of full scale against 100 %, the fields the view publishes for that vehicle; the 3D
    panel names the vehicle."""
    document = json.loads(layout_json("bluerov2_heavy"))
    panels = [n for n in _walk(document) if n.get("type") == "panel"]
    (inputs,) = [p for p in panels if p["panelType"] == "Plot" and "inputs" in p["title"]]
    assert inputs["title"] == "virtual inputs (% of full scale) and the 100 % limit"
    labels = [s["label"] for s in inputs["config"]["paths"]]
    assert labels == ["surge", "sway", "heave", "yaw", "+limit"]
    assert [s["value"] for s in inputs["config"]["paths"]][-1] == f"{PLOT_TOPIC}.input_limit"
    (three_d,) = [p for p in panels if p["panelType"] == "ThreeDee"]
    assert three_d["title"].startswith("bluerov2_heavy")
    seapup = json.loads(layout_json())
    assert "blade pitches (deg) and the 35 deg limit" in json.dumps(seapup)
