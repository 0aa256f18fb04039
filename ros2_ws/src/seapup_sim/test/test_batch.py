"""The batch plant (seapup_sim.batch): N vehicles on a leading axis, each the single vehicle bit for bit.

Truth: the single-vehicle integrator (tested against the NumPy reference in test_compiled.py and against
the thesis elsewhere), run on each vehicle alone with the same configuration, efficiency, commands,
currents and wrenches.
"""
import copy
import math

import numpy as np
import pytest

from seapup_common.blade_pitch import InvalidBladePitchError
from seapup_sim.batch import BatchPlant
from seapup_sim.integrator import DivergenceError, VehicleIntegrator
from seapup_sim.linearised import vehicle_model
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config


def _configs(rng, n):
    """Mixed configurations: the shipped ones and overlays of the baseline's hydrodynamic table."""
    out = []
    for i in range(n):
        config = copy.deepcopy(load_vehicle_config(("baseline", "camera", "fouled_main_port")[i % 3]))
        if i % 4 == 3:   # an overlay: every derivative perturbed by up to 20 %
            config["hydrodynamics"] = {k: v * rng.uniform(0.8, 1.2) for k, v in config["hydrodynamics"].items()}
        out.append(config)
    return out


@pytest.mark.unit
def test_each_vehicle_of_a_batch_is_the_vehicle_flown_alone_bit_for_bit():
    rng = np.random.default_rng(11)
    n, steps = 12, 300
    configs = _configs(rng, n)
    states = np.zeros((n, 12))
    states[:, 2] = rng.uniform(20, 60, n)
    states[:, 5] = rng.uniform(-3, 3, n)
    efficiency = np.where(rng.random((n, 4)) < 0.2, rng.uniform(0.3, 1.0, (n, 4)), 1.0)
    commands = np.radians(rng.uniform(-40, 40, (steps, n, 4)))   # some beyond the limits: clipped alike
    currents = rng.normal(0, 0.2, (steps, n, 3))
    externals = rng.normal(0, 10, (steps, n, 6))
    batch = BatchPlant.from_configs(configs, dt=0.1, states=states)
    for i in range(n):
        batch.set_efficiency(i, efficiency[i])
    batch.thrusters_on[5] = False
    trajectory = np.array([batch.step(commands[k], currents[k], externals[k]) for k in range(steps)])
    assert batch.active.all() and batch.t == pytest.approx(30.0)
    for i in range(n):
        alone = VehicleIntegrator(VehicleModel(configs[i]), dt=0.1, state=states[i], backend="compiled")
        alone.model.thrusters.set_efficiency(efficiency[i])
        alone.thrusters_on = i != 5
        mine = np.array([alone.step(commands[k, i], currents[k, i], externals[k, i]) for k in range(steps)])
        assert np.array_equal(mine, trajectory[:, i]), (i, np.max(np.abs(mine - trajectory[:, i])))
        assert np.array_equal(alone.pitch, batch.pitch[i])
    # and the vehicles are not one vehicle: the configurations and inputs made them differ
    assert np.ptp(trajectory[-1, :, 6]) > 0.05


@pytest.mark.unit
def test_a_diverging_vehicle_stops_alone_with_its_reason():
    model = VehicleModel(load_vehicle_config("baseline"))
    batch = BatchPlant([model] * 3, dt=0.1)
    wrench = np.zeros((3, 6))
    wrench[1, 0] = 1e6
    before = batch.state.copy()
    batch.step(np.zeros((3, 4)), externals=wrench)
    assert list(batch.active) == [True, False, True]
    with pytest.raises(DivergenceError) as single:   # the message the vehicle alone would raise
        VehicleIntegrator(model, dt=0.1, backend="compiled").step(np.zeros(4), external=wrench[1])
    assert batch.errors[1] == str(single.value) and "outside the valid envelope" in batch.errors[1]
    assert np.array_equal(batch.state[1], before[1]) and batch.errors[0] is None
    alone = VehicleIntegrator(model, dt=0.1, backend="compiled")
    alone.step(np.zeros(4))
    for _ in range(5):
        batch.step(np.radians(np.full((3, 4), 20.0)))
        alone.step(np.radians(np.full(4, 20.0)))
    assert np.array_equal(batch.state[0], alone.state) and np.array_equal(batch.state[1], before[1])


@pytest.mark.unit
@pytest.mark.parametrize("field, value, message", [
    ("commands", np.zeros((2, 4)), "shape \\(3, 4\\)"),
    ("commands", np.array([[0, 0, 0, 0], [0, np.nan, 0, 0], [0, 0, 0, 0]]), "not finite for vehicle\\(s\\) 1"),
    ("currents", np.full((3, 3), np.inf), "currents is not finite"),
    ("externals", np.zeros((3, 5)), "external wrenches needs shape"),
])
def test_bad_input_is_refused_for_the_whole_step_and_changes_nothing(field, value, message):
    batch = BatchPlant([VehicleModel(load_vehicle_config("baseline"))] * 3, dt=0.1)
    args = {"commands": np.full((3, 4), 0.3), "currents": None, "externals": None, field: value}
    before = batch.state.copy()
    with pytest.raises(ValueError, match=message) as caught:
        batch.step(args["commands"], args["currents"], args["externals"])
    assert "\n" not in str(caught.value) and batch.steps == 0 and np.array_equal(batch.state, before)
    if field == "commands":
        assert isinstance(caught.value, InvalidBladePitchError)


@pytest.mark.unit
def test_a_reconfigured_vehicle_changes_alone_and_keeps_its_fouling():
    model = VehicleModel(load_vehicle_config("baseline"))
    batch = BatchPlant([model, model], dt=0.1)
    batch.set_efficiency(0, [0.5, 1, 1, 1])
    command = np.radians(np.full((2, 4), 25.0))
    for _ in range(20):
        batch.step(command)
    batch.configure(1, load_vehicle_config("camera"))
    assert batch.models[0] is model and batch.models[1] is not model
    assert list(batch.efficiency[0]) == [0.5, 1, 1, 1]
    camera = VehicleIntegrator(VehicleModel(load_vehicle_config("baseline")), dt=0.1, backend="compiled")
    for _ in range(20):
        camera.step(command[1])
    camera.model.configure(load_vehicle_config("camera"))
    for _ in range(30):
        batch.step(command)
        camera.step(command[1])
    assert np.array_equal(batch.state[1], camera.state)


@pytest.mark.unit
def test_a_batch_refuses_what_it_cannot_step():
    with pytest.raises(ValueError, match="at least one vehicle"):
        BatchPlant([])
    with pytest.raises(ValueError, match="LinearisedVehicleModel"):
        BatchPlant([vehicle_model(load_vehicle_config("baseline"), "linearised")])
    with pytest.raises(ValueError, match="states needs shape"):
        BatchPlant([VehicleModel(load_vehicle_config("baseline"))], states=np.zeros(12))


@pytest.mark.unit
def test_a_batch_of_currents_is_each_current_alone_bit_for_bit():
    """Eq. 2.25-2.33 for 7 vehicles with their own statistics and streams (two steady, one changed
    mid-run to a noisy current and one to a steady one): speeds, directions and NED velocities equal the
    single currents' exactly, through more than one refill of the pre-drawn noise."""
    from seapup_common.random_streams import RandomStreams
    from seapup_sim.batch import BatchCurrent
    from seapup_sim.current import CurrentParams, GaussMarkovCurrent

    def build():
        out = []
        for i in range(7):
            params = CurrentParams(0.1 + 0.03 * i, 0.0 if i in (2, 5) else 0.02 * (i + 1), 0.3 * i,
                                   0.0 if i in (2, 5) else 0.1, 20.0 + i)
            out.append(GaussMarkovCurrent(params, 0.1, RandomStreams(100 + i).generator("current"),
                                          start_at_mean=i % 2 == 0))
        return out
    alone, batch = build(), BatchCurrent(build(), block=64)
    changed = {2: CurrentParams(0.26, 0.086, 0.0, math.radians(20), 10.0), 3: CurrentParams(0.2, 0.0, 1.0, 0.0, 5.0)}
    for k in range(300):
        if k == 150:
            for i, params in changed.items():
                alone[i].set_params(params)
                batch.set_params(i, params)
        for c in alone:
            c.step()
        batch.step()
        assert np.array_equal(batch.speed, [c.speed for c in alone]), k
        assert np.array_equal(batch.direction, [c.direction for c in alone]), k
        assert np.array_equal(batch.velocity_ned(), [c.velocity_ned() for c in alone]), k
    assert np.std(batch.speed) > 0 and len(set(np.round(batch.speed, 6))) == 7


@pytest.mark.unit
def test_batch_sensors_read_what_each_suite_alone_reads_bit_for_bit():
    """Every profile but strapdown, a sloping seabed some vehicles are above and some below, fixes lost and
    kept, altimeter echoes in and out of range: the readings of vehicle i equal its SensorSuite's."""
    from seapup_common.random_streams import RandomStreams
    from seapup_sim.batch import BatchSensors
    from seapup_sim.seabed import Seabed
    from seapup_sim.sensors import SensorSuite, load_sensor_profile
    rng = np.random.default_rng(5)
    n, samples = 12, 120
    seabeds = [Seabed("flat", 30.0), Seabed("slope", 20.0, 0.3, 0.5), None,
               Seabed("polyline", 25.0, direction=-0.4, points=[[-30, 10.0], [0, 35.0], [40, 5.0]])]
    profiles = ["ideal", "baseline", "haslar"]

    def suites():
        return [SensorSuite(load_sensor_profile(profiles[i % 3]), RandomStreams(100 + i), seabeds[i // 3])
                for i in range(n)]
    alone, batch = suites(), BatchSensors(suites())
    states = np.zeros((samples, n, 12))
    states[:, :, :3] = rng.normal(0, 20, (samples, n, 3))          # above and below the seabeds
    states[:, :, 3:6] = rng.normal(0, 1.2, (samples, n, 3))        # some tilts point the altimeter up
    states[:, :, 6:] = rng.normal(0, 0.3, (samples, n, 6))
    names = {"velocity": "velocity", "rates": "rates", "attitude": "attitude", "depth": "depth",
             "altitude": "altitude", "position": "position"}
    seen = {"altitude": 0, "position": 0}
    for k in range(samples):
        t = 0.2 * k
        read = batch.measure(t, states[k])
        for i in range(n):
            m = alone[i].measure(t, states[k, i])
            for field, key in names.items():
                reading = getattr(m, field)
                if reading.valid:
                    seen[field] = seen.get(field, 0) + 1
                    assert np.array_equal(np.atleast_1d(reading.value), np.atleast_1d(read[key][i])), (k, i, field)
                else:
                    assert np.isnan(read[key][i]).all(), (k, i, field)
    # the conditional readings happened both ways
    assert 0 < seen["altitude"] < samples * n and 0 < seen["position"] < samples * n


def test_a_suite_read_alone_then_taken_over_by_a_batch_goes_on_with_its_own_draws():
    """A suite that already read (and so holds draws from its streams it has not used) and is then read by a
    batch: the batch uses those draws first, so the vehicle's readings are those of the suite read alone
    throughout -- over more than a block of draws either side of the takeover."""
    from seapup_common.random_streams import RandomStreams
    from seapup_sim.batch import BatchSensors
    from seapup_sim.seabed import Seabed
    from seapup_sim.sensors import NORMALS_BLOCK, SensorSuite, load_sensor_profile

    def suite(i):
        return SensorSuite(load_sensor_profile("baseline"), RandomStreams(40 + i), Seabed("flat", 60.0))
    lone, taken = [suite(i) for i in range(3)], [suite(i) for i in range(3)]
    state = np.zeros(12)
    state[2] = 30.0
    before = [5, NORMALS_BLOCK // 3, 0]   # read mid-block, a whole block used, never read
    for i, n in enumerate(before):
        for k in range(n):
            assert np.array_equal(taken[i].measure(0.2 * k, state).velocity.value,
                                  lone[i].measure(0.2 * k, state).velocity.value)
    batch = BatchSensors(taken)
    start = max(before)
    for k in range(start, start + 2 * NORMALS_BLOCK):
        read = batch.measure(0.2 * k, np.tile(state, (3, 1)))
        for i in range(3):
            m = lone[i].measure(0.2 * k, state)
            for field in ("velocity", "rates", "attitude", "depth", "altitude"):
                assert np.array_equal(np.atleast_1d(getattr(m, field).value), np.atleast_1d(read[field][i])), \
                    (k, i, field)


@pytest.mark.unit
@pytest.mark.parametrize("threads", [2, 3])
def test_a_batch_on_two_threads_is_the_batch_on_one(threads):
    rng = np.random.default_rng(3)
    n = 40
    configs = _configs(rng, n)
    states = np.zeros((n, 12))
    states[:, 2] = rng.uniform(20, 60, n)
    one, two = (BatchPlant.from_configs(configs, states=states, threads=k) for k in (1, threads))
    for _ in range(50):
        commands, currents = np.radians(rng.uniform(-30, 30, (n, 4))), rng.normal(0, 0.2, (n, 3))
        assert np.array_equal(one.step(commands, currents), two.step(commands, currents))
    with pytest.raises(ValueError, match="threads"):
        BatchPlant.from_configs(configs[:2], threads=0)
