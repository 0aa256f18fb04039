"""The live view's Foxglove layout, generated from code with the SDK's layout API (``foxglove.layouts``).

``./seapup view --write-layout FILE`` writes it; the shipped copy is ``config/foxglove_layout.json`` (a test keeps
it equal to :func:`layout`). Import it in Foxglove (Layouts -> Import from file): a 3D panel in ``odom``
(ENU, up is up) following the vehicle, with its three scene topics; plots of the body velocities against
the velocity controllers' references and of the inputs applied against their limit (the Seapup's blade
pitches in degrees against +-35 deg; ``--vehicle bluerov2_heavy``: its virtual surge, sway, heave and yaw in
percent of full scale, labelled so); the service buttons. The paths name
:data:`seapup_live_view.live_view_node.PLOT_SCHEMA`'s fields.
"""
from __future__ import annotations

import json

__all__ = ["layout", "layout_json", "VELOCITY_AXES"]

#: The /plot arrays' components (velocity and reference: u, v, w [m/s], r [rad/s]).
VELOCITY_AXES = ("u", "v", "w", "r")


def layout(vehicle: str = "baseline"):
    """The layout object (``foxglove.layouts.Layout``) for a vehicle configuration (its inputs' names, unit and
    limit label the inputs' plot)."""
    from foxglove import layouts as L
    from seapup_live_view.live_view_node import EVENTS_TOPIC, PLOT_TOPIC, SCENE_TOPICS, SERVICES
    from seapup_live_view.view_scene import plot_inputs, vehicle_shape
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config

    model = VehicleModel(load_vehicle_config(vehicle))
    shape = vehicle_shape(model)
    limit = plot_inputs(shape, [0.0] * 4)["input_limit"]

    scene = {topic: L.BaseRendererSceneUpdateTopicSettings(visible=True) for topic in SCENE_TOPICS}
    name = "Seapup" if shape.input_unit == "deg" else model.config_name   # blade-pitch inputs: the Seapup's
    three_d = L.ThreeDeePanel(title=f"{name} (odom, ENU: up is up)", config=L.ThreeDeeConfig(
        follow_tf="base_link", follow_mode="follow-position", topics=scene))
    colours = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728")
    velocity_series = []
    for i, axis in enumerate(VELOCITY_AXES):
        velocity_series += [
            L.PlotSeries(value=f"{PLOT_TOPIC}.velocity[{i}]", label=f"{axis} true", color=colours[i]),
            L.PlotSeries(value=f"{PLOT_TOPIC}.reference[{i}]", label=f"{axis} reference", color=colours[i],
                         line_style="dashed")]
    velocities = L.PlotPanel(title="body velocities vs references (m/s, rad/s)",
                             config=L.PlotConfig(paths=velocity_series, show_legend=True))
    input_series = [L.PlotSeries(value=f"{PLOT_TOPIC}.inputs[{j}]", label=name.replace("_", " "), color=colours[j])
                    for j, name in enumerate(shape.input_names)]
    input_series += [L.PlotSeries(value=f"{PLOT_TOPIC}.input_limit", label="+limit", color="#888888", line_style="dotted")]
    what = ("blade pitches (deg)" if shape.input_unit == "deg" else "virtual inputs (% of full scale)")
    pitches = L.PlotPanel(title=f"{what} and the {limit:g} {shape.input_unit} limit",
                          config=L.PlotConfig(paths=input_series, show_legend=True))
    switch = L.ServiceCallPanel(title="switch controller", config=L.ServiceCallConfig(
        service_name=SERVICES[0], request_payload=json.dumps({"activate": "gmv"}), button_text="switch"))
    current = L.ServiceCallPanel(title="set current", config=L.ServiceCallConfig(
        service_name=SERVICES[1], request_payload=json.dumps(
            {"enabled": True, "mean_speed": 0.26, "mean_direction": 0.0, "speed_std": 0.0, "direction_std": 0.0,
             "break_time": 0.0}), button_text="set"))
    profile = L.ServiceCallPanel(title="sensor profile", config=L.ServiceCallConfig(
        service_name=SERVICES[2], request_payload=json.dumps({"name": "haslar"}), button_text="set"))
    goto = L.ServiceCallPanel(title="goto", config=L.ServiceCallConfig(
        service_name=SERVICES[3], request_payload=json.dumps({"x": 10.0, "y": 0.0, "z": 30.0, "yaw": 0.0}),
        button_text="go"))
    right = L.SplitContainer(direction="column", items=[
        L.SplitItem(proportion=2, content=velocities), L.SplitItem(proportion=2, content=pitches),
        L.SplitItem(proportion=1, content=L.SplitContainer(direction="row", items=[
            L.SplitItem(content=switch), L.SplitItem(content=current), L.SplitItem(content=profile),
            L.SplitItem(content=goto)])),
        L.SplitItem(proportion=1, content=L.SplitContainer(direction="row", items=[
            L.SplitItem(content=L.ParametersPanel(title="pace and controller")),
            L.SplitItem(content=L.LogPanel(title="switches and refusals", config=L.LogConfig(
                topic_to_render=EVENTS_TOPIC)))]))])
    return L.Layout(content=L.SplitContainer(direction="row", items=[
        L.SplitItem(proportion=3, content=three_d), L.SplitItem(proportion=2, content=right)]))


def layout_json(vehicle: str = "baseline") -> str:
    """The layout as the JSON a Foxglove import takes (indented, stable: the shipped file is the Seapup's)."""
    return json.dumps(json.loads(layout(vehicle).to_json()), indent=2, sort_keys=True) + "\n"
