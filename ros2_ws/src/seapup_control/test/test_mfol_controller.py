"""The MFOL velocity controller against the closed-loop analysis, saturation and bad input."""
import numpy as np
import pytest

from seapup_common.contract import Command, ContractError, Measurement, Reference, VelocityController
from seapup_control.closed_loop import closed_loop_discrete
from seapup_control.mfol import LoopPoles, MFOLModel, design
from seapup_control.mfol_controller import GainSchedule, MFOLController

T = 0.2


def plant(seed=11):
    """An exact 4-loop MFOL plant y+ = Φ y + Δ u (outputs u, v, w, r), stable."""
    rng = np.random.default_rng(seed)
    while True:
        b0inv = np.diag([0.05, 0.02, 0.03, 0.3]) + 0.005 * rng.normal(size=(4, 4))
        b1inv = np.diag([0.5, 0.3, 0.2, 2.0]) + 0.05 * rng.normal(size=(4, 4))
        phi = np.eye(4) - b0inv @ np.linalg.inv(b1inv)
        if np.max(np.abs(np.linalg.eigvals(phi))) < 0.97:
            return phi, b0inv, MFOLModel.from_state_space(phi, b0inv, np.eye(4), T)


def measure(t, y):
    return Measurement.build(t, velocity=y[:3], rates=(0.0, 0.0, y[3]))


def fly(controller, phi, delta, references, y=None):
    y = np.zeros(4) if y is None else y
    ys, us = [], []
    for k, r in enumerate(references):
        u = controller.update(k * T, measure(k * T, y), Reference(r)).blade_pitch
        ys.append(y.copy())
        us.append(u)
        y = phi @ y + delta @ u
    return np.array(ys), np.array(us)


def test_the_controller_flies_exactly_the_analysed_closed_loop():
    """Unsaturated, the contract implementation and eq. 5.14 give the same outputs, sample by sample."""
    phi, delta, model = plant()
    gains = design(model, LoopPoles([0.8, 0.85, 0.75, 0.65], [0.8, 0.85, 0.75, 0.65], T))
    ctl = MFOLController(gains, limit=100.0)
    assert isinstance(ctl, VelocityController)
    ctl.reset(Command(np.zeros(4)))
    r = np.array([0.3, -0.1, 0.05, 0.2])
    ys, _ = fly(ctl, phi, delta, [r] * 120)
    loop = closed_loop_discrete(phi, delta, np.eye(4), gains.K_int, gains.K_err, T)
    state = np.zeros(8)
    for k in range(120):
        np.testing.assert_allclose(ys[k], loop.c_aug @ state, atol=1e-12)
        state = loop.phi @ state + loop.gamma @ r
    np.testing.assert_allclose(ys[-1], r, atol=1e-6)  # integral action: no steady-state error


def test_bumpless_start_from_the_applied_command_and_the_offset():
    phi, delta, model = plant()
    u0 = np.radians([-3.383, -3.383, -13.098, -13.098])  # eq. 5.2's quiescent setting as the offset
    model = MFOLModel(model.B0inv, model.B1inv, T, u0=u0)
    ctl = MFOLController(design(model, LoopPoles([0.8] * 4, [0.8] * 4, T)))
    applied = np.radians([10.0, -5.0, 3.0, 20.0])
    ctl.reset(Command(applied))
    y = np.array([0.1, 0.0, 0.02, 0.0])
    first = ctl.update(0.0, measure(0.0, y), Reference(y)).blade_pitch  # zero error: no bump
    np.testing.assert_allclose(first, applied, atol=1e-12)


def test_a_scheduled_controller_switched_in_at_speed_starts_bumpless():
    """Switched in while moving: the first command is the applied one plus only the proportional
    term on that sample's error (as at zero speed), not the schedule's offset and gain difference."""
    phi, delta, model = plant()
    slow = design(model, LoopPoles([0.8] * 4, [0.8] * 4, T))
    fast = design(MFOLModel(model.B0inv * 1.5, model.B1inv * 1.2, T, u0=np.radians([1.0, 1.0, -5.0, -5.0])),
                  LoopPoles([0.8] * 4, [0.8] * 4, T))
    ctl = MFOLController(GainSchedule([(0.0, slow), (0.7, fast)]))
    applied = np.radians([12.0, 8.0, -6.0, -9.0])
    ctl.reset(Command(applied))
    y = np.array([0.35, 0.02, -0.01, 0.05])
    r = y + np.array([0.01, -0.005, 0.005, 0.002])  # small error: the P term stays inside the blade limits
    first = ctl.update(0.0, measure(0.0, y), Reference(r)).blade_pitch
    _, k_err = ctl.schedule.gains_at(y[0])
    np.testing.assert_allclose(first, applied + k_err @ (r - y), atol=1e-12)
    ctl.reset(Command(applied))
    np.testing.assert_allclose(ctl.update(0.0, measure(0.0, y), Reference(y)).blade_pitch, applied, atol=1e-12)


def test_anti_windup_leaves_saturation_at_once_where_a_plain_integrator_stays():
    phi, delta, model = plant()
    gains = design(model, LoopPoles([0.8] * 4, [0.8] * 4, T))
    limit = np.radians(35.0)
    references = [np.array([1.5, 0, 0, 0])] * 60 + [np.zeros(4)] * 60  # unreachable surge, then stop

    class Plain(MFOLController):  # eq. 4.11 as written, output clipped, integrators free
        def update(self, t, measurement, reference):
            e = reference.velocity - measurement.body_velocity()
            k_int, k_err = self.schedule.gains_at(0.0)
            raw = k_int @ self.q + k_err @ e + self.schedule.offset_at(0.0)
            self.q = self.q + e
            return Command(np.clip(raw, -self.limit, self.limit), stamp=t)

    runs = {}
    for name, cls in (("aw", MFOLController), ("plain", Plain)):
        ctl = cls(gains, limit=limit)
        ctl.reset(Command(np.zeros(4)))
        runs[name] = fly(ctl, phi, delta, references)
    for name, (_, us) in runs.items():
        assert np.all(np.abs(us) <= limit + 1e-12)
        assert np.any(np.isclose(np.abs(us[:60]), limit)), name  # both saturate while chasing 1.5 m/s
    def saturated_after_stop(us):
        return int(np.sum(np.any(np.isclose(np.abs(us[60:]), limit), axis=1)))
    assert saturated_after_stop(runs["aw"][1]) <= 3
    assert saturated_after_stop(runs["plain"][1]) >= saturated_after_stop(runs["aw"][1]) + 10
    # and the vehicle comes back to rest sooner
    assert np.abs(runs["aw"][0][-1]).max() < 0.01 < np.abs(runs["plain"][0][75]).max()
    # anti_windup=False is the thesis's law as written: the plain integrator above, sample for sample
    thesis = MFOLController(gains, limit=limit, anti_windup=False)
    thesis.reset(Command(np.zeros(4)))
    ys, us = fly(thesis, phi, delta, references)
    np.testing.assert_allclose(us, runs["plain"][1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ys, runs["plain"][0], rtol=0, atol=1e-12)


def test_gain_schedule_interpolates_gains_on_measured_surge_and_the_offset_on_the_reference():
    phi, delta, model = plant()
    slow = design(MFOLModel(model.B0inv, model.B1inv, T, u0=np.zeros(4)), LoopPoles([0.8] * 4, [0.8] * 4, T))
    fast_model = MFOLModel(model.B0inv * 1.3, model.B1inv * 0.7, T, y0=[0.7, 0, 0, 0], u0=np.full(4, 0.25))
    fast = design(fast_model, LoopPoles([0.8] * 4, [0.8] * 4, T))
    schedule = GainSchedule([(0.7, fast), (0.0, slow)])  # any order
    k_int, k_err = schedule.gains_at(0.35)
    np.testing.assert_allclose(k_int, (slow.K_int + fast.K_int) / 2)
    np.testing.assert_allclose(k_err, (slow.K_err + fast.K_err) / 2)
    np.testing.assert_allclose(schedule.offset_at(0.175), np.full(4, 0.0625))
    np.testing.assert_allclose(schedule.gains_at(-0.2)[0], slow.K_int)  # held beyond the ends
    np.testing.assert_allclose(schedule.gains_at(2.0)[1], fast.K_err)
    ctl = MFOLController(schedule)
    ctl.reset(Command(np.zeros(4)))
    ctl.update(0.0, measure(0.0, np.zeros(4)), Reference(np.zeros(4)))  # started at rest
    cmd = ctl.update(T, measure(T, np.array([0.7, 0, 0, 0])), Reference([0.7, 0, 0, 0])).blade_pitch
    np.testing.assert_allclose(cmd, np.full(4, 0.25))  # zero error at 0.7 m/s: the fast offset, fast gains


def test_bad_measurements_and_references_change_nothing():
    phi, delta, model = plant()
    ctl = MFOLController(design(model, LoopPoles([0.8] * 4, [0.8] * 4, T)))
    ctl.reset(Command(np.radians([5, 5, 0, 0])))
    before = ctl.q.copy()
    with pytest.raises(ContractError, match="velocity"):
        ctl.update(0.0, Measurement.build(0.0, rates=(0, 0, 0)), Reference())
    with pytest.raises(ContractError):
        Measurement.build(0.0, velocity=(np.nan, 0, 0), rates=(0, 0, 0))
    with pytest.raises(ContractError):
        Reference([0.1, 0.2, np.inf, 0])
    with pytest.raises(ContractError, match="Reference"):
        ctl.update(0.0, measure(0.0, np.zeros(4)), [0.1, 0, 0, 0])
    np.testing.assert_array_equal(ctl.q, before)


@pytest.mark.unit
def test_the_law_s_solve_is_numpy_s_bit_for_bit_and_refuses_a_singular_matrix():
    """mfol_controller.solve (LAPACK's dgesv called directly) against numpy.linalg.solve, which calls the same
    routine: equal bit for bit over random 4 x 4 systems from well to badly scaled; a singular matrix refused
    as numpy refuses it."""
    from seapup_control.mfol_controller import solve
    rng = np.random.default_rng(11)
    for _ in range(2000):
        a = rng.normal(size=(4, 4)) * rng.uniform(1e-3, 1e3) + np.eye(4) * rng.uniform(-2.0, 5.0)
        b = rng.normal(size=4) * rng.uniform(1e-3, 1e3)
        assert np.array_equal(solve(a, b), np.linalg.solve(a, b))
    singular = np.ones((4, 4))
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.solve(singular, np.ones(4))
    with pytest.raises(np.linalg.LinAlgError, match="Singular"):
        solve(singular, np.ones(4))


@pytest.mark.unit
def test_the_schedule_interpolates_each_gain_as_eq_4_41_reads_bit_for_bit():
    """sec. 4.6's linear interpolation between operating points, K(u) = (1 - w) K_i + w K_j with w the surge
    speed's fraction of the way from point i to j (clamped at the ends): the schedule's gains and offsets equal
    that formula evaluated matrix by matrix, bit for bit, at speeds between, on and beyond the points."""
    from seapup_control.mfol import TwoTermGains
    rng = np.random.default_rng(5)
    speeds = [0.0, 0.35, 0.7, 1.2]
    gains = [TwoTermGains(rng.normal(size=(4, 4)), rng.normal(size=(4, 4)), rng.normal(size=4), np.zeros(4), 0.2)
             for _ in speeds]
    schedule = GainSchedule(list(zip(speeds, gains)))
    for u in [*rng.uniform(-0.5, 1.6, 200), *speeds, 0.35 + 1e-12]:
        if u <= speeds[0] or u >= speeds[-1]:
            i = j = 0 if u <= speeds[0] else len(speeds) - 1
            w = 0.0
        else:
            j = int(np.searchsorted(speeds, u))
            i, w = j - 1, (u - speeds[j - 1]) / (speeds[j] - speeds[j - 1])
        k_int, k_err = schedule.gains_at(float(u))
        assert np.array_equal(k_int, (1 - w) * gains[i].K_int + w * gains[j].K_int), u
        assert np.array_equal(k_err, (1 - w) * gains[i].K_err + w * gains[j].K_err), u
        assert np.array_equal(schedule.offset_at(float(u)), (1 - w) * gains[i].u0 + w * gains[j].u0), u


@pytest.mark.unit
@pytest.mark.parametrize("anti_windup", [True, False])
def test_the_compiled_law_flies_the_numpy_reference_bit_for_bit(anti_windup):
    """The compiled sample (seapup_control.compiled.mfol_sample, the default where numba is installed) against the
    NumPy reference (compiled=False) on the same closed loop: a four-point schedule crossed, reached and left at
    both ends by the measured surge and the reference's, the thrusters saturated and released, a bumpless restart
    half-way from another command -- every command, integrator state, diagnostic and saturation count equal bit
    for bit (the same BLAS and LAPACK calls in the same order)."""
    from seapup_control.mfol import TwoTermGains
    phi, delta, model = plant()
    designed = [design(MFOLModel(model.B0inv * scale, model.B1inv / scale, T, y0=[speed, 0, 0, 0],
                                 u0=np.full(4, 0.1 * speed)), LoopPoles([0.8] * 4, [0.8] * 4, T))
                for speed, scale in ((0.0, 1.0), (0.3, 1.2), (0.6, 1.4), (0.9, 1.6))]
    schedule = GainSchedule([(0.3 * i, TwoTermGains(g.K_int, g.K_err, g.u0, g.y0, T)) for i, g in enumerate(designed)])
    laws = {kind: MFOLController(schedule, limit=np.radians(35.0), anti_windup=anti_windup, compiled=kind)
            for kind in (True, False)}
    assert laws[True].kernel is not None and laws[False].kernel is None
    surge = np.concatenate([np.linspace(-0.2, 1.3, 80), np.full(40, 3.0), np.linspace(1.0, 0.0, 40)])
    references = [np.array([s, 0.05 * np.sin(k / 7), -0.02, 0.1 * np.cos(k / 5)]) for k, s in enumerate(surge)]
    flown = {}
    for kind, law in laws.items():
        law.reset(Command(np.radians([3.0, -2.0, 1.0, 0.5])))
        y, log = np.zeros(4), []
        for k, r in enumerate(references):
            if k == 100:
                law.reset(Command(np.radians([30.0, 35.0, -20.0, 10.0])))
            u = law.update(k * T, measure(k * T, y), Reference(r)).blade_pitch
            log.append((u.copy(), law.q.copy(), law.diagnostics()))
            y = phi @ y + delta @ u
        flown[kind] = log
    saturated = 0
    for (u1, q1, d1), (u0, q0, d0) in zip(flown[True], flown[False]):
        assert np.array_equal(u1, u0) and np.array_equal(q1, q0)
        assert d1 == d0
        saturated += any(d1["saturated"])
    assert saturated >= 10   # the thrusters were held at their limits, and the two agreed there too
