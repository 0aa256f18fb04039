"""Generic message conversion (seapup_common.ros.introspection) against the generated classes themselves."""
import numpy as np
import pytest
from geometry_msgs.msg import TwistWithCovarianceStamped
from rcl_interfaces.srv import SetParameters
from seapup_msgs.action import SelfTest
from seapup_msgs.msg import BladePitch

from seapup_common.ros.introspection import (InterfaceError, definition, field_value, fill, interface_class,
                                             to_data, to_yaml, type_name)


def test_names_resolve_to_the_generated_classes():
    assert interface_class("seapup_msgs/msg/BladePitch") is BladePitch
    assert interface_class("seapup_msgs/BladePitch") is BladePitch
    assert interface_class("rcl_interfaces/srv/SetParameters") is SetParameters
    assert type_name(BladePitch()) == "seapup_msgs/msg/BladePitch"
    for bad, words in (("BladePitch", "not an interface name"), ("nope/msg/X", "unknown interface package"),
                       ("seapup_msgs/msg/Nope", "has no 'Nope'"), ("seapup_msgs/idl/BladePitch", "not an interface")):
        with pytest.raises(InterfaceError, match=words):
            interface_class(bad)


def test_fill_and_to_data_round_trip_nested_messages_and_sequences():
    msg = fill(TwistWithCovarianceStamped(), {"header": {"stamp": {"sec": 3, "nanosec": 5}, "frame_id": "base_link_frd"},
                                              "twist": {"twist": {"linear": {"x": 0.5}}, "covariance": [0.1] * 36}})
    assert msg.header.stamp.sec == 3 and msg.twist.twist.linear.x == 0.5 and msg.twist.covariance[35] == 0.1
    data = to_data(msg)
    assert data["twist"]["twist"]["angular"] == {"x": 0.0, "y": 0.0, "z": 0.0}
    again = fill(TwistWithCovarianceStamped(), data)
    assert again == msg
    request = fill(SetParameters.Request(), {"parameters": [{"name": "a", "value": {"type": 3, "double_value": 2.5}}]})
    assert request.parameters[0].value.double_value == 2.5
    assert field_value(request, "parameters.0.value.double_value") == 2.5
    with pytest.raises(InterfaceError, match="no field"):
        field_value(request, "parameters.1")


def test_data_that_does_not_fit_is_refused_and_changes_nothing():
    msg = BladePitch(pitch=[0.1, 0.2, 0.3, 0.4])
    for bad, words in (({"pitch": [1.0, 2.0]}, "exactly 4"), ({"pitch": "x"}, "a list"),
                       ({"pitch": [0, 0, 0, True]}, "a number"), ({"nope": 1}, "no field 'nope'"),
                       ({"header": {"stamp": {"sec": 2**31}}}, r"int32"), ({"header": {"frame_id": 3}}, "a string"),
                       ({"header": {"frame_id": "ok"}, "pitch": [1.0]}, "exactly 4"), ([1, 2], "a mapping")):
        with pytest.raises(InterfaceError, match=words):
            fill(msg, bad)
        np.testing.assert_array_equal(msg.pitch, [0.1, 0.2, 0.3, 0.4])
        assert msg.header.frame_id == ""


def test_yaml_text_is_what_ros2_topic_echo_prints():
    msg = BladePitch(pitch=[0.1, -0.2, 0.0, 1.0])
    msg.header.frame_id = "base_link_frd"
    assert to_yaml(msg) == ("header:\n  stamp:\n    sec: 0\n    nanosec: 0\n  frame_id: base_link_frd\n"
                            "pitch:\n- 0.1\n- -0.2\n- 0.0\n- 1.0")
    request = fill(SetParameters.Request(), {"parameters": [{"name": "a"}]})
    text = to_yaml(request)
    assert text.startswith("parameters:\n- name: a\n  value:\n    type: 0\n") and "  byte_array_value: []" in text


def test_definition_of_an_action_lists_goal_result_feedback():
    parts = definition(SelfTest).split("\n---\n")
    assert len(parts) == 3 and parts[0].startswith("float64 sample_period") and "string phase" in parts[2]
