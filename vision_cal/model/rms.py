"""The RMS helpers (one owner): every ``*_rms_*`` figure in the project is one of these.

``rms_2d`` is what the contract calls ``residual_rms_mm``: the root mean square of the
length of 2-D residual vectors, sqrt(mean(dx^2 + dy^2)) (not per coordinate). ``rms`` is the
plain root mean square of scalars (lengths, angles, pixel values). Both are NaN for no data.
"""

from __future__ import annotations

import numpy as np


def rms_2d(r) -> float:
    """sqrt(mean |r_i|^2) over 2-D vectors ``r`` (N, 2) (any shape ending in 2); NaN if N = 0."""
    r = np.asarray(r, dtype=float).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) if len(r) else float("nan")


def rms(x) -> float:
    """sqrt(mean x_i^2) over every element of ``x``; NaN when ``x`` is empty."""
    x = np.asarray(x, dtype=float).ravel()
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")
