"""What the packages' compiled kernels share (``seapup_sim.compiled``, ``seapup_ident.compiled``,
``seapup_control.compiled``): whether numba is there to compile them. Each package keeps its NumPy code as the
tested reference and uses it when this says no."""
from __future__ import annotations

import functools
import importlib.util

__all__ = ["numba_installed"]


@functools.cache
def numba_installed() -> bool:
    """Whether numba can be imported (looked up once, without importing it: a process that never steps a kernel
    does not pay numba's import)."""
    return importlib.util.find_spec("numba") is not None
