"""The compiled plant (seapup_sim.compiled) against the NumPy reference (issue 26).

Truth: VehicleModel.derivatives and the NumPy VehicleIntegrator step, which the rest of the suite
checks against the thesis (eq. 2.1-2.3, Table 3.2) and against conservation laws. Equal to 1e-12 on
random states, blade pitches, currents, external wrenches and thruster efficiencies, for every shipped
configuration, with the thrusters on and off and with and without the actuator lag.
"""
import re

import numpy as np
import pytest

from seapup_sim import compiled
from seapup_sim.integrator import DivergenceError, VehicleIntegrator, default_backend
from seapup_sim.linearised import vehicle_model
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import available_configs, load_vehicle_config

#: every shipped vehicle: the Seapup's controllable-pitch thrusters and the BlueROV2's fixed-pitch ones (its
#: polynomial curve read through its monotone envelope, and the maker's table)
CONFIGS = available_configs()


def _random_inputs(rng, model=None):
    """A state, the actuators' state (the Seapup's four blade pitches [rad], or N fixed-pitch thrusters' lagged
    commands, a little beyond +-1 to reach the curve's clipping), a current, an external wrench."""
    state = np.concatenate([rng.normal(0, 20, 3), rng.uniform(-1.2, 1.2, 3) * np.array([1, 1, 2.5]),
                            rng.normal(0, 0.5, 3), rng.normal(0, 0.4, 3)])
    fixed = model is not None and model.thrusters.kind == "fixed_pitch"
    pitch = rng.uniform(-1.1, 1.1, model.thrusters.count) if fixed else rng.uniform(-0.61, 0.61, 4)
    current = rng.normal(0, 0.3, 3) if rng.random() < 0.7 else None
    external = rng.normal(0, 30, 6) if rng.random() < 0.5 else None
    return state, pitch, current, external


@pytest.mark.unit
def test_the_configurations_are_all_flown():
    assert {"baseline", "camera", "fouled_main_port", "bluerov2_heavy", "bluerov2_heavy_t200"} <= set(CONFIGS)
    rov = VehicleIntegrator(VehicleModel(load_vehicle_config("bluerov2_heavy")), backend="compiled")
    assert rov.compiled   # eight fixed-pitch thrusters behind the mixer: the kernels too


@pytest.mark.unit
@pytest.mark.parametrize("name", CONFIGS)
def test_a_flat_model_places_every_table_of_the_packed_one(name):
    """The kernels' two-array model (Flat) read back through its header: every table of the packed model, the
    hydrodynamic terms grouped by axis in their order within each (so each axis's sum adds the same terms in the same
    order); a batch's row is the vehicle's own flat model, padded."""
    packed = compiled.pack(VehicleModel(load_vehicle_config(name)))
    ints, floats = compiled.flatten(packed)
    h = ints[:compiled.HEADER]
    terms, width = h[compiled.I_TERMS], h[compiled.I_WIDTH]
    assert (h[compiled.I_THRUSTERS], terms, width) == (packed.directions.shape[0], *packed.h_signed.shape)

    def table(kind, start, size):
        return (ints if kind == "i" else floats)[h[start]:h[start] + size]
    assert np.array_equal(table("i", compiled.I_PTR, packed.sp_ptr.size), packed.sp_ptr)
    assert np.array_equal(table("i", compiled.I_IDX, packed.sp_idx.size), packed.sp_idx)
    assert np.array_equal(table("f", compiled.I_VAL, packed.sp_val.size), packed.sp_val)
    assert np.array_equal(table("f", compiled.I_DIRECTIONS, packed.directions.size).reshape(-1, 3), packed.directions)
    assert np.array_equal(table("f", compiled.I_SCALARS, packed.scalars.size), packed.scalars)
    assert np.array_equal(table("f", compiled.I_CURVE_X, h[compiled.I_CURVE_X_SIZE]), packed.curve_x)
    assert np.array_equal(table("f", compiled.I_CURVE_Y, h[compiled.I_CURVE_Y_SIZE]), packed.curve_y)
    starts = table("i", compiled.I_AXIS, 7)
    assert starts[0] == 0 and starts[-1] == terms and np.all(np.diff(starts) >= 0)
    coef = table("f", compiled.I_COEF, terms)
    signed = table("i", compiled.I_SIGNED, terms * width).reshape(terms, width)
    absolute = table("i", compiled.I_ABSOLUTE, terms * width).reshape(terms, width)
    for axis in range(6):   # axis by axis, the packed model's terms of that axis in its order
        mine = slice(starts[axis], starts[axis + 1])
        theirs = packed.h_axis == axis
        assert np.array_equal(coef[mine], packed.h_coef[theirs])
        assert np.array_equal(signed[mine], packed.h_signed[theirs])
        assert np.array_equal(absolute[mine], packed.h_absolute[theirs])
    other, mine = (VehicleModel(load_vehicle_config(c)) for c in
                   ("bluerov2_heavy" if name != "bluerov2_heavy" else "baseline", name))
    rows = compiled.pack_batch([other, mine, other, mine, mine])   # each model once, and which each vehicle flies
    assert rows.ints.shape[0] == 2 and rows.which.tolist() == [0, 1, 0, 1, 1]
    assert np.array_equal(rows.ints[1, :ints.size], ints) and not rows.ints[1, ints.size:].any()
    assert np.array_equal(rows.floats[1, :floats.size], floats) and not rows.floats[1, floats.size:].any()


@pytest.mark.unit
@pytest.mark.parametrize("name", CONFIGS)
def test_the_compiled_right_hand_side_is_the_reference_s(name):
    rng = np.random.default_rng(abs(hash(name)) % 2**32)
    model = VehicleModel(load_vehicle_config(name))
    packed = compiled.pack(model)
    worst = 0.0
    count = model.thrusters.count
    for k in range(300):
        state, pitch, current, external = _random_inputs(rng, model)
        on = k % 5 != 0
        efficiency = rng.uniform(0.0, 1.5, count) if k % 3 == 0 else np.ones(count)
        model.thrusters.set_efficiency(efficiency)
        ours = compiled.derivatives(packed, efficiency, state, pitch, current, external, on)
        ref = model.derivatives(state, pitch, current, external, on)
        assert np.all(np.isfinite(ref))
        worst = max(worst, float(np.max(np.abs(ours - ref) / np.maximum(1.0, np.abs(ref)))))
    assert worst <= 1e-12, worst


@pytest.mark.unit
@pytest.mark.parametrize("name", CONFIGS)
@pytest.mark.parametrize("lag", [True, False])
def test_one_compiled_step_is_the_reference_step(name, lag):
    rng = np.random.default_rng(7 + lag)
    model = VehicleModel(load_vehicle_config(name))
    if not lag:
        model.actuator_time_constant = 0.0
    diverged = []
    for k in range(100):
        state, pitch, current, external = _random_inputs(rng, model)
        state[4] = np.clip(state[4], -1.2, 1.2)
        # beyond the inputs' limit (+-35 deg, or a virtual input's full scale): saturated the same way
        command = rng.uniform(-1.2, 1.2, 4) * model.pitch_limit
        dt = (0.1, 0.05, 0.2)[k % 3]
        steps = [VehicleIntegrator(model, dt=dt, state=state, pitch=np.zeros(4), backend=b)
                 for b in ("compiled", "numpy")]
        for s in steps:
            s.thrusters_on = k % 7 != 0
            s.pitch = pitch.copy()   # the actuators' state (N lagged commands for fixed-pitch thrusters)
        assert steps[0].compiled and not steps[1].compiled

        def stepped(s):
            try:
                return s.step(command, current, external)
            except DivergenceError as exc:   # a random state the step cannot take (a light vehicle at dt 0.2 s)
                return str(exc)
        a, b = (stepped(s) for s in steps)
        if isinstance(b, str):   # the same state refused, its value alike to rounding, neither step taken
            value = re.compile(r"np\.float64\(([-+0-9.e]+)\)")
            assert isinstance(a, str) and a.split(" = ")[0] == b.split(" = ")[0], (a, b)
            assert float(value.search(a).group(1)) == pytest.approx(float(value.search(b).group(1)), rel=1e-9)
            assert steps[0].steps == steps[1].steps == 0
            diverged.append(k)
            continue
        assert np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b))) <= 1e-12, (k, a - b)
        assert np.max(np.abs(steps[0].pitch - steps[1].pitch)) <= 1e-15
        assert steps[0].t == steps[1].t == dt
    assert len(diverged) <= 15, diverged   # most random states are stepped, and compared


@pytest.mark.unit
def test_a_run_with_a_reconfiguration_and_fouling_stays_with_the_reference():
    """A minute of manoeuvring with the configuration switched to the camera vehicle and a thruster fouled
    mid-run (the events of a scenario): the compiled plant re-packs and follows the reference."""
    commands = np.radians(np.random.default_rng(3).uniform(-35, 35, (600, 4)))
    runs = []
    for backend in ("compiled", "numpy"):
        model = VehicleModel(load_vehicle_config("baseline"))
        plant = VehicleIntegrator(model, dt=0.1, state=np.r_[0, 0, 30.0, np.zeros(9)], backend=backend)
        states = []
        for k, command in enumerate(commands):
            if k == 200:
                model.configure(load_vehicle_config("camera"))
            if k == 400:
                model.thrusters.set_efficiency([0.5, 1.0, 1.0, 1.0])
            states.append(plant.step(command, current_ned=np.array([0.2, 0.05, 0.0])))
        runs.append(np.array(states))
    a, b = runs
    assert np.max(np.abs(a - b)) < 1e-9
    # and the events acted: the camera vehicle and the fouling change the trajectory
    plain = VehicleIntegrator(VehicleModel(load_vehicle_config("baseline")), dt=0.1,
                              state=np.r_[0, 0, 30.0, np.zeros(9)], backend="compiled")
    unswitched = np.array([plain.step(c, current_ned=np.array([0.2, 0.05, 0.0])) for c in commands])
    assert np.max(np.abs(unswitched[:200] - a[:200])) == 0.0 and np.max(np.abs(unswitched[250:] - a[250:])) > 1e-3


@pytest.mark.unit
def test_a_model_that_overrides_the_equations_steps_with_the_reference():
    linear = vehicle_model(load_vehicle_config("baseline"), "linearised")
    plant = VehicleIntegrator(linear, dt=0.1, backend="compiled")
    assert not plant.compiled
    before = plant.state.copy()
    plant.step(np.radians([10.0, 10.0, 0.0, 0.0]))
    assert plant.state[6] > before[6]


@pytest.mark.unit
def test_a_diverging_compiled_step_is_refused_and_keeps_the_state():
    model = VehicleModel(load_vehicle_config("baseline"))
    plant = VehicleIntegrator(model, dt=0.1, state=np.r_[np.zeros(6), 19.99, np.zeros(5)], backend="compiled")
    with pytest.raises(DivergenceError, match="state u"):
        plant.step(np.radians([35.0, 35.0, 0.0, 0.0]), external=np.array([1e5, 0, 0, 0, 0, 0]))
    assert plant.state[6] == 19.99 and plant.steps == 0


@pytest.mark.unit
def test_the_backend_is_chosen_by_argument_or_environment(monkeypatch):
    model = VehicleModel(load_vehicle_config("baseline"))
    with pytest.raises(ValueError, match="backend must be one of"):
        VehicleIntegrator(model, backend="fortran")
    monkeypatch.setenv("SEAPUP_PLANT", "numpy")
    assert default_backend() == "numpy" and not VehicleIntegrator(model).compiled
    monkeypatch.setenv("SEAPUP_PLANT", "compiled")
    assert default_backend() == "compiled" and VehicleIntegrator(model).compiled
    monkeypatch.setenv("SEAPUP_PLANT", "gpu")
    with pytest.raises(ValueError, match="SEAPUP_PLANT must be one of"):
        default_backend()


# -- the umbilical (sec. 2.3.4, 3.8) --------------------------------------------------------------------------
def _cables(params, ship, length=None):
    from seapup_sim.umbilical import Umbilical
    mine, ref = Umbilical(params, ship, length), Umbilical(params, ship, length)
    mine.compiled, ref.compiled = True, False
    return mine, ref


@pytest.mark.unit
def test_the_compiled_umbilical_follows_the_reference_along_a_trajectory_with_bypasses():
    """A vehicle manoeuvring under the thesis's cable (weightless, and a heavy one that bypasses at low flow):
    every wrench, solution and warm start of the compiled cable is the reference's to 1e-12, including the
    switches into and out of the bypass."""
    from dataclasses import replace

    from seapup_sim.environment_config import load_environment
    base = load_environment().umbilical.params
    rng = np.random.default_rng(5)
    for params in (replace(base, attachment=(0.1, 0.05, -0.2)), replace(base, weight_per_length=2.0)):
        mine, ref = _cables(params, np.zeros(3))
        state = np.r_[5.0, -3.0, 60.0, 0.05, -0.1, 0.3, 0.4, 0.1, 0.0, 0.02, -0.03, 0.1]
        reasons = set()
        for k in range(400):
            state = state + np.r_[rng.normal(0, 0.3, 3), rng.normal(0, 0.02, 3), rng.normal(0, 0.05, 6)]
            state[6:9] *= 0.97
            current = rng.normal(0, 0.2, 3) * np.array([1, 1, 0]) if k % 4 else None
            if 150 <= k < 170:   # stopped in still water: the bypass, then back
                state[6:12], current = 0.0, None
            a, b = mine.wrench(state, current), ref.wrench(state, current)
            scale = max(1.0, float(np.max(np.abs(b))))
            assert np.max(np.abs(a - b)) <= 1e-12 * scale, (k, a, b)
            sa, sb = mine.solution, ref.solution
            assert sa.bypassed == sb.bypassed and sa.length == pytest.approx(sb.length, rel=1e-14)
            reasons.add(sb.bypassed.split(" ")[0] if sb.bypassed else "solved")
            if not sb.bypassed:
                assert abs(sa.c0 - sb.c0) <= 1e-12 * max(1.0, abs(sb.c0)) and abs(sa.lam - sb.lam) <= 1e-12 * sb.lam
                assert np.allclose(sa.shape(20), sb.shape(20), rtol=0, atol=1e-9)
            assert (mine._guess is None) == (ref._guess is None)
        assert "solved" in reasons and len(reasons) >= 2, reasons   # both paths met a bypass and a solution


@pytest.mark.unit
def test_the_compiled_umbilical_refuses_what_the_reference_refuses():
    from seapup_sim.environment_config import load_environment
    from seapup_sim.umbilical import UmbilicalError
    params = load_environment().umbilical.params
    state = np.r_[0.0, 0.0, 50.0, np.zeros(3), 0.5, np.zeros(5)]
    messages = []
    for cable in _cables(params, np.zeros(3), length=40.0):
        with pytest.raises(UmbilicalError) as caught:
            cable.wrench(state)
        messages.append(str(caught.value))
    assert messages[0] == messages[1] and "shorter than the distance" in messages[0]


@pytest.mark.unit
@pytest.mark.parametrize("vehicle", ["baseline", "bluerov2_heavy"])
@pytest.mark.parametrize("with_current", [False, True])
def test_a_period_in_one_call_is_its_steps_one_at_a_time(vehicle, with_current):
    """Simulation.advance's one kernel call per control period (VehicleIntegrator.step_period) against the same
    period stepped a physics step at a time (its ``_advance_steps``): the same states, actuators, accelerations
    and current, bit for bit, over a flight with commands swept between the inputs' limits, the thesis's
    Gauss-Markov current (sec. 3.9) drawn for each step on the second, and events -- at a period's start and in
    the middle of one, where advance steps one at a time -- changing the fouling and the current."""
    from seapup_sim.simulation import Event, Simulation
    from seapup_sim.current import CurrentParams
    environment = {"sensors": "ideal", "current": {"enabled": with_current, "mean_speed": 0.26, "speed_std": 0.086,
                                                   "mean_direction": 0.3, "direction_std": 0.35, "break_time": 10.0}}
    count = VehicleModel(load_vehicle_config(vehicle)).thrusters.count
    events = [Event(6.0, "thruster_efficiency", [0.5] + [1.0] * (count - 1)),
              Event(12.1, "current", CurrentParams(0.1, 0.02, -1.0, 0.1, 10.0))]
    start = np.r_[0.0, 0.0, 30.0, np.zeros(9)]
    fast, slow = (Simulation.from_config(vehicle, environment, seed=3, dt=0.1, control_period=0.3, state=start,
                                         events=events) for _ in range(2))
    rng = np.random.default_rng(7)
    limit = fast.model.pitch_limit
    command = np.zeros(4)
    for k in range(300):
        if k % 10 == 0:
            command = rng.uniform(-1.1, 1.1, 4) * limit
        fast.advance(command)
        slow._advance_steps(command)
        assert np.array_equal(fast.plant.state, slow.plant.state) and np.array_equal(fast.plant.pitch, slow.plant.pitch)
        assert np.array_equal(fast.acceleration, slow.acceleration) and fast.t == slow.t
        assert np.array_equal(fast._current_ned(), slow._current_ned())
    assert fast.plant.steps == 900 and np.abs(fast.plant.state[6:9]).max() > 0.1   # it flew
    assert fast.model.thrusters.efficiency[0] == 0.5 and fast.current is not None   # the events happened
    assert np.abs(fast._current_ned()).max() > 0.05


@pytest.mark.unit
def test_a_period_that_diverges_in_a_simulation_leaves_it_as_the_steps_one_at_a_time_do():
    """A period whose second step leaves the envelope: advance raises as the reference does, with the plant at
    the step before, the current stepped once per step taken, the acceleration of the last step taken."""
    from seapup_sim.simulation import Simulation
    environment = {"sensors": "ideal", "current": {"enabled": True, "mean_speed": 0.26, "speed_std": 0.086,
                                                   "mean_direction": 0.3, "direction_std": 0.35, "break_time": 10.0}}
    start = np.r_[0.0, 0.0, 30.0, 0.0, np.radians(78.0), 0.0, 0.0, 0.0, 0.0, 0.0, 0.9, 0.0]   # pitching up fast
    fast, slow = (Simulation.from_config("baseline", environment, seed=3, dt=0.1, control_period=1.0, state=start)
                  for _ in range(2))
    with pytest.raises(DivergenceError) as a:
        fast.advance(np.zeros(4))
    with pytest.raises(DivergenceError) as b:
        slow._advance_steps(np.zeros(4))
    assert str(a.value) == str(b.value) and fast.plant.steps == slow.plant.steps == 2
    assert np.array_equal(fast.plant.state, slow.plant.state) and np.array_equal(fast.acceleration, slow.acceleration)
    assert np.array_equal(fast._current_ned(), slow._current_ned())
    assert fast.current.rng.bit_generator.state == slow.current.rng.bit_generator.state


@pytest.mark.unit
@pytest.mark.parametrize("curve", [
    {"polynomial": [0.0, 20.0, 0.0, 10.0], "deadband": 0.1},                 # Horner's branch, with a deadband
    {"table": [[-1.0, -30.0], [-0.9, -30.2], [0.0, 0.0], [0.9, 30.2], [1.0, 30.0]], "deadband": 0.05}])  # turns back
def test_fixed_pitch_curves_of_every_branch_are_the_reference_s(curve):
    """The kernels' fixed-pitch thrust for a polynomial that does not turn back (Horner's scheme) and for a table
    that does (its monotone envelope), each with a deadband, against the NumPy reference on random states."""
    config = load_vehicle_config("bluerov2_heavy")
    deadband = curve.pop("deadband")
    config["thrusters"]["thrust_curve"] = curve
    config["thrusters"]["deadband"] = deadband
    model = VehicleModel(config)
    packed = compiled.pack(model)
    assert packed.scalars[12] == (compiled.CURVE_POLYNOMIAL if "polynomial" in curve else compiled.CURVE_TABLE)
    assert model.thrusters.curve._droops == ("table" in curve)
    rng = np.random.default_rng(3)
    worst = 0.0
    for k in range(200):
        state, pitch, current, external = _random_inputs(rng, model)
        ours = compiled.derivatives(packed, model.thrusters.efficiency, state, pitch, current, external)
        ref = model.derivatives(state, pitch, current, external)
        worst = max(worst, float(np.max(np.abs(ours - ref) / np.maximum(1.0, np.abs(ref)))))
    assert worst <= 1e-12, worst


@pytest.mark.unit
def test_a_period_that_diverges_keeps_the_steps_before_it_and_says_where():
    plant = VehicleIntegrator(vehicle_model(load_vehicle_config("baseline")), backend="compiled")
    plant.state[4], plant.state[10] = np.radians(76.0), 1.0   # pitching up at 1 rad/s, 9 deg from the envelope
    twin = VehicleIntegrator(vehicle_model(load_vehicle_config("baseline")), backend="compiled",
                             state=plant.state, pitch=plant.pitch)
    with pytest.raises(DivergenceError, match="theta") as one_call:
        plant.step_period(np.zeros(4), 50)
    with pytest.raises(DivergenceError, match="theta") as one_at_a_time:   # the same steps, one call each
        for _ in range(50):
            twin.step(np.zeros(4))
    assert plant.steps == twin.steps == 2 and str(one_call.value) == str(one_at_a_time.value)
    assert np.array_equal(plant.state, twin.state) and abs(plant.state[4]) <= np.radians(85.0)
    with pytest.raises(ValueError, match="shape"):
        plant.step_period(np.zeros(4), 2, np.zeros((3, 3)))


_FLIGHTS = r'''
import numpy as np
from seapup_sim import compiled
compiled.warm()
kernels = ("rk4_checked", "rk4_period", "rk4_batch", "rhs")
before = {k: len(getattr(compiled, k).signatures) for k in kernels}
from seapup_common.contract import Command
from seapup_sim.simulator_core import SimulatorConfig, SimulatorCore
from seapup_sim.simulation import Simulation
current = {"enabled": True, "mean_speed": 0.2, "speed_std": 0.05, "mean_direction": 0.0, "direction_std": 0.1}
for vehicle in ("baseline", "bluerov2_heavy"):
    for environment in ({}, {"current": current}):
        core = SimulatorCore(SimulatorConfig(vehicle, 0, environment=environment), np.r_[0, 0, 30.0, np.zeros(9)])
        for k in range(3):   # the simulator node's path: a command through the gate, a period
            core.submit(np.array(core.hover, float), core.t_ns, lockstep=True)
            core.step()
        sim = Simulation.from_config(vehicle, environment, state=np.r_[0, 0, 30.0, np.zeros(9)])
        for k in range(3):   # a run's path: a law's Command, its pitches read-only
            sim.advance(Command(np.zeros(4), 0.0).blade_pitch)
            sim.plant.step(Command(np.zeros(4), 0.0).blade_pitch)
after = {k: len(getattr(compiled, k).signatures) for k in kernels}
print(before == after, before, after)
'''


@pytest.mark.process
def test_every_kernel_call_of_a_flight_is_a_type_warm_compiled():
    """The simulator node's and an in-process run's calls of the kernels, for both kinds of thrusters, with and
    without a current, are of the argument types ``warm`` (``./seapup setup``) compiles: a type it does not is
    compiled at its first call, seconds in which a lockstep simulator answers nobody (a fresh clone's demo once
    failed so: a period's still-water currents were a read-only array). In a process of its own, so no earlier
    call has loaded another type."""
    import subprocess
    import sys
    done = subprocess.run([sys.executable, "-c", _FLIGHTS], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("True"), done.stdout
