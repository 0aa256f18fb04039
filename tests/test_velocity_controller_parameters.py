"""A self-tuner's law parameters are refused on set through ROS when not finite or out of range (issue 40: 21
such values were accepted by a running hierarchy), each with a one-line reason naming the range, and the
value does not change. One process: a velocity_controller flying ``explicit`` (not configured: its parameters
are what is at stake)."""
import math

from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor

from seapup_common.ros.graph import call_idempotent

NODE = "/seapup/explicit"
#: The values of the issue's report and their kin: every number of the law, non-finite and absurd.
BAD = [("blade_pitch_limit", -math.inf), ("blade_pitch_limit", 1e300), ("blade_pitch_limit", math.nan),
       ("blade_pitch_limit", 0.0), ("excitation_deg", math.nan), ("excitation_deg", -1.0),
       ("excitation_deg", math.inf), ("forgetting", math.inf), ("forgetting", math.nan), ("forgetting", 0.0),
       ("forgetting", 1.5), ("max_pole", math.nan), ("max_pole", -math.inf), ("max_pole", 0.5),
       ("p0", math.nan), ("p0", -1.0), ("p0", 1e300), ("max_trace_growth", math.inf), ("max_trace_growth", 0.0),
       ("min_rcond", math.nan), ("min_rcond", 2.0), ("commissioning_samples", 0),
       ("commissioning_samples", 10**12), ("set_point_band", [0.005, math.nan, 0.005, 0.005]),
       ("set_point_band", [0.005, -1.0, 0.005, 0.005]), ("set_point_band", [math.inf] * 4)]


def _value(value) -> ParameterValue:
    if isinstance(value, list):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=value)
    if isinstance(value, int):
        return ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)


def _plain(value: ParameterValue):
    return {ParameterType.PARAMETER_DOUBLE: lambda: value.double_value,
            ParameterType.PARAMETER_INTEGER: lambda: value.integer_value,
            ParameterType.PARAMETER_DOUBLE_ARRAY: lambda: list(value.double_array_value)}[value.type]()


def test_bad_law_parameters_are_refused_on_set_and_change_nothing(ros_context, node_process):
    import rclpy
    controller = node_process(package="seapup_control", executable="velocity_controller",
                              args=["--ros-args", "-r", "__node:=explicit", "-p", "controller_type:=explicit"])
    node = rclpy.create_node("parameter_probe", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    setter = node.create_client(SetParameters, f"{NODE}/set_parameters")
    getter = node.create_client(GetParameters, f"{NODE}/get_parameters")
    names = sorted({name for name, _ in BAD})

    def values():
        reply = call_idempotent(executor, getter, GetParameters.Request(names=names), ready_timeout=30.0,
                                response_timeout=10.0, attempts=2)
        return dict(zip(names, (_plain(v) for v in reply.values)))

    before = values()
    assert before["forgetting"] == 0.999 and before["max_pole"] == 1.3, controller.log_text()
    accepted, reasons = [], []
    for name, value in BAD:
        request = SetParameters.Request(parameters=[ParameterMsg(name=name, value=_value(value))])
        result = call_idempotent(executor, setter, request, ready_timeout=10.0, response_timeout=10.0,
                                 attempts=2).results[0]
        if result.successful:
            accepted.append((name, value))
        reasons.append(result.reason)
    assert accepted == []
    assert all(r and "\n" not in r and ("within [" in r or "out of range" in r) for r in reasons), reasons
    assert values() == before            # nothing changed
    # a good value is taken (the refusals are not a read-only parameter's)
    ok = call_idempotent(executor, setter, SetParameters.Request(parameters=[
        ParameterMsg(name="forgetting", value=_value(0.98))]), ready_timeout=10.0, response_timeout=10.0,
        attempts=2).results[0]
    assert ok.successful and values()["forgetting"] == 0.98
    assert controller.running, controller.log_text()
    executor.shutdown()
