"""Pseudo-random binary sequences for identification experiments (thesis sec. 6.3, 6.5.1).

"A good choice for the input signal is a Pseudo Random Binary Sequence (PRBS). In a PRBS, the
signal randomly switches between two levels at a given clock period; this period can be varied to
excite different spectral properties of the system" (sec. 6.3). The sequences are maximum-length
sequences (``scipy.signal.max_len_seq``) held for ``clock`` samples; several inputs get the same
sequence shifted by a third of its period each, so they are uncorrelated over a period.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import max_len_seq

__all__ = ["prbs"]


def prbs(n_samples: int, clock: int = 10, amplitude=1.0, n_inputs: int = 1, nbits: int = 7,
         offset=0.0) -> np.ndarray:
    """A PRBS of ``n_samples`` x ``n_inputs``: +-amplitude about ``offset``, switching at most every ``clock`` samples.

    Parameters
    ----------
    n_samples : int
        Length of the signal.
    clock : int
        Clock period in samples (the thesis's experiments: 10 samples at 5 Hz, sec. 6.5.1).
    amplitude, offset : float or array (n_inputs,)
        Levels offset +- amplitude (e.g. +-10 deg of blade pitch about the hover setting).
    n_inputs : int
        Columns; input j is the sequence shifted by j * period / n_inputs bits.
    nbits : int
        Shift-register length: period 2^nbits - 1 bits (127 bits x 10 samples = 254 s at 5 Hz).
    """
    if n_samples < 1 or clock < 1 or n_inputs < 1:
        raise ValueError(f"prbs needs n_samples, clock, n_inputs >= 1, got {n_samples}, {clock}, {n_inputs}")
    bits, _ = max_len_seq(nbits)
    period = len(bits)
    n_bits = -(-n_samples // clock)
    columns = []
    for j in range(n_inputs):
        shift = (j * period) // n_inputs
        sequence = np.resize(np.roll(bits, -shift), n_bits)
        columns.append(np.repeat(2.0 * sequence - 1.0, clock)[:n_samples])
    signal = np.stack(columns, axis=1)
    return np.asarray(offset, float) + np.asarray(amplitude, float) * signal
