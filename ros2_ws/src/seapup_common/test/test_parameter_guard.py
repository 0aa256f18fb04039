"""ParameterGuard: the allowed range of every numeric parameter, arrays element by element, NaN and inf
refused (rclpy lets NaN pass a scalar range on set, and never checks arrays)."""
import math

from rclpy.parameter import Parameter

from seapup_common.ros.node import ParameterGuard


def test_scalars_and_arrays_outside_their_range_or_not_finite_are_refused_by_name():
    guard = ParameterGuard({"reference_wait": (0.0, 600.0), "gains": (0.0, 10.0), "orders": (0, 20)})
    for name, value in (("reference_wait", math.nan), ("reference_wait", math.inf), ("reference_wait", -1.0),
                        ("reference_wait", 1e300), ("gains", [0.2, math.nan, 0.3]), ("gains", [0.2, 11.0]),
                        ("orders", [2, 21, 0])):
        result = guard([Parameter(name, value=value)])
        assert not result.successful and result.reason.startswith(f"{name} = "), (name, value, result.reason)
    for name, value in (("reference_wait", 0.0), ("reference_wait", 600.0), ("gains", [0.0, 10.0]),
                        ("orders", [2, 2, 0]), ("controller_type", "mfol")):
        assert guard([Parameter(name, value=value)]).successful, (name, value)
