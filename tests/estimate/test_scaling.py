"""The sheet-map permutation tests are linear in marks (issue 19): the neighbour structure is
built once, never an N x N matrix; and it is the same statistic as the plain definition.
Figures for 40 to 20,000 marks: bench/marks_scaling.py."""

import tracemalloc

import numpy as np

import vision_cal.estimate.sheet as sheet
from vision_cal.estimate.structure import sheet_scan


def _marks(n, seed=11):
    rng = np.random.default_rng(seed)
    xy = rng.uniform([-400, -300], [400, 300], (n, 2))
    return rng, xy, rng.normal(0, 0.01, (n, 2)) + 0.02 * np.sin(xy / 90.0)


def test_sheet_scan_statistic_is_the_plain_definition():
    _, xy, r = _marks(60)
    d = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    np.fill_diagonal(d, np.inf)
    nb = np.argsort(d, axis=1)[:, :5]
    plain = float(np.mean(np.sum(r * r[nb].mean(axis=1), axis=1)))
    out = sheet_scan(xy, r, k=5, n_perm=0)
    assert abs(out["statistic_mm2"] - plain) <= 1e-12 * abs(plain)


def test_grid_smoother_is_the_gaussian_within_its_cells():
    """Above EXACT_MAX_MARKS marks the kernel is binned: its leave-one-out mean agrees with
    the exact Gaussian to a few per cent of the smoothed field (cells of a third of the
    length; a mark mislaid by one cell would be off by ~30 %)."""
    _, xy, r = _marks(sheet.EXACT_MAX_MARKS + 400)
    grid = sheet._Smoother(xy, 60.0)
    assert grid.W is None
    D2 = np.sum((xy[:, None] - xy[None]) ** 2, axis=2)
    W = np.exp(-D2 / (2 * 60.0**2))
    np.fill_diagonal(W, 0.0)
    want = (W @ r) / W.sum(axis=1, keepdims=True)
    got = grid(r)
    rel = np.sqrt(np.mean((got - want) ** 2) / np.mean(want**2))
    assert rel < 0.03, rel


def _peak_mb(f) -> float:
    tracemalloc.start()
    try:
        f()
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def test_memory_is_linear_in_marks():
    """6,000 marks: an N x N float matrix would be 288 MB; the neighbour structures of both
    scans take a few MB (O(N k) and a fixed grid)."""
    _, xy, r = _marks(6000)
    ext = (*xy.min(axis=0), *xy.max(axis=0))
    assert _peak_mb(lambda: sheet_scan(xy, r, n_perm=3)) < 40
    assert _peak_mb(lambda: sheet.smooth_residual(xy, r, ext, n_perm=3, alpha=1.0)) < 40
