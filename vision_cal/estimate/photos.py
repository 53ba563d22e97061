"""Per-photo offsets: does one photograph see every mark shifted?

A photo whose sheet mapping is off (a bad homography, a moved sheet, a lens the model
lacks) shifts every mark it sees the same way. For each photo, each measured dot is paired
with the mark it belongs to (the combined estimate within ``gate_mm``); its residual
against the final model is averaged over the photo, and a chi-square test of that mean
against the dots' own covariances says whether the offset is beyond the noise.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from vision_cal.config import DEFAULT, PhotoOffsetConfig


def _as_the_marks(im, marks: dict) -> tuple[np.ndarray, np.ndarray]:
    """A photo's dots (K, 2) and their covariances (K, 2, 2) against the reference their
    marks were combined in: a mark measured through the markers (``markers (sheet flat)``:
    the sheet as printed, or a flat sheet whose printed grid is off its layout) is compared
    with each photo's marker mapping of its dot, not with its printed-grid position (which
    carries the print's displacement at the mark, the same in every photo: on a sheet
    printed 0.2 mm off its layout five of six photos were flagged as moved together)."""
    xy = np.array(im.dots_xy_mm, float)
    cov = np.array(im.dots_cov_mm2, float)
    g_xy = np.asarray(getattr(im, "dots_global_xy_mm", ()), float).reshape(-1, 2)
    g_cov = np.asarray(getattr(im, "dots_global_cov_mm2", ()), float).reshape(-1, 2, 2)
    names = tuple(getattr(im, "dots_mark", ()) or ())
    if len(names) != len(xy) or len(g_xy) != len(xy) or len(g_cov) != len(xy):
        return xy, cov
    for j, mid in enumerate(names):
        m = marks.get(mid) if mid else None
        if getattr(m, "reference", None) == "markers (sheet flat)" \
                and np.all(np.isfinite(g_xy[j])):
            xy[j], cov[j] = g_xy[j], g_cov[j]
    return xy, cov


def per_photo_offsets(measurement, model, q_by_id: dict, approach_by_id: dict, *,
                      config: PhotoOffsetConfig | None = None) -> list[dict]:
    """One entry per measured photo: mean residual (mm), its std, chi2 p-value, flag
    (``config``: gate and level, default ``vision_cal.config.DEFAULT.per_photo_offsets``)."""
    cfg = config or DEFAULT.per_photo_offsets
    gate_mm, alpha = cfg.gate_mm, cfg.alpha
    marks = measurement.marks
    ids = [i for i in marks if i in q_by_id]
    if not ids:
        return []
    mxy = np.array([marks[i].xy_mm for i in ids], float)
    pred = model.predict(np.array([q_by_id[i] for i in ids]),
                         np.array([approach_by_id[i] for i in ids]))
    n_photos = max(sum(im.status == "ok" for im in measurement.images), 1)
    out = []
    for im in measurement.images:
        if im.status != "ok" or not len(im.dots_xy_mm):
            continue
        xy, cov_all = _as_the_marks(im, marks)
        d = np.linalg.norm(xy[:, None] - mxy[None], axis=2)
        k = np.argmin(d, axis=1)
        ok = d[np.arange(len(k)), k] < gate_mm
        if ok.sum() < 2:
            continue
        r = xy[ok] - pred[k[ok]]
        cov = cov_all[ok]
        w = np.linalg.inv(cov + 1e-12 * np.eye(2))
        W = w.sum(axis=0)
        mean = np.linalg.solve(W, np.einsum("nij,nj->i", w, r))
        cov_mean = np.linalg.inv(W)
        # the model residual itself (robot repeatability) is common to all photos: compare
        # against the spread of the photo means rather than only the dots' own noise
        out.append({"file": im.file, "n_marks": int(ok.sum()), "offset_mm": mean.tolist(),
                    "offset_std_mm": np.sqrt(np.diag(cov_mean)).tolist(), "_r": r})
    if not out:
        return []
    # robot repeatability makes a photo with few marks scatter more than its dots' noise:
    # the test uses the residual scatter of single marks about the model
    allr = np.concatenate([o["_r"] for o in out])
    s2 = np.mean(np.sum(allr**2, axis=1)) / 2
    for o in out:
        n = o.pop("_r").shape[0]
        m = np.asarray(o["offset_mm"])
        chi2 = float(m @ m) / (s2 / n) if s2 > 0 else 0.0
        p = float(stats.chi2.sf(chi2, 2))
        o.update(chi2=chi2, p_value=p, flagged=bool(p < alpha / n_photos))
    return out
