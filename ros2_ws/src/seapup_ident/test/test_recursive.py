"""Recursive LS / ELS / RPEM (seapup_ident.recursive) against independent truths (issue 14 (a)-(c)).

- (a) exponentially weighted batch least squares with the prior P(0)^-1 (scipy.linalg.lstsq):
  recursive least squares minimises exactly that criterion, with fixed lambda and with the
  thesis's lambda(t) schedule (eq. 6.15, product weights); the UD form equals the plain form;
- (b) Ljung's ARMAX example: the LS limit from the process's exact second moments (discrete
  Lyapunov equation), ELS and RPEM to the true parameters;
- (c) RPEM's C(z^-1) stays inside the stability region.
"""
import importlib
import pickle

import numpy as np
import pytest
import scipy.linalg

from seapup_ident.armax import ArmaxModel, ArmaxOrders, is_stable, polynomial_roots
from seapup_ident.order_selection import regressors
from seapup_ident.recursive import DataError, Forgetting, Jacket, RecursiveArmax, ud_update

# unit by default (conftest.py); the long convergence test below is a sweep


def mimo_arx(seed=0, n=400):
    """A 2-output, 2-input ARX(2, 2) with offset, driven by white inputs, with noise."""
    rng = np.random.default_rng(seed)
    o = ArmaxOrders(ny=2, nu=2, na=2, nb=2, nc=0)
    A = np.array([[[-1.2, 0.1], [0.05, -0.9]], [[0.4, 0.0], [0.0, 0.2]]])
    B = np.array([[[1.0, 0.2], [0.1, 0.5]], [[0.3, 0.0], [0.2, -0.2]]])
    model = ArmaxModel(o, A, B, np.zeros((0, 2, 2)), np.array([0.3, -0.1]))
    u = rng.normal(size=(n, 2))
    return o, model, u, model.simulate(u, 0.1 * rng.normal(size=(n, 2)))


def weighted_batch(o, y, u, weights, prior_weight, p0):
    """argmin sum_t w_t |y_t - Theta^T phi_t|^2 + prior_weight |Theta|^2 / p0 (theta0 = 0), by lstsq."""
    phi = regressors(o, y, u)
    rows = np.vstack([np.sqrt(weights)[:, None] * phi, np.sqrt(prior_weight / p0) * np.eye(o.n_params)])
    target = np.vstack([np.sqrt(weights)[:, None] * y, np.zeros((o.n_params, o.ny))])
    return scipy.linalg.lstsq(rows, target)[0]


def run(estimator, y, u):
    for t in range(len(y)):
        estimator.step(y[t], u[t])
    return estimator.theta


def test_rls_with_forgetting_is_the_exponentially_weighted_batch_solution():
    o, _, u, y = mimo_arx()
    lam, p0, n = 0.98, 100.0, len(y)
    theta = run(RecursiveArmax(o, "ls", forgetting=Forgetting(lam), p0=p0), y, u)
    batch = weighted_batch(o, y, u, lam ** np.arange(n - 1, -1, -1), lam ** n, p0)
    np.testing.assert_allclose(theta, batch, rtol=1e-9, atol=1e-9)


def test_rls_with_the_thesis_schedule_is_the_product_weighted_batch_solution():
    o, _, u, y = mimo_arx(seed=1)
    p0, n = 100.0, len(y)
    lams, schedule = [], Forgetting.schedule(0.6, 0.9)   # eq. 6.15
    for _ in range(n):
        lams.append(schedule.next())
    lams = np.array(lams)
    assert lams[0] == pytest.approx(0.9 * 0.6 + 0.1) and lams[-1] == pytest.approx(1.0)
    # sample t is weighted by the product of the lambdas after it; the prior by all of them
    weights = np.array([np.prod(lams[t + 1:]) for t in range(n)])
    theta = run(RecursiveArmax(o, "ls", forgetting=Forgetting.schedule(0.6, 0.9), p0=p0), y, u)
    np.testing.assert_allclose(theta, weighted_batch(o, y, u, weights, np.prod(lams), p0), rtol=1e-9, atol=1e-9)


def test_the_ud_update_equals_the_plain_covariance_update():
    rng = np.random.default_rng(3)
    n = 7
    U, D = np.eye(n), np.full(n, 50.0)
    P = 50.0 * np.eye(n)
    for k in range(200):
        phi, lam = rng.normal(size=n), 0.95 + 0.05 * rng.random()
        gain = ud_update(U, D, phi, lam)
        plain_gain = P @ phi / (lam + phi @ P @ phi)
        P = (P - np.outer(plain_gain, phi @ P)) / lam
        np.testing.assert_allclose(gain, plain_gain, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose((U * D) @ U.T, P, rtol=1e-8, atol=1e-10 * np.abs(P).max())
    assert np.all(D > 0) and np.allclose(np.diag(U), 1.0) and np.allclose(np.tril(U, -1), 0.0)


LJUNG = ArmaxModel(ArmaxOrders(1, 1, 2, 2, 2, offset=False), np.array([[[-1.5]], [[0.7]]]),
                   np.array([[[1.0]], [[0.5]]]), np.array([[[-1.0]], [[0.2]]]), np.zeros(1))
TRUE = np.array([-1.5, 0.7, 1.0, 0.5, -1.0, 0.2])


def ljung_data(seed, n=20000):
    rng = np.random.default_rng(seed)
    u, e = rng.normal(size=(n, 1)), rng.normal(size=(n, 1))
    return LJUNG.simulate(u, e), u


def ls_limit():
    """The LS(2, 2) limit E[phi phi^T]^-1 E[phi y] for unit white u and e, from the stationary covariance
    of the state s(t) = (y(t), y(t-1), u(t), u(t-1), e(t), e(t-1)) (discrete Lyapunov equation)."""
    F = np.zeros((6, 6))
    F[0] = [1.5, -0.7, 1.0, 0.5, -1.0, 0.2]   # y(t+1) from s(t), plus e(t+1) and nothing from u(t+1)
    F[1, 0] = F[3, 2] = F[5, 4] = 1.0
    G = np.zeros((6, 2))
    G[0, 1] = G[4, 1] = 1.0                   # e(t+1) enters y(t+1) and the e slot
    G[2, 0] = 1.0                             # u(t+1)
    S = scipy.linalg.solve_discrete_lyapunov(F, G @ G.T)
    # phi(t+1) = (-y(t), -y(t-1), u(t), u(t-1)) = M s(t); y(t+1) = F[0] s(t) + e(t+1)
    M = np.zeros((4, 6))
    M[0, 0], M[1, 1], M[2, 2], M[3, 3] = -1, -1, 1, 1
    return np.linalg.solve(M @ S @ M.T, M @ S @ F[0])


@pytest.mark.sweep   # four estimators over a 20 000-sample record: 12 s, the longest of -m unit
def test_ljung_armax_ls_converges_to_its_biased_limit_els_and_rpem_to_the_truth():
    y, u = ljung_data(seed=7)
    limit = ls_limit()
    assert abs(limit[0] - TRUE[0]) > 0.2  # the example's point: LS is badly biased
    ls = run(RecursiveArmax(ArmaxOrders(1, 1, 2, 2, 0, offset=False), "ls", p0=100.0), y, u).ravel()
    np.testing.assert_allclose(ls, limit, atol=0.03)
    for method in ("els", "rpem"):
        theta = run(RecursiveArmax(LJUNG.orders, method, p0=100.0), y, u).ravel()
        np.testing.assert_allclose(theta, TRUE, atol=0.04, err_msg=method)
    # the thesis's weakened filter (Table 6.3: K(0) = 0.1, gamma = 0.98) only changes the start
    theta = run(RecursiveArmax(LJUNG.orders, "rpem", p0=100.0, filter_weakening=(0.1, 0.98)), y, u).ravel()
    np.testing.assert_allclose(theta, TRUE, atol=0.04, err_msg="rpem, weakened filter")


@pytest.mark.sweep   # eight estimators over 20 000-sample records: ~8 s
def test_rpem_converges_to_the_true_noise_polynomial_as_els_does():
    """y(t) = 0.8 y(t-1) + 0.5 u(t-1) + e(t) + 0.5 e(t-1), unit white u and e, 20 000 samples, four
    realisations: c_1's asymptotic standard error is sqrt((1 - c_1^2) / N) = 0.006. RPEM's c_1 lies within
    0.02 (3.3 of them) in every realisation and within 0.01 on average, as ELS's does. With the
    Levenberg-Marquardt term added to P instead of to its inverse the estimate kept a memory of about
    1 / sqrt(delta) = 1 000 samples and wandered: 0.540, 0.523, 0.540, 0.475 in these four."""
    model = ArmaxModel(ArmaxOrders(1, 1, 1, 1, 1, offset=False), np.array([[[-0.8]]]), np.array([[[0.5]]]),
                       np.array([[[0.5]]]), np.zeros(1))
    errors = {"els": [], "rpem": []}
    for seed in range(4):
        rng = np.random.default_rng(seed)
        u, e = rng.normal(size=(20000, 1)), rng.normal(size=(20000, 1))
        y = model.simulate(u, e)
        for method in errors:
            theta = run(RecursiveArmax(model.orders, method, p0=100.0), y, u).ravel()
            np.testing.assert_allclose(theta[:2], [-0.8, 0.5], atol=0.03, err_msg=method)
            errors[method].append(abs(theta[2] - 0.5))
    for method, e in errors.items():
        assert max(e) < 0.02 and np.mean(e) < 0.01, (method, e)


def test_rpem_filter_weakening_contracts_the_gradient_filter_at_first():
    """K(t) -> 1 as eq. 6.15: K(0) = 1 is plain RPEM bit for bit; a small K(0) starts nearer ELS's
    unfiltered gradient (its first steps differ from plain RPEM's, the same limit)."""
    y, u = ljung_data(seed=3, n=400)
    plain = RecursiveArmax(LJUNG.orders, "rpem", p0=100.0, keep_history=True)
    same = RecursiveArmax(LJUNG.orders, "rpem", p0=100.0, filter_weakening=(1.0, 0.98), keep_history=True)
    weak = RecursiveArmax(LJUNG.orders, "rpem", p0=100.0, filter_weakening=(0.1, 0.98), keep_history=True)
    for est in (plain, same, weak):
        run(est, y, u)
    np.testing.assert_array_equal(np.array(same.history["theta"]), np.array(plain.history["theta"]))
    assert not np.allclose(weak.history["theta"][50], plain.history["theta"][50])
    assert weak.filter_weakening.value == pytest.approx(1 - 0.9 * 0.98 ** 400)
    with pytest.raises(ValueError, match="RPEM option"):
        RecursiveArmax(LJUNG.orders, "els", filter_weakening=(0.1, 0.98))


@pytest.mark.sweep   # RPEM over a 30 000-sample record: ~10 s
def test_rpem_keeps_c_inside_the_stability_region():
    """A noise model with roots at |z| = 0.95 and a large P(0): unprojected steps leave the region. C is kept
    stable at every sample and still converges, where ELS, without the guarantee of a positive real
    1/C - 1/2 (at omega = pi, 1/C = 0.27), is still 0.2 off in c_1 after the same 30 000 samples; RPEM with
    the thesis's filter weakening (Table 6.3: K(0) = 0.1, gamma = 0.98), its gain falling as 1/t."""
    model = ArmaxModel(LJUNG.orders, LJUNG.A, LJUNG.B, np.array([[[-1.8]], [[0.9025]]]), np.zeros(1))
    rng = np.random.default_rng(11)
    u, e = rng.normal(size=(30000, 1)), rng.normal(size=(30000, 1))
    y = model.simulate(u, e)
    estimator = RecursiveArmax(model.orders, "rpem", p0=1e4, filter_weakening=(0.1, 0.98), keep_history=True)
    run(estimator, y, u)
    assert estimator.counts["projections"] > 0
    for theta in estimator.history["theta"]:
        assert is_stable(ArmaxModel.from_theta(model.orders, theta).C, estimator.stability_margin)
    errors = np.abs(np.array(estimator.history["theta"])[:, 4:, 0] - [-1.8, 0.9025]).max(axis=1)
    assert errors[-1] < 0.05
    els = RecursiveArmax(model.orders, "els", p0=1e4)
    run(els, y, u)
    assert abs(els.theta.ravel()[4] + 1.8) > 4 * errors[-1]   # a real test: ELS is still far off


def test_matrix_polynomial_roots_are_those_of_its_determinant():
    C = np.array([[[-0.5, 0.2], [0.1, -0.3]], [[0.06, 0.0], [0.01, 0.02]]])
    # det(I z^2 + C1 z + C2) as a polynomial in z, by sampling and fitting a degree-4 polynomial
    zs = np.linspace(-2, 2, 9)
    dets = [np.linalg.det(np.eye(2) * z ** 2 + C[0] * z + C[1]) for z in zs]
    expected = np.roots(np.polyfit(zs, dets, 4))
    np.testing.assert_allclose(np.sort_complex(polynomial_roots(C)), np.sort_complex(expected), atol=1e-8)


def test_bad_samples_are_refused_and_change_nothing():
    o, _, u, y = mimo_arx()
    estimator = RecursiveArmax(o, "els" if o.nc else "ls", p0=10.0)
    run(estimator, y[:50], u[:50])
    before, P = estimator.theta.copy(), estimator.covariance
    for bad_y, bad_u in (([np.nan, 0.0], [0.0, 0.0]), ([0.0, 0.0], [np.inf, 0.0]), ([0.0], [0.0, 0.0])):
        with pytest.raises(DataError):
            estimator.step(bad_y, bad_u)
    np.testing.assert_array_equal(estimator.theta, before)
    np.testing.assert_array_equal(estimator.covariance, P)
    assert estimator.counts["rejected"] == 3 and estimator.counts["samples"] == 50


def test_jacket_dead_zone_and_trace_limit():
    o, _, u, y = mimo_arx()
    # inside a dead zone wider than every prediction error nothing moves
    frozen = RecursiveArmax(o, "ls", p0=10.0, jacket=Jacket(dead_zone=1e6))
    run(frozen, y[:100], u[:100])
    assert np.all(frozen.theta == 0) and frozen.counts["dead_zone"] == 100
    # with no excitation, forgetting blows P up -- unless the trace limit stops forgetting
    still = np.zeros_like(u)
    free = RecursiveArmax(o, "ls", p0=1.0, forgetting=Forgetting(0.9))
    limited = RecursiveArmax(o, "ls", p0=1.0, forgetting=Forgetting(0.9), jacket=Jacket(max_trace=100.0))
    run(free, np.zeros_like(y)[:200], still[:200])
    run(limited, np.zeros_like(y)[:200], still[:200])
    assert free.trace[0] > 1e6 and limited.trace[0] <= 100.0 / 0.9 + 1e-9
    # the shared trace is trace P itself, each output's entry of trace; RPEM's outputs have a P each
    for estimator in (free, limited):
        assert estimator.shared_trace == pytest.approx(np.trace(estimator.covariance), rel=1e-12)
        assert np.all(estimator.trace == estimator.shared_trace)
    with pytest.raises(ValueError, match="per output"):
        _ = RecursiveArmax(ArmaxOrders(ny=1, nu=1, na=1, nb=1, nc=1), "rpem").shared_trace
    # a dead zone of zero, scalar or per output, never holds an update back
    for zone in (0.0, np.zeros(o.ny)):
        open_zone = RecursiveArmax(o, "ls", p0=10.0, jacket=Jacket(dead_zone=zone))
        run(open_zone, y[:50], u[:50])
        assert open_zone.counts["updates"] == 50 and open_zone.counts["dead_zone"] == 0


def test_observe_then_input_is_step_for_a_controller_that_chooses_u_after_seeing_y():
    """An explicit self-tuner (sec. 7.3) updates Theta with y(t) before it chooses u(t): observe(y) then
    input(u) must be exactly step(y, u); out of order is refused and changes nothing."""
    o, _, u, y = mimo_arx()
    whole, halves = RecursiveArmax(o, "els" if o.nc else "ls", p0=10.0), RecursiveArmax(o, "els" if o.nc else "ls", p0=10.0)
    for k in range(150):
        theta, y_hat = whole.step(y[k], u[k], update=k % 7 != 3)
        theta2, y_hat2 = halves.observe(y[k], update=k % 7 != 3)
        halves.input(u[k])
        np.testing.assert_array_equal(theta, theta2)
        np.testing.assert_array_equal(y_hat, y_hat2)
    np.testing.assert_array_equal(whole.covariance, halves.covariance)
    before = halves.theta.copy()
    with pytest.raises(DataError, match="observe"):
        halves.input(u[0])
    halves.observe(y[150])
    with pytest.raises(DataError, match="input"):
        halves.observe(y[151])
    with pytest.raises(DataError, match="non-finite"):
        halves.input([np.nan] * o.nu)
    halves.input(u[150])
    whole.step(y[150], u[150])
    np.testing.assert_array_equal(whole.theta, halves.theta)
    assert not np.array_equal(before, halves.theta)


def test_a_first_order_polynomial_is_judged_stable_exactly_as_by_its_roots():
    """is_stable's shortcut (the largest absolute row sum bounds every root's modulus) gives the roots' answer
    on random matrices either side of the boundary, with and without a margin."""
    rng = np.random.default_rng(5)
    agree = shortcut = 0
    for _ in range(3000):
        m = rng.normal(0.0, rng.uniform(0.05, 0.8), size=(1, 3, 3))
        margin = rng.choice([0.0, 1e-3, 0.1])
        by_roots = bool(np.all(np.abs(polynomial_roots(m)) < 1.0 - margin))
        agree += is_stable(m, margin) == by_roots
        shortcut += np.abs(m[0]).sum(axis=1).max() < 1.0 - margin
    assert agree == 3000
    assert 300 < shortcut < 2700, "both paths exercised"


def _rpem_per_output(estimator, phi, error, lam, trace):
    """The RPEM step written output by output (eq. 6.19-6.22), as a reference for the vectorised one."""
    o = estimator.orders
    c = estimator.theta[o.c_slice].T.reshape(o.ny, o.nc, o.ny)
    step = np.zeros_like(estimator.theta)
    P_all, psi_all = estimator._P.copy(), estimator._psi.copy()
    for i in range(o.ny):
        psi = phi - sum(c[i, k, i] * psi_all[i, k] for k in range(o.nc))
        lam_i = 1.0 if trace[i] > estimator.jacket.max_trace else lam
        P = P_all[i]
        Pp = P @ psi
        gain = Pp / (lam_i + psi @ Pp)
        P = (P - np.outer(gain, Pp)) / lam_i
        # Levenberg-Marquardt: delta on the diagonal of the Hessian approximation R = P^-1
        P_all[i] = np.linalg.inv(np.linalg.inv(0.5 * (P + P.T)) + estimator.regularisation * np.eye(len(psi)))
        step[:, i] = gain * error[i]
        psi_all[i, 1:] = psi_all[i, :-1]
        psi_all[i, 0] = psi
    return estimator.theta + step, P_all, psi_all


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_the_rpem_step_for_all_outputs_at_once_equals_it_output_by_output(compiled):
    """Both the compiled gradient step (seapup_ident.compiled) and its NumPy reference."""
    o = ArmaxOrders(ny=3, nu=2, na=2, nb=1, nc=2)
    rng = np.random.default_rng(8)
    estimator = RecursiveArmax(o, "rpem", p0=10.0, forgetting=Forgetting(0.98), jacket=Jacket(max_trace=100.0),
                               compiled=compiled)  # trace P(0) = 140: limited at first
    checked = 0
    for t in range(300):
        y, u = rng.normal(size=3), rng.normal(size=2)
        phi = estimator.regressor.phi()
        error = y - estimator.theta.T @ phi
        expected = _rpem_per_output(estimator, phi, error, 0.98, estimator.trace)
        projections = estimator.counts["projections"]
        estimator.step(y, u)
        if estimator.counts["projections"] == projections:  # no projection: the raw step is the new estimate
            np.testing.assert_allclose(estimator.theta, expected[0], rtol=1e-12, atol=1e-12)
            checked += 1
        np.testing.assert_allclose(estimator._P, expected[1], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(estimator._psi, expected[2], rtol=1e-12, atol=1e-12)
    assert checked > 100 and estimator.counts["trace_limited"] > 0


def _ud_update_by_columns(U, D, phi, lam):
    """Bierman's UD update as the column loop of Ljung and Soderstrom (1983, sec. 6.2): the reference."""
    n = len(D)
    f = U.T @ phi
    g = D * f
    beta, nu = lam, np.zeros(n)
    for j in range(n):
        beta_prev, beta = beta, beta + f[j] * g[j]
        D[j] *= beta_prev / (beta * lam)
        mu = -f[j] / beta_prev
        column = U[:j, j].copy()
        U[:j, j] = column + nu[:j] * mu
        nu[:j] += column * g[j]
        nu[j] = g[j]
    return nu / beta


def test_the_ud_update_as_running_sums_is_the_column_loop_bit_for_bit():
    rng = np.random.default_rng(1)
    for _ in range(100):
        n = int(rng.integers(1, 15))
        U = np.triu(rng.normal(size=(n, n)), 1) + np.eye(n)
        D = rng.uniform(0.1, 10.0, n)
        U_ref, D_ref = U.copy(), D.copy()
        for _ in range(20):
            phi, lam = rng.normal(size=n), float(rng.uniform(0.9, 1.0))
            gain = ud_update(U, D, phi, lam)
            assert np.array_equal(gain, _ud_update_by_columns(U_ref, D_ref, phi, lam))
            assert np.array_equal(U, U_ref) and np.array_equal(D, D_ref)


@pytest.mark.unit
def test_the_compiled_ud_update_is_the_reference_bit_for_bit():
    """seapup_ident.compiled.ud_update against ud_update from the same factors, over sizes 1-40 (the explicit
    self-tuner's 36 parameters, the GMV predictor's 13-69), forgetting 0.9-1, regressors from tiny to large and
    read-only ones: the same gain, U and D bit for bit, sample after sample; and the estimators use it by default
    where numba is loaded, giving the reference's estimates bit for bit along a run."""
    importlib.import_module("numba")   # loaded, as in a process that flies a plant: the kernel by default
    from seapup_ident.compiled import ud_update as kernel
    from seapup_ident.recursive import RecursiveRegression
    rng = np.random.default_rng(4)
    for n in [1, 2, 5, 13, 21, 36, 40]:
        U = np.triu(rng.normal(size=(n, n)), 1) + np.eye(n)
        D = rng.uniform(0.1, 10.0, n)
        U_ref, D_ref = U.copy(), D.copy()
        for _ in range(30):
            phi, lam = rng.normal(size=n) * rng.choice([1e-4, 1.0, 1e3]), float(rng.uniform(0.9, 1.0))
            phi.setflags(write=bool(rng.integers(2)))
            gain = np.empty(n)
            kernel(U, D, phi, lam, gain)
            assert np.array_equal(gain, ud_update(U_ref, D_ref, phi, lam))
            assert np.array_equal(U, U_ref) and np.array_equal(D, D_ref)
    runs = [RecursiveRegression(9, 2, forgetting=0.99, p0=1e4, compiled=kind) for kind in (None, False)]
    assert runs[0]._ud is not ud_update and runs[1]._ud is ud_update
    for _ in range(400):
        x = rng.normal(size=9)
        z = x[:2] * 3.0 - x[2:4] + 0.01 * rng.normal(size=2)
        errors = [est.update(x, z) for est in runs]
        assert np.array_equal(errors[0], errors[1])
    assert np.array_equal(runs[0].theta, runs[1].theta) and runs[0].trace == runs[1].trace
    again = pickle.loads(pickle.dumps(runs[0]))   # an estimator with the kernel pickles (a Dask task's state)
    x = rng.normal(size=9)
    assert np.array_equal(again.update(x, x[:2]), runs[1].update(x, x[:2]))


@pytest.mark.unit
@pytest.mark.parametrize("nc, weakening", [(1, (0.1, 0.98)), (2, None), (0, None)])
def test_the_compiled_rpem_estimates_as_the_numpy_reference_over_a_whole_run(nc, weakening):
    """Ljung's ARMAX data, 1500 samples with forgetting, the filter weakened or not, projections and all:
    the two paths' estimates, covariances and counts agree to rounding."""
    rng = np.random.default_rng(nc)
    o = ArmaxOrders(ny=2, nu=2, na=1, nb=1, nc=nc)
    runs = [RecursiveArmax(o, "rpem", p0=100.0, forgetting=Forgetting(0.995), filter_weakening=weakening,
                           compiled=flag) for flag in (True, False)]
    y, e_prev = np.zeros(2), np.zeros(2)
    for t in range(1500):
        u, e = rng.normal(size=2), 0.1 * rng.normal(size=2)
        for est in runs:
            est.step(y, u)
        y = 0.7 * y + np.array([0.5 * u[0], 0.3 * u[1] + 0.2 * u[0]]) + e + 0.5 * e_prev
        e_prev = e
    fast, reference = runs
    assert fast.compiled and not reference.compiled
    np.testing.assert_allclose(fast.theta, reference.theta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast._P, reference._P, rtol=1e-9, atol=1e-12)
    assert fast.counts == reference.counts
    if nc == 1:   # and the estimate is the system's (C = 1 + 0.5 z^-1): the noise model found
        assert fast.theta[o.c_slice][0, 0] == pytest.approx(0.5, abs=0.1)
        assert fast.theta[o.c_slice][1, 1] == pytest.approx(0.5, abs=0.1)
