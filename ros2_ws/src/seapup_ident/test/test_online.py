"""Online identification (seapup_ident.online): readings joined by stamp as the simulator publishes them.

Truth: a known first-order system driven by the *command* held over each sample interval, published
the way the simulator does -- at t_k the outputs y(t_k) and the pitch the thrusters have at t_k,
which is the previous interval's command. Joined correctly the estimator recovers the system
exactly; the same record read by ``held_inputs`` and fitted offline gives the same model.
"""
import numpy as np
import pytest

from seapup_ident.armax import ArmaxOrders
from seapup_ident.identify import IdentificationData, fit
from seapup_ident.online import OnlineIdentifier, held_inputs, input_stamp
from seapup_ident.prbs import prbs
from seapup_ident.recursive import Forgetting

pytestmark = pytest.mark.unit

T_NS = 200_000_000
PHI = np.diag([0.9, 0.8, 0.85, 0.7])
DELTA = np.array([[0.2, 0.2, 0.0, 0.0], [0.0, 0.0, 0.1, -0.1], [0.0, 0.0, -0.3, -0.3], [0.4, -0.4, 0.0, 0.05]])


def published(n=400):
    """(stamps, y, applied, command): y(k+1) = PHI y(k) + DELTA command(k); applied(k) = command(k-1)."""
    command = prbs(n, clock=3, amplitude=0.2, n_inputs=4, nbits=8)
    y = np.zeros((n, 4))
    for k in range(n - 1):
        y[k + 1] = PHI @ y[k] + DELTA @ command[k]
    applied = np.vstack([np.zeros((1, 4)), command[:-1]])
    return np.arange(n, dtype=np.int64) * T_NS, y, applied, command


def online(stamps, y, applied, order="applied first", skip=()):
    ident = OnlineIdentifier(ArmaxOrders(4, 4, 1, 1, 0), "ls", ("u", "v", "w", "r"), forgetting=Forgetting(1.0),
                             p0=1e6)
    used = []
    for k, stamp in enumerate(stamps):
        readings = [("applied", applied[k]), ("velocity", y[k])]
        if order == "velocity first":
            readings.reverse()
        for kind, values in readings:
            if (kind, k) not in skip:
                used += ident.add(kind, int(stamp), values)
    return ident, used


@pytest.mark.parametrize("order", ["applied first", "velocity first"])
def test_the_next_samples_pitch_is_the_input_and_recovers_the_system(order):
    stamps, y, applied, command = published()
    ident, used = online(stamps, y, applied, order)
    assert len(used) == len(stamps) - 1                        # the last interval is never read
    assert [s.input_stamp_ns - s.stamp_ns for s in used] == [T_NS] * len(used)
    np.testing.assert_array_equal(np.array([s.u for s in used]), command[:-1])
    model = ident.estimator.model
    np.testing.assert_allclose(-model.A[0], PHI, atol=1e-6)
    np.testing.assert_allclose(model.B[0], DELTA, atol=1e-6)
    # offline: the same join, the same estimator, the same model
    u = held_inputs(stamps, dict(zip(stamps.tolist(), applied)), 0.2)
    assert np.all(np.isnan(u[-1])) and np.array_equal(u[:-1], command[:-1])
    offline = fit(IdentificationData(y[:-1], u[:-1], stamps[:-1] * 1e-9), ArmaxOrders(4, 4, 1, 1, 0), "ls",
                  forgetting=Forgetting(1.0), p0=1e6)
    np.testing.assert_allclose(offline.model.theta(), ident.estimator.theta, rtol=1e-9, atol=1e-12)


def test_the_pitch_at_the_same_stamp_is_one_sample_late():
    """What the join avoids: the pitch read at t_k as u(t_k) delays every input by a sample, and a
    first-order model cannot explain the data any more."""
    stamps, y, applied, _ = published()
    late = fit(IdentificationData(y, applied, stamps * 1e-9), ArmaxOrders(4, 4, 1, 1, 0), "ls",
               forgetting=Forgetting(1.0), p0=1e6, passes=2)
    assert np.max(np.abs(-late.model.A[0] - PHI)) > 0.05 or np.max(late.loss / np.var(y, axis=0)) > 1e-3


def test_a_missing_pitch_drops_the_sample_it_measured_and_restarts_the_regressor():
    stamps, y, applied, command = published()
    ident, used = online(stamps, y, applied, skip={("applied", 200)})
    assert 199 not in [s.stamp_ns // T_NS for s in used]       # its interval was not read
    assert len(used) == len(stamps) - 2 and ident.counts["dropped"] == 1 and ident.counts["segments"] == 2
    np.testing.assert_allclose(ident.estimator.model.B[0], DELTA, atol=1e-6)


def test_input_stamp_needs_the_next_sample_within_one_and_a_half_periods():
    assert input_stamp(0, [0, T_NS, 2 * T_NS], 0.2) == T_NS
    assert input_stamp(0, [0, 2 * T_NS], 0.2) is None           # a sample missing between
    assert input_stamp(5 * T_NS, [0, T_NS], 0.2) is None        # nothing after it yet


def test_online_rpem_with_a_weakened_filter_equals_the_offline_fit():
    stamps, y, applied, _ = published(300)
    rng = np.random.default_rng(0)
    y = y + 0.01 * rng.normal(size=y.shape)
    orders = ArmaxOrders(4, 4, 1, 1, 1)
    ident = OnlineIdentifier(orders, "rpem", ("u", "v", "w", "r"), forgetting=Forgetting.schedule(0.6, 0.9),
                             filter_weakening=(0.1, 0.98))
    for k, stamp in enumerate(stamps):
        ident.add("velocity", int(stamp), y[k])
        ident.add("applied", int(stamp), applied[k])
    u = held_inputs(stamps, dict(zip(stamps.tolist(), applied)), 0.2)
    offline = fit(IdentificationData(y[:-1], u[:-1], stamps[:-1] * 1e-9), orders, "rpem",
                  forgetting=Forgetting.schedule(0.6, 0.9), filter_weakening=(0.1, 0.98))
    assert ident.estimator.filter_weakening is not None
    np.testing.assert_allclose(offline.model.theta(), ident.estimator.theta, rtol=1e-9, atol=1e-12)


def test_a_reading_no_vehicle_gives_or_stamped_far_ahead_is_refused_and_changes_nothing():
    """Hostile run: one finite 1e200 reading made every later model non-finite; one sample stamped 1e6 s
    ahead stopped the identification (every real one after it was late). Both are refused (counted),
    and the identification goes on to the same model as without them."""
    from seapup_ident.recursive import DataError
    stamps, y, applied, _ = published()
    clean, _ = online(stamps, y, applied)
    ident = OnlineIdentifier(ArmaxOrders(4, 4, 1, 1, 0), "ls", ("u", "v", "w", "r"), forgetting=Forgetting(1.0),
                             p0=1e6)
    for k, stamp in enumerate(stamps):
        if k == 100:
            with pytest.raises(DataError, match="beyond what the vehicle can do"):
                ident.add("velocity", int(stamp), [1e200, 0, 0, 0])
            with pytest.raises(DataError, match="ahead of the graph's time"):
                ident.add("velocity", int(stamp) + 10**6 * 10**9, y[k])
        ident.add("applied", int(stamp), applied[k])
        ident.add("velocity", int(stamp), y[k])
    assert ident.counts["rejected"] == 2 and ident.counts["used"] == clean.counts["used"]
    assert np.all(np.isfinite(ident.estimator.theta))
    np.testing.assert_allclose(ident.estimator.theta, clean.estimator.theta, rtol=1e-12, atol=1e-15)


def test_a_stream_that_lags_another_by_more_than_a_minute_is_not_a_reset():
    """An executor on a loaded machine may take one topic's queue in long runs: 80 s of velocity readings, two
    seconds of applied pitches, the next 80 s of velocity, then the rest of the pitches. Each stream keeps its own
    graph's time, so the lagging stream's stamps (more than a minute behind the leading one's) are not read as a
    simulator reset -- with one shared time, the next velocity readings then looked 78 s ahead and were refused
    -- and every sample is used, as with the readings interleaved."""
    stamps, y, applied, _ = published(800)
    clean, _ = online(stamps, y, applied)
    ident = OnlineIdentifier(ArmaxOrders(4, 4, 1, 1, 0), "ls", ("u", "v", "w", "r"), forgetting=Forgetting(1.0),
                             p0=1e6)
    for kind, taken in (("velocity", range(0, 400)), ("applied", range(0, 10)), ("velocity", range(400, 800)),
                        ("applied", range(10, 800))):   # each topic's queue taken in long runs
        for k in taken:
            ident.add(kind, int(stamps[k]), y[k] if kind == "velocity" else applied[k])
    assert ident.counts["rejected"] == 0
    assert ident.counts["used"] == clean.counts["used"] > 790
    np.testing.assert_allclose(ident.estimator.theta, clean.estimator.theta, rtol=1e-9, atol=1e-12)


def test_a_stream_s_first_reading_far_ahead_of_the_others_is_refused():
    """Each stream keeps its own graph's time, but a stream's first reading is judged by the time the others have
    reached: an applied pitch stamped 10^6 s ahead of the velocity readings, as the first of its stream, is refused
    (counted) and the identification goes on with the real ones."""
    from seapup_ident.recursive import DataError
    stamps, y, applied, _ = published(50)
    ident = OnlineIdentifier(ArmaxOrders(4, 4, 1, 1, 0), "ls", ("u", "v", "w", "r"), forgetting=Forgetting(1.0),
                             p0=1e6)
    ident.add("velocity", int(stamps[0]), y[0])
    with pytest.raises(DataError, match="ahead of the graph's time"):
        ident.add("applied", int(stamps[0]) + 10**6 * 10**9, applied[0])
    for k, stamp in enumerate(stamps):
        ident.add("applied", int(stamp), applied[k])
        if k:
            ident.add("velocity", int(stamp), y[k])
    assert ident.counts["rejected"] == 1 and ident.counts["used"] >= 48
