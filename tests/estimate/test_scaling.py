"""The sheet-map permutation tests are linear in marks (issue 19): the neighbour structure is
built once, never an N x N matrix; and it is the same statistic as the plain definition.
Figures for 40 to 20,000 marks: bench/marks_scaling.py."""

import tracemalloc

import numpy as np

import vision_cal.estimate.sheet as sheet
from vision_cal.estimate.select import marks_away_from
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


def _repeats(n_poses=10, repeats=25, seed=41, sigma=0.02):
    """A repeatability study's marks (issue 41): ``n_poses`` places on the sheet, each
    commanded ``repeats`` times (every place once, then again); measured = the model's
    place + ``sigma`` of noise; the residual is that noise, as a fit to the truth leaves it."""
    rng = np.random.default_rng(seed)
    at = np.tile(rng.uniform([-300, -200], [300, 200], (n_poses, 2)), (repeats, 1))
    r = rng.normal(0, sigma, at.shape)
    return at + r, r


def test_a_poses_repeats_are_not_neighbours_picked_by_their_noise():
    """Pure noise at repeated places shares nothing: picked by measured position, a mark's
    nearest repeats were the ones whose noise is nearest its own (p 0.001 on this seed, a
    local structure found in noise at every repeatability study); a mark's neighbours are
    now the other places (p of an honest permutation test, above the selection's alpha / 2
    = 0.005 but one time in 200)."""
    xy, r = _repeats()
    assert sheet_scan(xy, r)["p_value"] > 0.005


def test_repeated_places_statistic_is_the_plain_definition():
    """With repeats: the mean over marks of the residual dotted with the mean, over the k
    nearest other places, of each place's mean residual (an N x P matrix here, a sparse
    product in the scan)."""
    xy, r = _repeats(n_poses=12, repeats=3, seed=5)
    at = xy - r                                                     # the model's places
    r = r + 0.02 * np.sin(at / 90.0)
    xy = at + r
    place = np.tile(np.arange(12), 3)
    at = np.array([xy[place == p].mean(axis=0) for p in range(12)])
    mean = np.array([r[place == p].mean(axis=0) for p in range(12)])
    d = np.linalg.norm(at[:, None] - at[None], axis=2)
    np.fill_diagonal(d, np.inf)
    nb = np.argsort(d, axis=1)[:, :5]                               # (P, k) places
    plain = float(np.mean(np.sum(r * mean[nb].mean(axis=1)[place], axis=1)))
    out = sheet_scan(xy, r, k=5, n_perm=0)
    assert abs(out["statistic_mm2"] - plain) <= 1e-12 * abs(plain)


def test_a_bump_under_repeated_places_is_still_found():
    """A bump (0.1 mm, 80 mm wide) under 40 places drawn 5 times each is found where it is:
    the repeats are left out of each other's neighbours, not the places around them."""
    xy, r = _repeats(n_poses=40, repeats=5, seed=7, sigma=0.01)
    centre = np.median(xy, axis=0)
    at = xy - r
    bump = 0.1 * np.exp(-np.sum((at - centre) ** 2, axis=1) / (2 * 80.0**2))
    r = r + bump[:, None] * np.array([0.6, 0.8])
    out = sheet_scan(at + r, r)
    assert out["p_value"] < 0.005
    assert np.hypot(*(np.array(out["peak_mm"]) - centre)) < 2 * 80.0


def test_marks_away_from_a_structure_count_places_not_repeats():
    """The neighbourhood left out around a local structure is its k nearest places, as the
    map counts them: with 4 repeats at each place 10 mm apart on a line and k = 2, the
    places at 0, 10 and 20 mm (radius 1.5 x 20 mm), not the peak's own repeats."""
    rng = np.random.default_rng(3)
    x = np.tile(np.arange(8) * 10.0, 4)
    xy = np.column_stack([x, np.zeros_like(x)]) + rng.normal(0, 0.02, (32, 2))
    place = np.tile(np.arange(8), 4)
    away, radius = marks_away_from(xy, {"peak_mm": [0.0, 0.0], "k": 2}, place)
    assert np.array_equal(~away, x <= 20.0) and 29.5 < radius < 30.5
    # counted by marks: the peak's own repeats (some of them) and nothing around it
    alone = ~marks_away_from(xy, {"peak_mm": [0.0, 0.0], "k": 2})[0]
    assert alone.any() and np.all(x[alone] == 0.0)


def test_permutations_in_blocks_are_the_same_test(monkeypatch):
    """The permutations drawn a few at a time (memory linear in marks: 100,000 marks held
    1.6 GB at once) give the same p-value as all at once, with and without repeats."""
    import vision_cal.estimate.structure as structure

    _, xy, r = _marks(300)
    r = r - 0.018 * np.sin(xy / 90.0)                               # a weaker structure
    rep_xy, rep_r = _repeats(n_poses=30, repeats=4, seed=9)
    at = rep_xy - rep_r
    rep_r = rep_r + 0.004 * np.sin(at / 90.0)
    cases = [(xy, r), (at + rep_r, rep_r)]
    once = [sheet_scan(a, b, n_perm=99) for a, b in cases]
    monkeypatch.setattr(structure, "PERMUTATION_BLOCK", 7 * 2 * 300)   # blocks of 7 and 5
    again = [sheet_scan(a, b, n_perm=99) for a, b in cases]
    for a, b in zip(once, again):
        assert a["p_value"] == b["p_value"] and a["statistic_mm2"] == b["statistic_mm2"]
        assert 0.01 < a["p_value"] < 1      # permutations on either side of the statistic
