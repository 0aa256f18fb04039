"""Sec. 6.5's identification experiments as run specs flown in process (seapup_runs.identification_experiment).

Truths: the PRBS of sec. 6.2.1 (its levels, switching on the clock), the hover setting of eq. 5.2 it is
centred on, the first-order actuator of sec. 2.2 (a switch settled to e^-4 one sample later), the square wave of
sec. 6.5.5 and the bag convention of ``seapup_ident.online.held_inputs`` (u(t_k) is the pitch read at t_k+1). That
the record equals the graph's bag sample for sample is tested on the graph (tests/test_ident_commands.py).
"""
import math

import numpy as np
import pytest

from seapup_runs.identification_experiment import (experiment_samples, experiment_spec, identification_data,
                                                    prbs_schedule, square_wave)
from seapup_common.blade_pitch import THRUSTER_NAMES
from seapup_runs.runner import run

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def open_loop():
    schedule = prbs_schedule("baseline", 30.0)
    return schedule, run(experiment_spec(duration=30.0, schedule=schedule))


def test_the_open_loop_record_is_the_prbs_about_hover_held_over_each_interval(open_loop):
    from seapup_sim.analysis import hover_blade_pitch
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    schedule, result = open_loop
    data = identification_data(result)
    # 30 s at 5 Hz: the record holds t = 0 .. 30 s, the data the 150 samples with an input interval
    assert len(result.series.t) == 151 and len(data.t) == 150
    np.testing.assert_allclose(data.t, 0.2 * np.arange(150), atol=1e-9)
    assert data.outputs == ("u", "v", "w", "r", "roll", "pitch") and np.all(np.isfinite(data.y))
    # u(t_k) is the pitch applied over [t_k, t_k+1], read at t_k+1 (the bag convention), not the one at t_k
    np.testing.assert_array_equal(data.u, result.series.applied[1:])
    assert not np.array_equal(data.u, result.series.applied[:-1])
    hover = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))   # eq. 5.2, solved here
    offset = np.abs(data.u - hover)
    assert offset.max() <= math.radians(10) + 1e-9
    assert np.all(np.isclose(offset, math.radians(10), atol=math.radians(0.4)))   # settled one sample on
    # the schedule switches only on the 10-sample clock, and every thruster is excited both ways
    times = np.array(schedule["times"])
    assert times[0] == 0.0 and np.allclose(np.round(times / 2.0), times / 2.0)
    assert schedule["switches"] == len(times) and len(schedule["pitches"]) == 4 * len(times)
    assert np.all((data.u - hover).max(axis=0) > 0) and np.all((data.u - hover).min(axis=0) < 0)
    # the motion the thrusters make: the vehicle moves in every velocity it is identified in
    assert np.all(np.std(data.y[:, :4], axis=0) > 1e-3)


def test_the_ch6_findings_hold_on_the_in_process_record(open_loop):
    """Sec. 6.5.2 (Tables 6.2, 6.3): second order needed on most outputs (F-test, 5 % risk), ELS slightly better
    than LS on most outputs -- as the graph's record of the same experiment shows."""
    from seapup_ident.identify import compare_methods, order_table
    from seapup_ident.recursive import Forgetting
    data = identification_data(open_loop[1])
    schedule = lambda: Forgetting.schedule(0.6, 0.9)  # noqa: E731
    assert sum(order_table(data, 2, forgetting_factory=schedule)["rows"][1]["significant"]) >= 4
    methods = compare_methods(data, 2, ("ls", "els"), forgetting_factory=schedule)["methods"]
    ls, els = np.array(methods["ls"]["aic"]), np.array(methods["els"]["aic"])
    assert np.sum(els < ls) >= 4 and np.all(np.abs(els - ls) < 0.1 * np.abs(ls))


def test_the_ch7_outputs_and_an_invalid_reading_are_kept_as_the_bag_reader_keeps_them(open_loop):
    _, result = open_loop
    data = identification_data(result, ("u", "v", "w", "r"))
    assert data.y.shape == (150, 4) and data.inputs == THRUSTER_NAMES and len(THRUSTER_NAMES) == 4
    result.series.measured["u"][7] = np.nan   # an invalid velocity reading: NaN, never used
    try:
        again = identification_data(result, ("u", "v"))
        assert np.isnan(again.y[7, 0]) and np.isfinite(again.y[7, 1])
    finally:
        result.series.measured["u"][7] = data.y[7, 0]
    with pytest.raises(ValueError, match="unknown output"):
        identification_data(result, ("u", "heading"))


def test_the_closed_loop_reference_is_sec_6_5_5_s_square_wave():
    wave = square_wave([[0.2, 0, 0, math.radians(15)], [0, 0.1, -0.1, 0]], 10.0, 40.0)
    assert [t for t, _ in wave.steps] == [0.0, 10.0, 20.0, 30.0, 40.0]
    assert wave.at(9.8).velocity[0] == 0.2 and wave.at(10.0).velocity[1] == 0.1 and wave.at(25.0).velocity[0] == 0.2
    spec = experiment_spec(duration=40.0, controller_file="ctrl.yaml", reference=wave, current=True,
                           dynamics="linearised", seed=3)
    assert spec.controller.type == "mfol" and spec.controller.file == "ctrl.yaml" and spec.seed == 3
    assert spec.environment["current"]["enabled"] is True and spec.dynamics == "linearised"
    assert spec.control_period == 0.2 and spec.samples == 200


@pytest.mark.parametrize("call, reason", [
    (lambda: experiment_samples(10.1), "whole number of 0.2 s"),
    (lambda: experiment_samples(-5.0), "> 0 s"),
    (lambda: experiment_samples(math.nan), "> 0 s"),
    (lambda: experiment_samples("60"), "a number of seconds"),
    (lambda: experiment_samples(1e9), "longer than"),
    (lambda: prbs_schedule("baseline", 10.0, amplitude_deg=40.0), r"\(0, 35\] deg"),
    (lambda: prbs_schedule("baseline", 10.0, amplitude_deg=30.0), "leaves the \\+-35 deg"),
    (lambda: prbs_schedule("baseline", 10.0, clock=0), "--clock"),
    (lambda: square_wave([[0, 0, 0, 0]], 10.0, 20.0), "two levels"),
    (lambda: square_wave([[0, 0, 0, 0]] * 2, 0.0, 20.0), "--half-period"),
    (lambda: square_wave([[0, 0, 0, 0]] * 2, 1e-4, 2e4), "more than 10\\^5"),
    (lambda: experiment_spec(duration=10.0), "one of the two"),
    (lambda: experiment_spec(duration=10.0, schedule={"times": [0.0], "pitches": [0.0] * 4}, dynamics="quadratic"),
     "dynamics"),
])
def test_a_bad_request_is_refused_in_one_line_before_anything_is_flown(call, reason):
    with pytest.raises(ValueError, match=reason) as caught:
        call()
    assert "\n" not in str(caught.value)
