"""Every declared parameter of every seapup node has its allowed values in its descriptor and is checked on set.

Truth: the nodes themselves. Each node executable installed as a console script (the packages' own entry
points: a new node cannot be forgotten) is constructed in this process, once per kind (the velocity controller
once per registered law), and its declared parameters are read back from rclpy: every number and number array
has a range, every string and string array its allowed values (``additional_constraints``), and every number
that may be set at run time refuses NaN and a value beyond its range, unchanged. No process is started.
"""
import math
from importlib import metadata

import pytest
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter

NUMERIC = {ParameterType.PARAMETER_INTEGER, ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_INTEGER_ARRAY,
           ParameterType.PARAMETER_DOUBLE_ARRAY}
TEXT = {ParameterType.PARAMETER_STRING, ParameterType.PARAMETER_STRING_ARRAY}
IMPLICIT = {"use_sim_time", "start_type_description_service"}   # rclpy's own


def _node_modules() -> set[str]:
    return {e.value.split(":")[0] for e in metadata.entry_points(group="console_scripts")
            if e.value.startswith("seapup") and e.value.split(":")[0].endswith("_node")}


def _kinds(tmp_path):
    """(label, module, class name, parameter overrides) of every node kind."""
    from seapup_common.controllers import available_controllers
    kinds = [("simulator", "seapup_sim.simulator_node", "SimulatorNode", {}),
             ("navigator", "seapup_control.navigator_node", "NavigatorNode", {}),
             ("controller_manager", "seapup_control.controller_manager_node", "ControllerManagerNode", {}),
             ("position_controller", "seapup_control.position_controller_node", "PositionControllerNode", {}),
             ("task_controller", "seapup_control.task_controller_node", "TaskControllerNode", {}),
             ("self_test", "seapup_control.self_test_node", "SelfTestNode", {"result_dir": str(tmp_path)}),
             ("identifier", "seapup_ident.identifier_node", "IdentifierNode", {"bag_path": "none"}),
             ("recorder", "seapup_common.recorder_node", "RecorderNode", {"bag_path": str(tmp_path / "bag")}),
             ("open_loop", "seapup_control.open_loop_node", "OpenLoopNode", {}),
             ("reference_schedule", "seapup_control.reference_schedule_node", "ReferenceScheduleNode", {}),
             ("teleop", "seapup_control.teleop_node", "TeleopNode", {}),
             ("live_view", "seapup_live_view.live_view_node", "LiveViewNode", {"port": 0})]
    kinds += [(f"velocity_controller[{law}]", "seapup_control.velocity_controller_node", "VelocityControllerNode",
               {"controller_type": law}) for law in available_controllers()]
    return kinds


def test_the_table_names_every_node_executable(tmp_path):
    assert _node_modules() == {module for _, module, _, _ in _kinds(tmp_path)}


def _value(node, name) -> list:
    """The parameter's value as a list (an array declared empty is uninitialised in rclpy: [])."""
    from rclpy.exceptions import ParameterUninitializedException
    try:
        value = node.get_parameter(name).value
    except ParameterUninitializedException:
        return []
    return list(value) if isinstance(value, (list, tuple)) or hasattr(value, "tolist") else [value]


def _problems(node, label) -> list[str]:
    problems = []
    names = sorted(set(node._parameters) - IMPLICIT)
    for name, descriptor in zip(names, node.describe_parameters(names)):
        ranged = list(descriptor.floating_point_range) + list(descriptor.integer_range)
        if descriptor.type in NUMERIC:
            if not ranged:
                problems.append(f"{label}: {name} has no range")
                continue
            lo, hi = ranged[0].from_value, ranged[0].to_value
            if not (math.isfinite(lo) and math.isfinite(hi)):
                problems.append(f"{label}: {name} range [{lo}, {hi}] is not finite")
            if descriptor.read_only:
                continue
            before = _value(node, name)
            is_int = descriptor.type in (ParameterType.PARAMETER_INTEGER, ParameterType.PARAMETER_INTEGER_ARRAY)
            bad = [int(hi) + 1] if is_int else [math.nan, math.inf, hi + abs(hi) + 1.0]
            for value in bad:
                if descriptor.type in (ParameterType.PARAMETER_DOUBLE_ARRAY, ParameterType.PARAMETER_INTEGER_ARRAY):
                    value = [value]
                result = node.set_parameters([Parameter(name, value=value)])[0]
                if result.successful or _value(node, name) != before:
                    problems.append(f"{label}: {name} = {value!r} accepted")
                elif "\n" in result.reason or not result.reason:
                    problems.append(f"{label}: {name} refusal is not one line: {result.reason!r}")
        elif descriptor.type in TEXT and not descriptor.additional_constraints:
            problems.append(f"{label}: string {name} states no allowed values")
    return problems


def test_every_parameter_of_every_node_is_ranged_and_checked_on_set(ros_context, tmp_path):
    import importlib
    problems = []
    for label, module, cls, overrides in _kinds(tmp_path):
        node = getattr(importlib.import_module(module), cls)(
            context=ros_context, parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        try:
            problems += _problems(node, label)
        finally:
            node.destroy_node()
    assert problems == []


def test_every_registered_law_declares_a_range_with_its_source_for_every_number():
    """Pure: the laws' own declarations (``Ranged`` next to each default)."""
    from seapup_common.controllers import available_controllers, controller_type
    missing = []
    for name in available_controllers():
        kind = controller_type(name)
        for parameter, default in kind.parameters.items():
            numeric = isinstance(default, (int, float, list, tuple)) and not isinstance(default, bool)
            if numeric and not (parameter in kind.ranges and kind.sources.get(parameter)):
                missing.append(f"{name}.{parameter}")
    assert missing == []


def test_a_mistyped_parameter_is_named_with_the_nearest_declared_one(ros_context):
    """rclpy said ``Invalid access to undeclared parameter(s): []`` (its generator spent by ``any``)."""
    from seapup_common.ros.node import refuse_unknown_overrides
    from seapup_control.navigator_node import NavigatorNode
    node = NavigatorNode(context=ros_context)
    refuse_unknown_overrides(node)   # as run_node does for every node
    with pytest.raises(Exception) as refused:
        node.set_parameters([Parameter("max_sped", value=2.0)])
    text = str(refused.value)
    assert "'max_sped'" in text and "'max_speed'" in text and "\n" not in text, text
    assert node.get_parameter("max_speed").value == 5.0
    # through the parameter service (what ./seapup param set calls): the same reason, one line
    from rcl_interfaces.msg import Parameter as ParameterMsg
    from rcl_interfaces.srv import SetParameters
    request = SetParameters.Request(parameters=[ParameterMsg(name="max_sped",
                                                             value=Parameter("x", value=2.0).get_parameter_value())])
    response = node._parameter_service._set_parameters_callback(request, SetParameters.Response())
    assert not response.results[0].successful and "'max_speed'" in response.results[0].reason
