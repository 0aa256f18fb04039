"""Hydrodynamic forces as a table of named slow-motion derivatives.

The NMI model of the Seapup expresses each hydrodynamic force and moment
(X, Y, Z, K, M, N -- the thesis writes L for the roll moment) as a sum of
slow-motion derivatives, each a coefficient times a product of body velocities
relative to the water (thesis sec. 2.3.1). seapup keeps exactly that form: a
derivative is named in SNAME notation and its name *is* its definition:

=============  ==========================================
``X_u|u|``     X = X_u|u| * u * |u|
``Z_uu``       Z = Z_uu * u * u
``M_|w|q``     M = M_|w|q * |w| * q
``N_r``        N = N_r * r            (a linear term)
``K_v|v|``     K = K_v|v| * v * |v|   (K or L: roll moment)
=============  ==========================================

Velocities u, v, w are relative to the water; the fluid's angular velocity is
neglected, so p, q, r are the vehicle's (thesis sec. 2.3.1, last paragraph).
Acceleration derivatives (added mass) are not in this table: they belong in the
mass matrix (eq. 2.3).

Because a term's name gives its velocity factors, the model checker
(:mod:`seapup_sim.model_check`) can test each term for port/starboard symmetry
and for negative damping without evaluating the model (thesis sec. 3.4-3.5).
"""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass

import numpy as np

__all__ = ["HydroTermError", "HydroTerm", "parse_term", "HydroTable", "AXES", "VELOCITIES"]

#: Force/moment axes in state order; "L" is accepted as a synonym of "K".
AXES = ("X", "Y", "Z", "K", "M", "N")
#: Velocity symbols in the order of the body velocity vector (u v w p q r).
VELOCITIES = ("u", "v", "w", "p", "q", "r")
_TOKEN = re.compile(r"\|([uvwpqr])\||([uvwpqr])")


class HydroTermError(ValueError):
    """A derivative name that is not valid SNAME slow-motion notation."""


@dataclass(frozen=True)
class HydroTerm:
    """One derivative: axis index, velocity factors, and coefficient (SI).

    ``signed`` and ``absolute`` hold the velocity indices (0-5) of the plain
    and the absolute-value factors; repeated indices are powers.
    """

    name: str
    axis: int
    signed: tuple[int, ...]
    absolute: tuple[int, ...]
    coefficient: float

    @property
    def factors(self) -> tuple[int, ...]:
        """All velocity indices of the term, plain and absolute."""
        return self.signed + self.absolute

    def evaluate(self, nu: np.ndarray) -> float:
        """The term's force or moment for body velocities ``nu`` (6,)."""
        value = self.coefficient
        for i in self.signed:
            value *= nu[i]
        for i in self.absolute:
            value *= abs(nu[i])
        return value


def parse_term(name: str, coefficient: float) -> HydroTerm:
    """Parse an SNAME derivative name such as ``M_|w|q`` or ``X_u|u|``.

    Raises
    ------
    HydroTermError
        For an unknown axis, an empty or malformed velocity part, or a
        non-finite coefficient.
    """
    axis, signed, absolute = _parse_name(name)
    if not np.isfinite(coefficient):
        raise HydroTermError(f"{name!r}: coefficient {coefficient!r} is not finite")
    return HydroTerm(name, axis, signed, absolute, float(coefficient))


@functools.lru_cache(maxsize=4096)
def _parse_name(name: str) -> tuple[int, tuple[int, ...], tuple[int, ...]]:
    """(axis, signed factors, absolute factors) of a derivative's name: parsed once per name (every vehicle
    model built -- thousands in a campaign -- parses the same few dozen)."""
    if not isinstance(name, str) or "_" not in name:
        raise HydroTermError(f"{name!r}: expected <axis>_<velocities>, e.g. 'X_u|u|'")
    axis_name, velocities = name.split("_", 1)
    axis_name = "K" if axis_name == "L" else axis_name
    if axis_name not in AXES:
        raise HydroTermError(f"{name!r}: axis must be one of X Y Z K(L) M N")
    signed, absolute, pos = [], [], 0
    for m in _TOKEN.finditer(velocities):
        if m.start() != pos:
            break
        if m.group(1):
            absolute.append(VELOCITIES.index(m.group(1)))
        else:
            signed.append(VELOCITIES.index(m.group(2)))
        pos = m.end()
    if pos != len(velocities) or not (signed or absolute):
        raise HydroTermError(f"{name!r}: velocity part must be a product of u v w p q r and |u|..|r|")
    return AXES.index(axis_name), tuple(signed), tuple(absolute)


class HydroTable:
    """A set of derivatives evaluated together into a 6-vector of forces.

    Parameters
    ----------
    coefficients : dict
        Derivative name -> coefficient in SI units (N or N m per the velocity
        product's units).
    """

    def __init__(self, coefficients: dict[str, float]):
        self.terms = [parse_term(name, float(c)) for name, c in coefficients.items()]
        seen: dict = {}
        for t in self.terms:  # K_p and L_p, or M_q|w| and M_|w|q, are one term
            key = (t.axis, tuple(sorted(t.signed)), tuple(sorted(t.absolute)))
            if key in seen:
                raise HydroTermError(f"duplicate derivatives {seen[key]!r} and {t.name!r}")
            seen[key] = t.name
        # Vectorised form (hot path): factor index tables padded with index 6,
        # which points at a constant 1.0 appended to the velocity vector.
        width = max((len(t.factors) for t in self.terms), default=1)
        self._axis = np.array([t.axis for t in self.terms], dtype=int)
        self._coef = np.array([t.coefficient for t in self.terms])
        self._signed = np.full((len(self.terms), width), 6, dtype=int)
        self._absolute = np.full((len(self.terms), width), 6, dtype=int)
        for k, t in enumerate(self.terms):
            self._signed[k, :len(t.signed)] = t.signed
            self._absolute[k, :len(t.absolute)] = t.absolute

    def forces(self, nu_r: np.ndarray) -> np.ndarray:
        """Hydrodynamic forces and moments (6,) for relative body velocities ``nu_r``."""
        if not self.terms:
            return np.zeros(6)
        ext = np.append(nu_r, 1.0)
        values = (self._coef * ext[self._signed].prod(axis=1)
                  * np.abs(ext)[self._absolute].prod(axis=1))
        return np.bincount(self._axis, weights=values, minlength=6)

    def as_dict(self) -> dict[str, float]:
        return {t.name: t.coefficient for t in self.terms}
