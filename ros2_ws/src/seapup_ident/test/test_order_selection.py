"""Order tests (seapup_ident.order_selection) on known systems (issue 14 (d)), and the PRBS.

Truths: the generating system's order (picked in most seeds, asserted as a rate over many seeds,
never every seed: AIC and the F-test make errors at a known rate), the chi-square/F quantiles from
scipy.stats, a maximum-length sequence's two-level, flat-spectrum properties.
"""
import numpy as np
import pytest

from seapup_ident.armax import ArmaxModel, ArmaxOrders
from seapup_ident.order_selection import aic, batch_least_squares, f_test, loss, residual_autocorrelation
from seapup_ident.prbs import prbs

pytestmark = pytest.mark.unit

SECOND_ORDER = ArmaxModel(ArmaxOrders(1, 1, 2, 2, 0), np.array([[[-1.2]], [[0.5]]]), np.array([[[0.6]], [[0.3]]]),
                          np.zeros((0, 1, 1)), np.array([0.2]))


def fits(seed, n=600):
    rng = np.random.default_rng(seed)
    u = prbs(n, clock=3, amplitude=1.0, nbits=8)
    u = u + 0.3 * rng.normal(size=u.shape)
    y = SECOND_ORDER.simulate(u, 0.2 * rng.normal(size=(n, 1)))
    out = {}
    for order in (1, 2, 3, 4):
        orders = ArmaxOrders(1, 1, order, order, 0)
        _, residuals = batch_least_squares(orders, y, u, skip=4)
        out[order] = (orders.n_params, residuals)
    return out


def test_aic_and_the_f_test_pick_the_true_order_in_most_seeds():
    picked_aic, picked_f = [], []
    for seed in range(40):
        results = fits(seed)
        scores = {k: aic(r, v)[0] for k, (v, r) in results.items()}
        picked_aic.append(min(scores, key=scores.get))
        order = 1  # raise the order while the larger model is significantly better (eq. 6.18, risk 5 %)
        while order < 4:
            (v_n, r_n), (v_m, r_m) = results[order], results[order + 1]
            if not f_test(loss(r_n), loss(r_m), v_n, v_m, len(r_m), alpha=0.05).larger_is_better[0]:
                break
            order += 1
        picked_f.append(order)
    assert np.mean(np.array(picked_aic) == 2) >= 0.75, picked_aic
    assert np.mean(np.array(picked_f) == 2) >= 0.8, picked_f
    assert 1 not in picked_aic and 1 not in picked_f   # too low an order is always caught


def test_residuals_of_the_true_order_are_white_and_of_too_low_an_order_are_not():
    results = fits(seed=123, n=2000)
    r2, band = residual_autocorrelation(results[2][1], max_lag=20)
    r1, _ = residual_autocorrelation(results[1][1], max_lag=20)
    assert r2[0, 0] == pytest.approx(1.0)
    assert np.mean(np.abs(r2[1:, 0]) < band) >= 0.9          # ~95 % inside the 2-sigma band (fig. 6.2)
    assert np.abs(r1[1:4, 0]).max() > 3 * band


def test_f_test_threshold_is_the_f_quantile():
    from scipy import stats
    result = f_test([1.2], [1.0], 5, 7, 500, alpha=0.05)
    assert result.threshold == pytest.approx(stats.f.ppf(0.95, 2, 493))
    assert result.statistic[0] == pytest.approx(0.2 * 493 / 2) and result.larger_is_better[0]


def test_prbs_levels_clock_and_decorrelated_inputs():
    u = prbs(2540, clock=10, amplitude=np.radians(10), n_inputs=4, offset=np.radians([-3, -3, -13, -13]))
    assert u.shape == (2540, 4)
    centred = u - np.radians([-3, -3, -13, -13])
    np.testing.assert_allclose(np.abs(centred), np.radians(10))
    switches = np.flatnonzero(np.diff(centred[:, 0]))
    assert np.all((switches + 1) % 10 == 0)                      # changes only on the clock
    bits = np.sign(centred[::10][:127])                         # one period of the 127-bit m-sequence
    assert abs(bits[:, 0].sum()) == 1                           # 64 of one level, 63 of the other
    correlation = bits.T @ bits / len(bits)
    assert np.abs(correlation - np.eye(4)).max() <= 1 / 127 + 1e-12   # m-sequence: -1/N off the peak


def test_the_f_quantile_and_the_ljung_box_tail_are_scipy_stats_own():
    """eq. 6.18's F quantile and the Ljung-Box chi-square tail come from scipy.special (scipy.stats' own
    functions, without its import): equal to scipy.stats.f.ppf and chi2.sf bit for bit over the tables' sizes."""
    import scipy.stats
    from seapup_ident.identify import residual_whiteness
    from seapup_ident.order_selection import f_test
    for d1 in (1, 2, 6, 12, 24):
        for d2 in (50, 288, 1488, 20000):
            for alpha in (0.01, 0.05, 0.1):
                n_small, n_samples = 10, 10 + d1 + d2
                threshold = f_test(np.ones(1), np.full(1, 0.5), n_small, n_small + d1, n_samples, alpha).threshold
                assert threshold == scipy.stats.f.ppf(1 - alpha, d1, d2), (d1, d2, alpha)
    import importlib.util
    from pathlib import Path
    spec = importlib.util.spec_from_file_location("identify_records", Path(__file__).parent / "test_identify.py")
    records = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(records)          # its known two-output system and records of it
    for seed, lags in ((0, 5), (1, 20)):
        table = residual_whiteness(records.TRUE, records.record(n=400, seed=seed), lags)
        assert table["p_value"] == scipy.stats.chi2.sf(table["ljung_box_q"], lags).tolist()
