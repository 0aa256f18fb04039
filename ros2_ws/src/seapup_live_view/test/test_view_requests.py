"""The live view's request checks (``view_requests.py``): every refusal one line naming the reason, and what is
accepted typed exactly as the graph's messages need it (issue 40)."""
import json
import math

import pytest

from seapup_live_view import view_requests as vr
from seapup_live_view.view_requests import ViewRequestError


def _json(body) -> bytes:
    return json.dumps(body).encode()


def _refused(call, payload, *words):
    with pytest.raises(ViewRequestError) as caught:
        call(payload)
    text = str(caught.value)
    assert "\n" not in text and len(text) < 200, text
    for word in words:
        assert word in text, (word, text)
    return text


# -- booleans are JSON booleans ---------------------------------------------------------------------------------
@pytest.mark.parametrize("enabled", ["false", "true", [0], 0, 1, None, {}])
def test_set_current_takes_only_a_json_boolean_for_enabled(enabled):
    # the finding: "false" and [0] were truthy, answered ok and switched the current ON
    _refused(vr.current_request, _json({"enabled": enabled}), "set_current", "enabled", "true or false")


def test_set_current_off_and_on_are_typed_as_the_service_needs():
    assert vr.current_request(_json({"enabled": False})) == {
        "enabled": False, "mean_speed": 0.0, "mean_direction": 0.0, "speed_std": 0.0, "direction_std": 0.0,
        "break_time": 0.0}
    on = vr.current_request(_json({"enabled": True, "mean_speed": 0.26, "mean_direction": -1, "speed_std": 0.086,
                                   "direction_std": 0.349, "break_time": 10}))
    assert on == {"enabled": True, "mean_speed": 0.26, "mean_direction": -1.0, "speed_std": 0.086,
                  "direction_std": 0.349, "break_time": 10.0}
    assert all(type(v) is float for k, v in on.items() if k != "enabled")
    assert vr.current_request(b"")["enabled"] is True   # the empty payload: the current on, as documented


# -- numbers are finite JSON numbers in range -------------------------------------------------------------------
@pytest.mark.parametrize("value, reason", [("0.3", "finite number"), (True, "finite number"), ([0.3], "finite number"),
                                           (None, "finite number"), (10 ** 400, "finite number"),
                                           (-0.1, ">= 0"), (-1e-300, ">= 0")])
def test_set_current_refuses_a_speed_that_is_not_a_finite_non_negative_number(value, reason):
    _refused(vr.current_request, _json({"mean_speed": value}), "mean_speed", reason)


@pytest.mark.parametrize("text", [b'{"mean_speed": NaN}', b'{"mean_speed": Infinity}', b'{"x": -Infinity}'])
def test_non_standard_json_constants_are_refused_as_not_json(text):
    _refused(vr.current_request, text, "not JSON", "is not a JSON number")


def test_goto_takes_finite_numbers_and_a_boolean_preempt():
    goal = vr.goto_request(_json({"x": 10, "y": 0.0, "z": 30, "yaw": -3.1, "speed": 0.2, "preempt": True}))
    assert goal == {"x": 10.0, "y": 0.0, "z": 30.0, "yaw": -3.1, "speed": 0.2, "preempt": True}
    _refused(vr.goto_request, _json({"x": 5.0, "y": 1.0}), "missing z")
    _refused(vr.goto_request, _json({"x": 5.0, "y": 1.0, "z": 2.0, "preempt": "yes"}), "preempt", "true or false")
    _refused(vr.goto_request, _json({"x": 5.0, "y": 1.0, "z": 2.0, "timeout": -5}), "timeout", ">= 0")
    _refused(vr.goto_request, _json({"x": "5", "y": 1.0, "z": 2.0}), "x", "finite number")


# -- names are printable, bounded, NUL-free ---------------------------------------------------------------------
@pytest.mark.parametrize("name, reason", [("haslar\u0000x", "U+0000"), ("has\nlar", "U+000A"), ("", "non-empty"),
                                          ("h" * (vr.MAX_NAME_LENGTH + 1), f"at most {vr.MAX_NAME_LENGTH}"),
                                          (7, "non-empty string"), (["haslar"], "non-empty string")])
def test_a_profile_name_must_be_printable_bounded_text(name, reason):
    # the finding: a NUL in the name reached the graph as the name cut at the NUL, and succeeded
    _refused(vr.profile_request, _json({"name": name}), "set_sensor_profile", "name", reason)


def test_accepted_names_are_returned_unchanged():
    assert vr.profile_request(_json({"name": "haslar"})) == "haslar"
    assert vr.switch_request(_json({"activate": "gmv"})) == "gmv"
    assert vr.profile_request(_json({"name": "h" * vr.MAX_NAME_LENGTH})) == "h" * vr.MAX_NAME_LENGTH
    _refused(vr.switch_request, _json({}), "needs", "activate")
    _refused(vr.switch_request, _json({"activate": "mfol\u0000"}), "U+0000")


# -- payloads: JSON objects, bounded, known keys ----------------------------------------------------------------
@pytest.mark.parametrize("payload, words", [
    (b"{not json", ("not JSON", "line 1")),
    (b"\xff\xfe", ("not UTF-8",)),
    (b"[1, 2]", ("JSON object",)),
    (b'"haslar"', ("JSON object",)),
    (b"[" * 3000 + b"]" * 3000, ("payload of 6000 bytes",)),
    (b"[" * 2000 + b"]" * 2000, ("not JSON", "nested too deeply")),
    (_json({"name": "haslar", "bogus": 1}), ("unknown keys", "bogus", "allowed: name")),
])
def test_a_payload_that_is_not_one_bounded_json_object_of_known_keys_is_refused(payload, words):
    _refused(vr.profile_request, payload, "set_sensor_profile", *words)


def test_the_largest_payload_read_is_bounded_before_it_is_parsed(monkeypatch):
    parsed = []
    monkeypatch.setattr(vr.json, "loads", lambda *a, **k: parsed.append(a) or {})
    _refused(vr.current_request, b" " * (vr.MAX_PAYLOAD_BYTES + 1), "at most 4096")
    assert parsed == []   # refused on its size alone


# -- parameter sets: few, each once, known, typed ---------------------------------------------------------------
def test_a_parameter_set_naming_the_same_parameter_twice_or_too_many_is_refused():
    # the finding: "controller" repeated 40 times blocked the server for 5 s per value
    _refused(vr.parameter_request, [("controller", "gmv")] * 2, "controller named twice")
    text = _refused(vr.parameter_request, [("controller", "gmv")] * 40, "40 parameters", "at most 2")
    assert len(text) < 200


def test_a_huge_parameter_set_is_refused_on_its_length_before_any_value_is_read():
    class Untouchable:
        def __len__(self):
            return 10 ** 6

        def __iter__(self):
            raise AssertionError("read although its length is refused")
    _refused(vr.parameter_request, Untouchable(), "1000000 parameters")


@pytest.mark.parametrize("pairs, words", [
    ([("lockstep_pace", -1.0)], ("lockstep_pace", "in [0, 10000]")),
    ([("lockstep_pace", math.nan)], ("finite number",)),
    ([("lockstep_pace", "3")], ("finite number",)),
    ([("lockstep_pace", True)], ("finite number",)),
    ([("controller", "")], ("non-empty",)),
    ([("controller", "gmv\u0000")], ("U+0000",)),
    ([("bogus", 1.0)], ("no parameter", "bogus")),
    ([], ("no parameter named",)),
])
def test_parameter_values_are_typed_and_in_range(pairs, words):
    _refused(vr.parameter_request, pairs, "setParameters", *words)


def test_a_valid_parameter_set_is_typed_for_the_graph():
    assert vr.parameter_request([("lockstep_pace", 3), ("controller", "gmv")]) == [("lockstep_pace", 3.0),
                                                                                   ("controller", "gmv")]
    assert vr.parameter_request([("lockstep_pace", 1e4)]) == [("lockstep_pace", 1e4)]   # the simulator's bound


def test_only_the_pilot_s_json_twist_channel_is_taken_from_a_viewer():
    vr.pilot_channel("/seapup/pilot/cmd_vel", "json", "geometry_msgs/msg/Twist", "/seapup/pilot/cmd_vel")
    vr.pilot_channel("/seapup/pilot/cmd_vel", "json", "geometry_msgs/Twist", "/seapup/pilot/cmd_vel")
    for topic, encoding, schema in (("/seapup/thrusters/command", "json", "geometry_msgs/msg/Twist"),
                                    ("/seapup/pilot/cmd_vel", "cdr", "geometry_msgs/msg/Twist"),
                                    ("/seapup/pilot/cmd_vel", "json", "std_msgs/String")):
        with pytest.raises(ViewRequestError, match="only /seapup/pilot/cmd_vel as JSON geometry_msgs/Twist"):
            vr.pilot_channel(topic, encoding, schema, "/seapup/pilot/cmd_vel")


def test_a_pilot_message_is_a_bounded_finite_twist_missing_parts_zero():
    linear, angular = vr.pilot_twist(json.dumps({"linear": {"x": 0.2, "y": -0.1}, "angular": {"z": 0.3}}).encode())
    assert linear == (0.2, -0.1, 0.0) and angular == (0.0, 0.0, 0.3)
    for payload, reason in ((b'{"linear": {"x": NaN}}', "not a JSON number"),
                            (b'{"linear": {"x": "1"}}', "x must be a finite number"),
                            (b'{"linear": {"x": 11}}', r"x must be in \[-10, 10\]"),
                            (b'{"linear": {"w": 1}}', "must be an object of x, y, z"),
                            (b'{"twist": {}}', "unknown keys"),
                            (b"[1, 2]", "must be a JSON object"),
                            (b"x" * 5000, "at most 4096")):
        with pytest.raises(ViewRequestError, match=reason):
            vr.pilot_twist(payload)


def test_a_viewer_s_switch_deactivates_the_controller_flying_as_the_manager_requires():
    """The manager refuses to activate a controller while another flies unless the same request deactivates it
    (its pure core, seapup_control.controller_manager): the view's switch names both, so a viewer swaps laws, or
    takes the vehicle by hand, in flight."""
    from seapup_control.controller_manager import STRICT, ControllerManagerCore, SwitchError
    core = ControllerManagerCore(["mfol_fixed", "gmv", "manual"], "mfol_fixed")
    core.active = "mfol_fixed"
    with pytest.raises(SwitchError, match="mfol_fixed is active"):
        core.plan_switch(["manual"], [], STRICT)            # what the view asked before
    plan = core.plan_switch(*vr.switch_lists("manual", core.active), STRICT)
    assert plan.activate == ["manual"] and plan.deactivate == ["mfol_fixed"]
    assert vr.switch_lists("gmv", "") == (["gmv"], []) and vr.switch_lists("gmv", "gmv") == (["gmv"], [])
