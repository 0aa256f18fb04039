"""Plain JSON data from results holding numpy values: one conversion for every ``--json`` and run result."""
from __future__ import annotations

import math
from collections.abc import Mapping

__all__ = ["jsonable"]


def jsonable(obj):
    """Convert a result to plain JSON-serialisable Python.

    Parameters
    ----------
    obj : object
        Dicts, lists, tuples, numpy scalars and arrays, nested freely.

    Returns
    -------
    object
        The same structure with numpy values as Python numbers and lists,
        dict keys as strings, and non-finite floats as None (JSON has no NaN).

    Examples
    --------
    >>> jsonable({1: (0.5, float("nan"))})
    {'1': [0.5, None]}
    """
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if hasattr(obj, "tolist"):
        return jsonable(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
