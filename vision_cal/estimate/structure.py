"""Structure left in a fit's residual: a joint-angle periodogram and a sheet map.

A residual that is only measurement noise is white: it depends neither on the joint
angles nor on where on the sheet the mark is. Two scans look for the opposite.

- :func:`harmonic_scan` (per joint): for harmonics ``h = 1..h_max`` the 2-D residual is
  regressed on the sheet displacement a joint error ``a sin(h q) + b cos(h q)`` would
  cause (the joint's Jacobian column times the two sines), after projecting out what the
  fitted model can already absorb (its own Jacobian). The drop in the residual sum of
  squares gives an F statistic, a p-value and the amplitude (deg) for each ``h``: the
  periodogram of that joint.
- :func:`sheet_scan`: whether neighbouring marks share their residual (a local bump,
  a wrinkle, a dent). The statistic is the mean dot product of each mark's residual with
  the mean residual of its ``k`` nearest neighbours on the sheet, its p-value from random
  permutations of the residuals over the marks (no distribution assumed). The map: the
  residual smoothed over neighbours at each mark, the largest one (where and how big), and
  mean residual vectors over a coarse grid of the marked area. Marks the model puts at one
  place (a pose's repeats) are one place: their neighbours are the nearest other places.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse, stats
from scipy.spatial import cKDTree



def _rows(a: np.ndarray) -> np.ndarray:
    return np.asarray(a, dtype=float).reshape(len(a) * 2, -1)


def harmonic_scan(model, q_deg, approach, residual_mm, *, weights=None, h_max: int = 8
                  ) -> dict:
    """Periodogram of the residual against each joint angle (see the module docstring).

    ``model``: the fitted ``RobotModel``; ``q_deg``, ``approach`` (N, 2) (or (N, 3) with
    joint 4, for a model with a tool); ``residual_mm``
    (N, 2) measured minus predicted; ``weights`` (N,) 1/sigma per mark (None: equal).
    Returns ``{"joint1": [{"harmonic", "amplitude_deg", "F", "p_value"}, ...], ...}``.
    """
    q = np.atleast_2d(np.asarray(q_deg, dtype=float))
    r = np.asarray(residual_mm, dtype=float).reshape(-1, 2)
    n = len(q)
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=float)
    J = model.jacobian(q, approach) * w[:, None, None]              # (N, 2, P)
    Jr = _rows(J)
    jq = model.joint_columns(q, approach) * w[:, None, None]
    rw = (r * w[:, None]).reshape(-1)
    # what the model can absorb: project it out of every basis
    Qm, _ = np.linalg.qr(Jr)
    rss = float(rw @ rw)
    dof = 2 * n - Jr.shape[1] - 2
    out = {}
    for j in range(2):
        qj = np.radians(q[:, j])
        rows = []
        for h in range(1, h_max + 1):
            B = np.stack([jq[:, :, j] * np.sin(h * qj)[:, None],
                          jq[:, :, j] * np.cos(h * qj)[:, None]], axis=2)   # (N, 2, 2)
            Br = _rows(B)
            Bp = Br - Qm @ (Qm.T @ Br)
            coef, *_ = np.linalg.lstsq(Bp, rw, rcond=None)
            fitted = Bp @ coef
            drop = float(fitted @ fitted)
            if dof <= 0 or rss - drop <= 0:
                F, p = float("inf"), 0.0
            else:
                F = (drop / 2) / ((rss - drop) / dof)
                p = float(stats.f.sf(F, 2, dof))
            rows.append({"harmonic": h, "amplitude_deg": float(np.degrees(np.hypot(*coef))),
                         "F": float(F), "p_value": p})
        out[f"joint{j + 1}"] = rows
    return out


def _neighbours(xy: np.ndarray, k: int) -> np.ndarray:
    """The ``k`` nearest other marks of each mark (N, k), nearest first (ties by index),
    from a k-d tree: O(N log N) time and O(N k) memory."""
    n = len(xy)
    m = min(k + 1, n)
    dist, idx = cKDTree(xy).query(xy, k=m)
    dist, idx = dist.reshape(n, m), idx.reshape(n, m)
    # the mark itself (or, with repeated positions, one of its twins) is dropped
    self_ = idx == np.arange(n)[:, None]
    dist = np.where(self_, np.inf, dist)
    order = np.lexsort((idx, dist), axis=1)[:, :k]
    return np.take_along_axis(idx, order, axis=1)


def predicted_places(xy_mm, residual_mm) -> tuple[np.ndarray, int]:
    """(the place of each mark (N,) ints, how many places): marks the model puts at one
    place (predicted ``xy - residual`` within 1 nm: the repeats of one commanded pose, as a
    repeatability study or ISO 9283 draws them) share a place; every other mark is its own.
    """
    pred = (np.asarray(xy_mm, float).reshape(-1, 2)
            - np.asarray(residual_mm, float).reshape(-1, 2))
    _, place, count = np.unique(np.round(pred * 1e6), axis=0, return_inverse=True,
                               return_counts=True)
    return place.reshape(-1), len(count)


#: residual values (N x 2 x permutations) held at once by the permutation tests: 100,000
#: marks take 999 permutations 10 at a time (32 MB a block, not 1.6 GB at once)
PERMUTATION_BLOCK = 2_000_000


def _permuted(r: np.ndarray, n_perm: int, rng, stat) -> np.ndarray:
    """``stat`` (permuted residuals (m, N, 2) -> (m,)) of ``n_perm`` random permutations of
    the residuals, drawn in order from ``rng`` a block at a time
    (:data:`PERMUTATION_BLOCK`): the same values as all at once, in memory linear in N."""
    n = len(r)
    block = max(1, PERMUTATION_BLOCK // (2 * n))
    out = [np.zeros(0)]
    for start in range(0, n_perm, block):
        m = min(block, n_perm - start)
        idx = np.array([rng.permutation(n) for _ in range(m)], dtype=np.intp).reshape(-1, n)
        out.append(stat(r[idx]))
    return np.concatenate(out)


def _by_mark(xy, r, k, n_perm, rng):
    """The scan's statistic, its permutations and the smoothed residual (N, 2), each mark
    at its own place: the ``k`` nearest other marks are its neighbours."""
    n = len(xy)
    nb = _neighbours(xy, k)                                         # (N, k)
    # the neighbour structure, built once: the statistic of any permutation of the residuals
    # is then O(N k) (a sparse product), never an N x N matrix
    W = sparse.csr_matrix((np.full(n * k, 1.0 / (n * k)), (np.repeat(np.arange(n), k),
                                                           nb.ravel())), shape=(n, n))
    s0 = float(np.sum(r * (W @ r)))

    def stat(rp):   # (m, N, 2) -> (m,)
        # a block of permutations at once: one sparse product over (N, 2 m) columns (the
        # same sums, column by column, as one product per permutation)
        wr = (W @ rp.transpose(1, 0, 2).reshape(n, -1)).reshape(n, -1, 2).transpose(1, 0, 2)
        return np.sum(np.ascontiguousarray(rp * wr).reshape(len(rp), 2 * n), axis=1)

    perm = _permuted(r, n_perm, rng, stat)
    return s0, perm, (r[nb].sum(axis=1) + r) / (k + 1), xy


def _by_place(xy, r, place, n_places, k, n_perm, rng):
    """:func:`_by_mark` for marks of which several share a place (:func:`predicted_places`):
    a mark's neighbours are the marks of the ``k`` nearest other places, each place weighed
    as one (its mean residual), never the mark's own twins. Twins picked by measured
    position would be the ones whose noise is nearest the mark's own, sharing it (a local
    structure found in pure noise); a residual shared by one pose's repeats is that pose's
    accuracy beyond its repeatability (the verdict's noise floor), not a place on the sheet.
    Linear in marks: three sparse products (marks -> places -> neighbours -> marks)."""
    n = len(xy)
    cols = np.arange(n)
    count = np.bincount(place, minlength=n_places)
    at = np.column_stack([np.bincount(place, xy[:, j], n_places) for j in range(2)])
    at /= count[:, None]
    nb = _neighbours(at, k)                                         # (P, k) places
    member = sparse.csr_matrix((np.ones(n), (place, cols)), shape=(n_places, n))
    mean = sparse.csr_matrix((1.0 / count[place], (place, cols)), shape=(n_places, n))
    rows = np.repeat(np.arange(n_places), k)
    near = sparse.csr_matrix((np.full(n_places * k, 1.0 / k), (rows, nb.ravel())),
                             shape=(n_places, n_places)) @ mean     # (P, N)

    def stat(x):                                                    # x (N, m) -> (m,)
        return np.sum((member @ x) * (near @ x), axis=0) / n

    s0 = float(np.sum(stat(r)))
    perm = _permuted(r, n_perm, rng, lambda rp: stat(rp.transpose(1, 0, 2).reshape(n, -1))
                     .reshape(-1, 2).sum(axis=1))
    smooth = ((near @ r) * k + mean @ r) / (k + 1)                  # (P, 2) per place
    return s0, perm, smooth, at


def sheet_scan(xy_mm, residual_mm, *, k: int = 5, n_perm: int = 999, grid=(4, 3),
               rng=None) -> dict:
    """Do neighbouring marks share their residual? (see the module docstring).

    ``xy_mm`` (N, 2) where the marks are on the sheet; ``residual_mm`` (N, 2) measured minus
    predicted (so ``xy - residual`` is where the model puts each mark: marks it puts at one
    place, a pose's repeats, are one place of the map, :func:`_by_place`). Returns
    ``{"statistic_mm2", "p_value", "k", "peak_mm": [x, y], "peak_size_mm", "map": {...}}``.
    """
    xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    r = np.asarray(residual_mm, dtype=float).reshape(-1, 2)
    n = len(xy)
    place, n_places = predicted_places(xy, r)
    k = int(min(k, n_places - 1))
    if k < 2:
        return {"statistic_mm2": float("nan"), "p_value": 1.0, "k": k}
    rng = np.random.default_rng(0 if rng is None else rng)
    s0, perm, smooth, at = (_by_mark(xy, r, k, n_perm, rng) if n_places == n
                            else _by_place(xy, r, place, n_places, k, n_perm, rng))
    p = float((1 + np.sum(perm >= s0)) / (n_perm + 1)) if n_perm else float("nan")
    i = int(np.argmax(np.linalg.norm(smooth, axis=1)))
    x0, y0 = xy.min(axis=0)
    x1, y1 = xy.max(axis=0)
    gx, gy = grid
    cx = np.clip(((xy[:, 0] - x0) / max(x1 - x0, 1e-9) * gx).astype(int), 0, gx - 1)
    cy = np.clip(((xy[:, 1] - y0) / max(y1 - y0, 1e-9) * gy).astype(int), 0, gy - 1)
    cells = []
    for a in range(gx):
        for b in range(gy):
            m = (cx == a) & (cy == b)
            if m.any():
                cells.append({"x_mm": [float(x0 + a * (x1 - x0) / gx),
                                       float(x0 + (a + 1) * (x1 - x0) / gx)],
                              "y_mm": [float(y0 + b * (y1 - y0) / gy),
                                       float(y0 + (b + 1) * (y1 - y0) / gy)],
                              "n": int(m.sum()),
                              "mean_residual_mm": r[m].mean(axis=0).tolist()})
    return {"statistic_mm2": s0, "p_value": p, "k": k,
            "peak_mm": at[i].tolist(), "peak_size_mm": float(np.linalg.norm(smooth[i])),
            "peak_residual_mm": smooth[i].tolist(),
            "map": {"cells": cells, "grid": [gx, gy]}}
