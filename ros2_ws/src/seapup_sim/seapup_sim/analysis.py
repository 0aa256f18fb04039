"""Linear analysis of the vehicle model (thesis sec. 3.2 and 3.7).

- :func:`linearise` -- A and B by fourth-order central differences (eq. 3.3);
- :func:`system_zeros` -- zeros of the system matrix by the generalised
  eigenvalue problem (eq. 3.8-3.9, the QZ algorithm via scipy), each
  classified as input-decoupling (eq. 3.10), output-decoupling (eq. 3.11),
  input/output-decoupling, or transmission zero (eq. 3.12);
- :func:`trim` -- steady straight flight at a surge speed: pitch angle and
  blade pitches (sec. 3.7: at 0.7 m/s, 10.0 deg, mains 14.6 deg, vectored
  -5.9 deg);
- :func:`speed_loci` -- poles and transmission zeros over surge speed
  (figs 3.8-3.10).

The outputs are C = selection of u, v, w, r (sec. 3.7), D = 0.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from seapup_sim.vehicle import VehicleModel

__all__ = ["OUTPUTS", "output_matrix", "linearise", "ZeroInfo", "system_zeros", "trim_sweep", "hover_blade_pitch",
           "transmission_zeros", "TrimError", "Trim", "trim", "speed_loci"]

#: Indices of the outputs u, v, w, r in the state vector.
OUTPUTS = (6, 7, 8, 11)


def output_matrix() -> np.ndarray:
    """C (4, 12) selecting u, v, w and r."""
    c = np.zeros((4, 12))
    c[range(4), OUTPUTS] = 1.0
    return c


def linearise(model: VehicleModel, state, pitch, h_state=None, h_input=None,
              thrusters_on: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A (12, 12) and B (12, 4) of x' = f(x, u) about (state, pitch).

    Implements eq. 3.3, the fourth-order central difference
    ``A_ij = [-f(x+2h) + 8 f(x+h) - 8 f(x-h) + f(x-2h)] / (12 h)``
    (and likewise for B). Default spacings: 1e-4 (m, rad, m/s, rad/s) for the
    states and 1e-4 rad for the blade pitches. ``u`` are the vehicle's four inputs
    (:meth:`~seapup_sim.vehicle.VehicleModel.input_derivatives`: a virtual-input vehicle's through its mixer).
    """
    x0 = np.asarray(state, float)
    u0 = np.asarray(pitch, float)
    hx = np.full(12, 1e-4) if h_state is None else np.asarray(h_state, float)
    hu = np.full(4, 1e-4) if h_input is None else np.asarray(h_input, float)

    def f(x, u):
        return model.input_derivatives(x, u, thrusters_on=thrusters_on)

    def column(perturb, h):
        return (-f(*perturb(2 * h)) + 8 * f(*perturb(h)) - 8 * f(*perturb(-h))
                + f(*perturb(-2 * h))) / (12 * h)

    a = np.empty((12, 12))
    for j in range(12):
        e = np.zeros(12)
        e[j] = 1.0
        a[:, j] = column(lambda d, e=e: (x0 + d * e, u0), hx[j])
    b = np.empty((12, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = 1.0
        b[:, j] = column(lambda d, e=e: (x0, u0 + d * e), hu[j])
    return a, b


@dataclass(frozen=True)
class ZeroInfo:
    """A finite system zero and its class (eq. 3.10-3.12)."""

    value: complex
    input_decoupling: bool
    output_decoupling: bool

    @property
    def kind(self) -> str:
        if self.input_decoupling and self.output_decoupling:
            return "input/output-decoupling"
        if self.input_decoupling:
            return "input-decoupling"
        if self.output_decoupling:
            return "output-decoupling"
        return "transmission"


def system_zeros(a, b, c, d=None, rtol: float = 1e-8) -> list[ZeroInfo]:
    """Finite zeros of the system matrix, classified.

    Solves det [[A - sI, B], [C, D]] = 0 as the generalised eigenvalue problem
    M w = s N w with M = [[A, B], [C, D]], N = [[I, 0], [0, 0]] (eq. 3.8-3.9);
    infinite eigenvalues are dropped. A zero s is input-decoupling if
    [sI - A, B] loses rank (eq. 3.10), output-decoupling if [sI - A; C] does
    (eq. 3.11); rank is judged by the smallest singular value relative to the
    largest, against ``rtol``.
    """
    import scipy.linalg  # here: the simulator imports this module for its hover trim only (0.3 s)

    a, b, c = (np.atleast_2d(np.asarray(m, float)) for m in (a, b, c))
    n, m_in = b.shape
    p = c.shape[0]
    d = np.zeros((p, m_in)) if d is None else np.atleast_2d(np.asarray(d, float))
    big = np.block([[a, b], [c, d]])
    small = np.zeros_like(big)
    small[:n, :n] = np.eye(n)
    values = scipy.linalg.eig(big, small, right=False, homogeneous_eigvals=True)
    alpha, beta = values
    finite = np.abs(beta) > 1e-9 * np.maximum(np.abs(alpha), 1.0)
    zeros = alpha[finite] / beta[finite]
    scale = max(np.linalg.norm(big, 2), 1.0)
    out = []
    for s in zeros:
        s = complex(s)
        si_a = s * np.eye(n) - a
        sv_in = scipy.linalg.svdvals(np.hstack([si_a, b]))
        sv_out = scipy.linalg.svdvals(np.vstack([si_a, c]))
        out.append(ZeroInfo(s, bool(sv_in[-1] <= rtol * scale), bool(sv_out[-1] <= rtol * scale)))
    return sorted(out, key=lambda z: (z.value.real, z.value.imag))


def transmission_zeros(a, b, c, d=None) -> np.ndarray:
    """The zeros of :func:`system_zeros` that are not decoupling zeros (complex array)."""
    return np.array([z.value for z in system_zeros(a, b, c, d) if z.kind == "transmission"])


class TrimError(RuntimeError):
    """No steady flight condition found at the asked surge speed."""


@dataclass(frozen=True)
class Trim:
    """A steady straight-flight condition."""

    surge_speed: float
    pitch_angle: float            # theta [rad]
    blade_pitch: np.ndarray       # (4,) [rad]
    state: np.ndarray             # (12,)
    residual: float               # max |acceleration| left [m/s^2, rad/s^2]
    within_limits: bool           # blade pitches inside the +/-35 deg limits

    @property
    def unknowns(self) -> list[float]:
        """(theta, main blade pitch, vectored blade pitch): a warm start for a nearby trim."""
        return [self.pitch_angle, float(self.blade_pitch[0]), float(self.blade_pitch[2])]


def trim(model: VehicleModel, surge_speed: float, guess=None, enforce_limits: bool = True) -> Trim:
    """Steady forward flight at ``surge_speed`` [m/s], all other velocities zero.

    Unknowns (sec. 3.7): pitch angle theta, main blade pitch (both mains
    alike) and vectored blade pitch (both alike); equations: zero surge, heave
    and pitch accelerations. By port/starboard symmetry the lateral
    accelerations are then zero too (checked in the residual).

    With ``enforce_limits=False`` an equilibrium that needs blade pitch
    beyond the limits is returned (``within_limits`` False): the vehicle cannot
    fly it, but the equations can still be linearised there.

    Raises
    ------
    TrimError
        If the solver does not converge, or (``enforce_limits``) needs blade
        pitch beyond the limits (the speed is out of reach).
    """
    if not np.isfinite(surge_speed):
        raise TrimError(f"surge speed must be finite, got {surge_speed!r}")

    def state_of(z):
        x = np.zeros(12)
        x[4] = z[0]
        x[6] = surge_speed
        return x

    def pitches(z):
        return model.inputs.trim_inputs(z[1], z[2])

    def residual(z):
        acc = model.input_derivatives(state_of(z), pitches(z))
        return acc[[6, 8, 10]]

    import scipy.optimize  # here: a node that never trims does not pay its import (0.2 s)

    z0 = np.array(model.inputs.trim_guess if guess is None else guess, float)
    reach = 1.5 if model.inputs.kind == "direct" else 1.0   # a virtual input's mixer gives no more than its full scale
    sol = scipy.optimize.least_squares(residual, z0, xtol=1e-14, ftol=1e-14, gtol=1e-14,
                                       bounds=([-1.2, -reach, -reach], [1.2, reach, reach]))
    z = sol.x
    full = np.abs(model.input_derivatives(state_of(z), pitches(z))[6:]).max()
    if full > 1e-7:
        raise TrimError(f"no trim at u = {surge_speed:.3f} m/s (residual {full:.2e})")
    within = bool(np.all(np.abs(pitches(z)) <= model.pitch_limit + 1e-9))
    if enforce_limits and not within:
        raise TrimError(f"trim at u = {surge_speed:.3f} m/s needs blade pitch "
                        f"{np.degrees(pitches(z)).round(2).tolist()} deg, beyond the limits")
    return Trim(float(surge_speed), float(z[0]), pitches(z), state_of(z), float(full), within)


def trim_sweep(model: VehicleModel, speeds) -> Iterator[Trim]:
    """Trims at increasing surge speeds, each warm-started from the previous one.

    Trims beyond the blade limits are included (``within_limits`` False): the
    equations can still be linearised there (sec. 3.7).

    Raises
    ------
    TrimError
        At the first speed with no trim (the trims before it were yielded).
    """
    guess = None
    for u in speeds:
        tr = trim(model, float(u), guess, enforce_limits=False)
        guess = tr.unknowns
        yield tr


def hover_blade_pitch(model: VehicleModel) -> np.ndarray:
    """The hover setting (eq. 5.2) of ``model``'s present configuration [rad].

    Computed from the trim at zero speed, so it follows the configuration: the
    baseline hovers at (-3.38, -3.38, -13.10, -13.10) deg (eq. 5.2), the
    camera-fitted vehicle needs more vectored thrust.
    """
    return trim(model, 0.0).blade_pitch.copy()


def speed_loci(model: VehicleModel, speeds) -> list[dict]:
    """Trim, eigenvalues and transmission zeros at each surge speed (figs 3.8-3.10).

    Trims beyond the blade limits are included (``trim.within_limits`` False).
    """
    c = output_matrix()
    out = []
    for tr in trim_sweep(model, speeds):
        a, b = linearise(model, tr.state, tr.blade_pitch)
        out.append({"surge_speed": tr.surge_speed, "trim": tr, "eigenvalues": np.linalg.eigvals(a),
                    "zeros": system_zeros(a, b, c)})
    return out
