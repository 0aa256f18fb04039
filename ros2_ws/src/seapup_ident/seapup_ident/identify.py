"""Identification runs: data checks, recursive fits over the data N times, order tables and method comparisons.

What ``./seapup ident fit|orders|compare`` compute (thesis sec. 6.3, 6.5): a recursive estimator
(:class:`seapup_ident.recursive.RecursiveArmax`) run over the record ``passes`` times, or until it
has examined ``points`` samples ("the 300 sample data series is rewound and passed through
repeatedly until the algorithm has examined 2000 points", sec. 6.5.1), its loss V_N and AIC per
output from the equation errors of the last pass (or of every examined point) -- the a posteriori
residuals e(k) = y(k) - Theta(k)^T phi(k) of eq. 6.20 (eq. 6.11, 6.21) -- and the tables of
sec. 6.5: loss, AIC and F per output and order (Tables 6.1, 6.2, 6.6), AIC per method (Tables
6.3-6.5, 6.7).

Bad data never reach an estimator: non-finite samples and gaps in the sample times split the
record into segments (the regressor restarts at each, Theta and P carry on), and inputs that do
not excite (constant over the record) are reported; :class:`DataReport` says what was found.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import special

from seapup_ident.armax import ArmaxModel, ArmaxOrders
from seapup_ident.order_selection import aic, f_test, residual_autocorrelation
from seapup_ident.recursive import Forgetting, RecursiveArmax

__all__ = ["IdentificationData", "DataReport", "FitResult", "fit", "predict", "residual_whiteness", "order_table", "compare_methods",
           "model_document", "read_csv", "NotExcitingError"]


class NotExcitingError(ValueError):
    """The inputs cannot identify a model (constant, or too few usable samples)."""


@dataclass
class DataReport:
    """What the checks found in a record."""

    samples: int
    usable: int
    non_finite: int
    gaps: int
    segments: int
    constant_inputs: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class IdentificationData:
    """A record of outputs y (N x ny) and inputs u (N x nu) at sample times t (N, seconds).

    u[k] is the input applied from t[k] on (so it acts on y[k+1]): the blade pitch the vehicle
    applied with sample k.
    """

    y: np.ndarray
    u: np.ndarray
    t: np.ndarray | None = None
    outputs: tuple = ()
    inputs: tuple = ()

    def __post_init__(self):
        self.y = np.asarray(self.y, dtype=float)
        self.u = np.asarray(self.u, dtype=float)
        if self.y.ndim == 1:
            self.y = self.y[:, None]
        if self.u.ndim == 1:
            self.u = self.u[:, None]
        if len(self.y) != len(self.u):
            raise ValueError(f"{len(self.y)} output samples but {len(self.u)} input samples")
        n = len(self.y)
        self.t = np.arange(n, dtype=float) if self.t is None else np.asarray(self.t, dtype=float)
        if self.t.shape != (n,):
            raise ValueError(f"{n} samples but {self.t.size} times")
        self.outputs = tuple(self.outputs) or tuple(f"y{i}" for i in range(self.y.shape[1]))
        self.inputs = tuple(self.inputs) or tuple(f"u{i}" for i in range(self.u.shape[1]))

    @property
    def sample_period(self) -> float:
        finite = self.t[np.isfinite(self.t)]
        return float(np.median(np.diff(finite))) if len(finite) > 1 else 1.0

    def span(self) -> dict:
        """What the record covers: ``samples``, ``t`` [first, last] sample times [s], ``sample_period``
        T and ``seconds`` = samples x T, the time its inputs cover (u[k] is held over [t_k, t_k + T]);
        times rounded to the nanosecond (a bag's stamps)."""
        period = self.sample_period
        return {"samples": len(self.t), "t": [round(float(self.t[0]), 9), round(float(self.t[-1]), 9)]
                if len(self.t) else [], "sample_period": round(period, 9), "seconds": round(len(self.t) * period, 9)}

    def first(self, duration: float) -> "IdentificationData":
        """The samples whose inputs lie in the first ``duration`` seconds of the record: t_k - t_0 <= duration - T.

        An experiment of D seconds at period T gives D / T of them (the sample at t = D has no
        input interval left in the record).

        Examples
        --------
        >>> data = IdentificationData(np.zeros(425), np.arange(425.0), 0.2 * np.arange(425))
        >>> span = data.first(60.0).span()
        >>> span["samples"], span["t"], span["seconds"]
        (300, [0.0, 59.8], 60.0)
        """
        period = self.sample_period
        if not (math.isfinite(duration) and duration >= period - 1e-9):
            raise ValueError(f"duration must be >= one sample period ({period:g} s), got {duration!r}")
        keep = self.t - self.t[0] <= duration - period + 0.5 * period
        return IdentificationData(self.y[keep], self.u[keep], self.t[keep], self.outputs, self.inputs)

    def segments(self) -> tuple[list[np.ndarray], DataReport]:
        """Index arrays of the contiguous, finite stretches, and the report."""
        good = np.all(np.isfinite(self.y), axis=1) & np.all(np.isfinite(self.u), axis=1) & np.isfinite(self.t)
        period = self.sample_period
        breaks = np.zeros(len(self.t), dtype=bool)
        breaks[1:] = np.diff(self.t) > 1.5 * period       # dropped samples
        pieces, current = [], []
        for k in range(len(self.t)):
            if not good[k] or (breaks[k] and current):
                if current:
                    pieces.append(np.array(current))
                current = []
            if good[k]:
                current.append(k)
        if current:
            pieces.append(np.array(current))
        usable = np.concatenate(pieces) if pieces else np.zeros(0, dtype=int)
        spread = np.ptp(self.u[usable], axis=0) if len(usable) else np.zeros(self.u.shape[1])
        constant = [self.inputs[j] for j in range(self.u.shape[1]) if spread[j] <= 1e-12]
        report = DataReport(len(self.t), len(usable), int(np.sum(~good)), int(np.sum(breaks[1:])), len(pieces),
                            constant)
        return pieces, report


@dataclass
class FitResult:
    """A fitted model and how well it predicts (the last pass, or every examined point)."""

    method: str
    orders: ArmaxOrders
    model: ArmaxModel
    loss: np.ndarray          # V_N per output (eq. 6.11, 6.20: mean squared a posteriori residual)
    aic: np.ndarray           # per output (eq. 6.21)
    predictions: np.ndarray   # one-step predictions of the last pass (N x ny, NaN where unusable)
    report: DataReport
    passes: int               # passes run (the last one partly, with ``points``)
    estimator: RecursiveArmax
    examined: int = 0         # samples the estimator took over all passes
    scored: int = 0           # samples in V_N and AIC (N of eq. 6.18-6.21)
    transient: np.ndarray | None = None   # one-step predictions of the first pass: the adapting model (fig. 6.5)


def fit(data: IdentificationData, orders: ArmaxOrders, method: str = "ls", *, forgetting: Forgetting | None = None,
        p0: float = 100.0, passes: int = 1, points: int | None = None, keep_history: bool = False,
        min_samples: int | None = None, filter_weakening: tuple[float, float] | None = None,
        score: str = "posterior") -> FitResult:
    """Run the recursive estimator over ``data`` ``passes`` times, or until it has examined ``points``
    samples (sec. 6.5.1: "the 300 sample data series is rewound and passed through repeatedly until
    the algorithm has examined 2000 points").

    V_N and AIC score the errors of the last pass (``passes``) or of every examined sample
    (``points``, as the thesis's 2000-point rows of Tables 6.3-6.5, 6.7), each segment from the first
    sample whose regressor is full: with ``score="posterior"`` the a posteriori equation errors
    y(k) - Theta(k)^T phi(k) (eq. 6.20's e(k), whose size matches the thesis's tables), with
    ``score="prior"`` the one-step prediction errors y(k) - Theta(k-1)^T phi(k) (eq. 6.11), which
    also charge each model its transient. Defaults as the thesis's runs:
    P(0) = 100 I, Theta(0) = 0 (sec. 6.5.1). The forgetting factor carries on over the passes (the
    schedule of eq. 6.15 is not restarted).

    Raises
    ------
    NotExcitingError
        When an input is constant over the record, or fewer usable samples than parameters remain.
    """
    if passes < 1:
        raise ValueError(f"passes must be >= 1, got {passes}")
    if points is not None and points < 1:
        raise ValueError(f"points must be >= 1, got {points}")
    if score not in ("posterior", "prior"):
        raise ValueError(f"score must be posterior or prior, got {score!r}")
    pieces, report = data.segments()
    if report.constant_inputs:
        raise NotExcitingError(f"input(s) {', '.join(report.constant_inputs)} constant over the record: they excite "
                               f"nothing and their parameters cannot be identified (sec. 6.3: persistently exciting)")
    needed = min_samples or 2 * orders.n_params
    if report.usable < needed:
        raise NotExcitingError(f"{report.usable} usable samples (of {report.samples}; {report.non_finite} non-finite, "
                               f"{report.gaps} gaps) for {orders.n_params} parameters per output")
    estimator = RecursiveArmax(orders, method, forgetting=forgetting, p0=p0, keep_history=keep_history,
                               filter_weakening=filter_weakening if method == "rpem" else None)
    predictions = np.full_like(data.y, np.nan)
    transient = np.full_like(data.y, np.nan)
    errors: list[np.ndarray] = []
    examined, passes_run = 0, 0
    while (examined < points) if points is not None else (passes_run < passes):
        passes_run += 1
        if points is None:
            errors = []   # passes: score the last one
        for piece in pieces:
            estimator.restart()  # a segment's first lag samples only fill the regressor
            for i, k in enumerate(piece):
                if points is not None and examined == points:
                    break
                _, predictions[k] = estimator.step(data.y[k], data.u[k], update=i >= orders.lag)
                if passes_run == 1:
                    transient[k] = predictions[k]
                examined += 1
                if i >= orders.lag:
                    errors.append(estimator.residual.copy() if score == "posterior" else data.y[k] - predictions[k])
    errors = np.array(errors)
    loss = np.mean(errors ** 2, axis=0)
    return FitResult(method, orders, estimator.model, loss, aic(errors, orders.n_params), predictions, report,
                     passes_run, estimator, examined, len(errors), transient)


def predict(model: ArmaxModel, data: IdentificationData) -> np.ndarray:
    """One-step predictions of a fixed model over a record (N x ny; NaN where unusable and over each
    segment's first ``lag`` samples): the ARMAX predictor, its C terms on its own past prediction
    errors. ``data.y - predict(...)`` are the model's residuals (figs 6.2-6.14)."""
    o = model.orders
    pieces, _ = data.segments()
    predictor = RecursiveArmax(o, "els" if o.nc else "ls", theta0=model.theta())
    out = np.full_like(data.y, np.nan)
    for piece in pieces:
        predictor.restart()
        for i, k in enumerate(piece):
            _, y_hat = predictor.step(data.y[k], data.u[k], update=False)
            if i >= o.lag:
                out[k] = y_hat
    return out


def residual_whiteness(model: ArmaxModel, data: IdentificationData, max_lag: int = 20, alpha: float = 0.05) -> dict:
    """The residual test of sec. 6.3 (fig. 6.2) on the model's one-step prediction errors, per output.

    The thesis's form: the normalised autocorrelation for lags 0 .. ``max_lag``, its 95 % band
    +-1.96/sqrt(N), and the fraction of lags > 0 inside it ("ninety-five percent ... should fall within
    2 sigma limits if the residuals are white"). With 20 lags one value outside is that fraction, so the
    verdict ``white`` is the portmanteau form of the same test, Ljung-Box Q = N(N+2) sum R(k)^2/(N-k)
    against chi-square(max_lag) at risk ``alpha`` (its survival function ``scipy.stats.chi2.sf``, computed as
    scipy.stats computes it, ``scipy.special.chdtrc``: ``scipy.stats`` costs a command about 1 s to import).
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"the whiteness test's risk must be in (0, 1), got {alpha}")
    residuals = data.y - predict(model, data)
    residuals = residuals[np.all(np.isfinite(residuals), axis=1)]
    n = len(residuals)
    if n <= max_lag + 1:
        raise NotExcitingError(f"{n} residuals for {max_lag} lags")
    r, band = residual_autocorrelation(residuals, max_lag)
    inside = np.mean(np.abs(r[1:]) <= band, axis=0)
    lags = np.arange(1, max_lag + 1)[:, None]
    q = n * (n + 2) * np.sum(r[1:] ** 2 / (n - lags), axis=0)
    p_value = special.chdtrc(max_lag, q)
    return {"outputs": list(data.outputs), "lags": list(range(max_lag + 1)), "autocorrelation": r.T.tolist(),
            "band": band, "inside": inside.tolist(), "max_abs": np.max(np.abs(r[1:]), axis=0).tolist(),
            "ljung_box_q": q.tolist(), "p_value": p_value.tolist(), "white": (p_value >= alpha).tolist(),
            "alpha": alpha, "samples": n}


def order_table(data: IdentificationData, max_order: int = 3, method: str = "ls", *, alpha: float = 0.05,
                forgetting_factory=None, p0: float = 100.0, passes: int = 1, points: int | None = None,
                score: str = "posterior") -> dict:
    """Loss, AIC and F per output for orders (n, n[, n]) n = 1 .. max_order (Tables 6.1, 6.2, 6.6).

    F compares order n - 1 with n (eq. 6.18) at risk ``alpha``. Per output, the AIC pick is the
    order of least AIC and the F pick the last order before the increase stops being significant;
    the system order is the largest over the outputs (sec. 6.3.1).
    """
    rows = []
    for n in range(1, max_order + 1):
        orders = ArmaxOrders(data.y.shape[1], data.u.shape[1], n, n, n if method != "ls" else 0)
        forgetting = forgetting_factory() if forgetting_factory else None
        result = fit(data, orders, method, forgetting=forgetting, p0=p0, passes=passes, points=points, score=score)
        row = {"order": n, "n_params": orders.n_params, "loss": result.loss.tolist(), "aic": result.aic.tolist()}
        if rows:
            previous = rows[-1]
            samples = result.scored
            test = f_test(previous["loss"], result.loss, previous["n_params"], orders.n_params, samples, alpha)
            row.update(f=test.statistic.tolist(), f_threshold=test.threshold,
                       significant=test.larger_is_better.tolist())
        rows.append(row)
    ny = data.y.shape[1]
    by_aic = [int(min(rows, key=lambda r: r["aic"][i])["order"]) for i in range(ny)]
    by_f = []
    for i in range(ny):
        order = 1
        for row in rows[1:]:
            if not row["significant"][i]:
                break
            order = row["order"]
        by_f.append(order)
    return {"method": method, "outputs": list(data.outputs), "rows": rows, "aic_order": by_aic, "f_order": by_f,
            "system_order": max(max(by_aic), max(by_f)), "alpha": alpha, "score": score}


def compare_methods(data: IdentificationData, order: int = 2, methods=("ls", "els", "rpem"), *,
                    forgetting_factory=None, p0: float = 100.0, passes: int = 1, points: int | None = None,
                    rpem_filter: tuple[float, float] | None = None, score: str = "posterior") -> dict:
    """AIC per output of each method at order (n, n) / (n, n, n) (Tables 6.3-6.5, 6.7); ``rpem_filter``
    (K(0), gamma) weakens RPEM's gradient filter at first (the tables' K(0) = 0.1, gamma = 0.98).
    ``results`` holds each method's :class:`FitResult` (not JSON)."""
    out = {"outputs": list(data.outputs), "order": order, "passes": passes, "points": points,
           "rpem_filter": list(rpem_filter) if rpem_filter else None, "score": score, "methods": {}, "results": {}}
    for method in methods:
        orders = ArmaxOrders(data.y.shape[1], data.u.shape[1], order, order, 0 if method == "ls" else order)
        forgetting = forgetting_factory() if forgetting_factory else None
        result = fit(data, orders, method, forgetting=forgetting, p0=p0, passes=passes, points=points,
                     filter_weakening=rpem_filter, score=score)
        out["results"][method] = result
        out["methods"][method] = {"aic": result.aic.tolist(), "loss": result.loss.tolist(), "scored": result.scored,
                                  "n_params": orders.n_params, "projections": result.estimator.counts["projections"]}
    return out


def model_document(result: FitResult, data: IdentificationData | None = None, **extra) -> dict:
    """The JSON document of ``./seapup ident fit``: the thesis's sign convention (eq. 6.7), B from z^-1."""
    m, o = result.model, result.orders
    doc = {"method": result.method, "orders": [o.na, o.nb, o.nc], "A": m.A.tolist(), "B": m.B.tolist(),
           "C": m.C.tolist(), "d": m.d.tolist(), "loss": result.loss.tolist(), "aic": result.aic.tolist(),
           "passes": result.passes, "data": result.report.as_dict()}
    if data is not None:
        doc.update(outputs=list(data.outputs), inputs=list(data.inputs), sample_period=data.sample_period)
    doc.update(extra)
    return doc


def read_csv(path, outputs=None, inputs=None, time_column: str | None = "t") -> IdentificationData:
    """A record from a CSV file whose header names the columns.

    Outputs are the columns named in ``outputs`` (default: those starting with ``y``), inputs
    those in ``inputs`` (default: starting with ``u``); a ``t`` column, if present, gives the
    sample times [s]. Empty cells and non-numbers become NaN (reported, never used).
    """
    path = Path(path)
    with path.open(newline="") as f:
        reader = csv.reader(f)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise ValueError(f"{path}: empty file") from None
        rows = list(reader)
    outputs = list(outputs) if outputs else [h for h in header if h.startswith("y")]
    inputs = list(inputs) if inputs else [h for h in header if h.startswith("u")]
    missing = [c for c in outputs + inputs if c not in header]
    if missing or not outputs or not inputs:
        raise ValueError(f"{path}: columns {missing or 'y.../u...'} not found in header {header}")

    def number(text: str) -> float:
        try:
            return float(text)
        except ValueError:
            return math.nan
    values = np.array([[number(cell) for cell in row] + [math.nan] * (len(header) - len(row)) for row in rows])
    if values.size == 0:
        raise ValueError(f"{path}: no data rows")
    column = {name: values[:, header.index(name)] for name in header}
    t = column[time_column] if time_column and time_column in column else None
    return IdentificationData(np.stack([column[c] for c in outputs], axis=1),
                              np.stack([column[c] for c in inputs], axis=1), t, tuple(outputs), tuple(inputs))
