"""What counts as a number in a file or a request: one rule for every reader.

YAML and JSON give numbers as ``int`` or ``float`` (numpy's scalars come from seapup's own arrays). A string
that looks like a number (``'0.2'``) is not one, nor is a boolean (Python's ``True == 1``), and an integer
beyond a float's range (``10**400``), ``.inf`` and ``.nan`` are not finite. Every reader of specifications,
configurations, controller parameters and live-view requests asks :func:`finite_real` and words its own
refusal.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["is_real", "finite_real"]

_REAL_TYPES = (int, float, np.integer, np.floating)


def is_real(value) -> bool:
    """Whether ``value`` is a number of a file or request: an int or float (numpy's too), never a bool.

    Examples
    --------
    >>> is_real(0.2), is_real(3), is_real("0.2"), is_real(True), is_real(np.float32(1))
    (True, True, False, False, True)
    """
    return isinstance(value, _REAL_TYPES) and not isinstance(value, (bool, np.bool_))


def finite_real(value) -> float | None:
    """``value`` as a float when it is a finite number (:func:`is_real`), else None.

    Examples
    --------
    >>> finite_real(2), finite_real("2"), finite_real(float("nan")), finite_real(10 ** 400)
    (2.0, None, None, None)
    """
    if not is_real(value):
        return None
    try:
        number = float(value)
    except OverflowError:   # an integer beyond a float's range
        return None
    return number if math.isfinite(number) else None
