"""The tests' own removal of a similarity from a sheet's displacements (the gauge a survey
reports its layout in), written apart from ``measure/asprinted``."""

import numpy as np


def similarity(p: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The small similarity (tx, ty, a, b) best fitting displacements ``d`` (N, 2) at points
    ``p`` (N, 2): d = t + [[a, -b], [b, a]] p, by least squares."""
    p, d = np.asarray(p, float), np.asarray(d, float)
    one, zero = np.ones(len(p)), np.zeros(len(p))
    A = np.vstack([np.column_stack([one, zero, p[:, 0], -p[:, 1]]),
                   np.column_stack([zero, one, p[:, 1], p[:, 0]])])
    return np.linalg.lstsq(A, np.r_[d[:, 0], d[:, 1]], rcond=None)[0]
