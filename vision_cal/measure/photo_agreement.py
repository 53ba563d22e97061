"""A photo whose dots all sit away from where the other photos see them (issue 18).

A bad sheet mapping in one photo (a marker misread, a lens that does not fit that photo)
moves every dot of it together. Grouped with the other photos' dots, each of its dots then
becomes a second candidate near its mark ("two candidate dots"), and the marks it shares
with the others would be left out. Instead the photo is left out: for each photo with at
least ``min_dots`` dots that the other photos see too (nearest dot of another photo
within ``search_mm``), the median displacement from them is compared with
``max_offset_mm`` (far beyond a mapping's error of hundredths of a millimetre, far
below the spacing of marks) and with the displacements' own scatter (a photo moved as a
whole, not dots that happen to be near others). Needs at least three usable photos, so that
"the others" agree among themselves. The thresholds are config ``photo_agreement``
(:class:`vision_cal.config.PhotoAgreementConfig`).
"""

from __future__ import annotations

import numpy as np

from vision_cal.config import DEFAULT, PhotoAgreementConfig


def _all_dots(im) -> np.ndarray:
    """A photo's dots, refined and only seen (:mod:`vision_cal.measure.views`): a bad
    mapping moves both."""
    xy = np.asarray(im.dots_xy_mm, float).reshape(-1, 2)
    seen = np.asarray(getattr(im, "seen_xy_mm", ()), float).reshape(-1, 2)
    return np.concatenate([xy, seen]) if len(seen) else xy


def disagreeing_photos(images, config: PhotoAgreementConfig | None = None) -> dict[int, str]:
    """{index in ``images``: reason} of the usable photos whose dots are displaced together
    from the other photos' (``images``: results with ``status``, ``dots_xy_mm`` (K, 2) and
    optionally ``seen_xy_mm`` (S, 2), the dots seen but not refined);
    ``config`` the thresholds (default ``DEFAULT.photo_agreement``)."""
    cfg = config or DEFAULT.photo_agreement
    seen = [_all_dots(im) for im in images]
    ok = [k for k, im in enumerate(images) if im.status == "ok" and len(seen[k])]
    if len(ok) < cfg.min_photos:
        return {}
    out = {}
    for k in ok:
        others = np.concatenate([seen[j] for j in ok if j != k])
        if not len(others):
            continue
        xy = seen[k]
        d = xy[:, None, :] - others[None, :, :]
        dist = np.linalg.norm(d, axis=2)
        j = dist.argmin(axis=1)
        near = dist[np.arange(len(xy)), j] <= cfg.search_mm
        if near.sum() < cfg.min_dots:
            continue
        disp = d[np.arange(len(xy)), j][near]
        med = np.median(disp, axis=0)
        spread = 1.4826 * np.median(np.linalg.norm(disp - med, axis=1))
        size = float(np.hypot(*med))
        if size > cfg.max_offset_mm and size > cfg.spread_factor * spread:
            out[k] = (f"disagrees with the other photos: its {int(near.sum())} dots sit "
                      f"{size:.2f} mm ({med[0]:+.2f}, {med[1]:+.2f}) from where they see them "
                      "(a bad sheet mapping in this photo); left out, its marks measured on "
                      "the others")
    if len(out) * 2 >= len(ok):   # no majority to disagree with
        return {}
    return out
