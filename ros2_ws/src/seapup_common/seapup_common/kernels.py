"""What the packages' compiled kernels share (``seapup_sim.compiled``, ``seapup_ident.compiled``,
``seapup_control.compiled``): whether numba is there to compile them. Each package keeps its NumPy code as the
tested reference and uses it when this says no."""
from __future__ import annotations

import functools
import importlib.util
import sys

__all__ = ["numba_installed", "compiled_by_default"]


@functools.cache
def numba_installed() -> bool:
    """Whether numba can be imported (looked up once, without importing it: a process that never steps a kernel
    does not pay numba's import)."""
    return importlib.util.find_spec("numba") is not None


def compiled_by_default() -> bool:
    """Whether a core whose compiled kernel is an option (the MFOL law's sample, the position controller's) uses
    it when not told: numba is installed and this process has loaded it already (its plant, its navigator). A
    process that has not -- a velocity or position controller node of a graph -- keeps the reference: loading
    numba and the kernels costs about 0.3 s of CPU, which the kernel saves back (about 13 us a sample) only after
    some 25 000 samples. In process a run, a batch and a mission load the plant's or the navigator's kernels
    before they make their laws, so each takes the compiled one. The two give the same numbers where numba's
    BLAS and LAPACK (scipy's) and numpy's agree, as the tests of each kernel check on the machine they run on."""
    return numba_installed() and "numba" in sys.modules
