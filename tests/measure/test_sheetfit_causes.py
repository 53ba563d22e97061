"""The sheet-fit gate and its causes (issue 28 section 1, last bullet), on marker corners
projected by OpenCV (no rendering): a phone photo 3264 x 2448 of a correctly described
60-marker sheet, with what real paper and a real phone do (an undeclared lens with
tangential terms, a print off its layout by a feed wave and a bow, corner noise), is
measured; typing mistakes are still refused and named; a refusal that is not a typing
mistake names the print, the paper or the lens with the size each explains."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from vision_cal.config import DEFAULT
from vision_cal.measure.sheetfit import (corner_tolerance_mm, misfit_parts, misfit_reason,
                                         sheet_misfit)

SIZE = (3264, 2448)
WRONG_PLACE = "markers not where sheet.markers puts them"


def sheet_60(side=14.0, pitch=27.0):
    """(60, 4, 2) declared corners: 10 x 6 markers, TL TR BR BL with y up."""
    out = []
    for r in range(6):
        for c in range(10):
            x0, y0 = (c - 4.5) * pitch - side / 2, (r - 2.5) * pitch - side / 2
            out.append([[x0, y0 + side], [x0 + side, y0 + side], [x0 + side, y0], [x0, y0]])
    return np.array(out, float)


def print_field(xy, rms=0.17):
    """A printer's smooth deviation in the paper's plane (mm): a wave along the feed (y)
    and a bow, scaled to ``rms`` (issue 28: 0.17 mm RMS, 0.30 max)."""
    x, y = xy[..., 0] / 140.0, xy[..., 1] / 80.0
    d = np.stack([0.6 * np.sin(2.1 * np.pi * y + 0.4) + 0.5 * y * y - 0.2,
                  0.4 * x * x - 0.15 + 0.3 * np.sin(1.3 * np.pi * x)], axis=-1)
    d -= d.reshape(-1, 2).mean(axis=0)
    return d * rms / np.sqrt(np.mean(np.sum(d.reshape(-1, 2) ** 2, axis=1)))


def photo(mm, *, dist=(0, 0, 0, 0, 0), printed=0.0, noise=0.0, seed=0, tilt_deg=14.0):
    """Corner pixels of the sheet ``mm`` (N, 4, 2) printed ``printed`` mm RMS off its
    layout, seen by a phone (f 2800 px) 300 mm away, tilted; Gaussian corner noise (px)."""
    true = mm + (print_field(mm, printed) if printed else 0.0)
    obj = np.c_[true.reshape(-1, 2), np.zeros(true.size // 2)]
    K = np.array([[2800.0, 0, 1632 + 11], [0, 2800.0, 1224 - 7], [0, 0, 1]])
    t = np.deg2rad(tilt_deg)
    R = cv2.Rodrigues(np.array([t, 0.3 * t, 0.1]))[0]
    tvec = np.array([4.0, -3.0, 300.0])
    px, _ = cv2.projectPoints(obj, cv2.Rodrigues(R)[0], tvec, K, np.asarray(dist, float))
    px = px.reshape(-1, 2) + noise * np.random.default_rng(seed).standard_normal((len(obj), 2))
    return px.reshape(-1, 4, 2)


PHONE_LENS = (-0.08, 0.03, 4e-4, -3e-4, 0.0)   # undeclared (bench/phone.py: k1 -0.04..-0.08)


def _gate(mm, px):
    H, _ = cv2.findHomography(px.reshape(-1, 2), mm.reshape(-1, 2), 0)
    p = cv2.perspectiveTransform(px.reshape(1, -1, 2), H)[0]
    rms = float(np.sqrt(np.mean(np.sum((p - mm.reshape(-1, 2)) ** 2, axis=1))))
    # mm per px at the markers: declared over seen marker sides
    mmpp = float(np.median(np.linalg.norm(np.diff(mm, axis=1), axis=2)
                           / np.linalg.norm(np.diff(px, axis=1), axis=2)))
    return rms, mmpp, sheet_misfit(mm, px, rms, mmpp, size_px=SIZE)


def test_a_real_phone_photo_of_a_correct_sheet_is_measured():
    """The issue's case: the homography leaves more than a printer and 2 px (the old gate
    refused it: "markers not where sheet.markers puts them"); the lens and the print
    explain it, so it is measured."""
    mm = sheet_60()
    px = photo(mm, dist=PHONE_LENS, printed=0.17, noise=0.5, seed=1)
    rms, mmpp, why = _gate(mm, px)
    assert rms > corner_tolerance_mm(mm, mmpp)          # the old gate's refusal
    assert why is None, why


@pytest.mark.parametrize("edit,cause", [
    (lambda c: c[:, ::-1], "corner order"),
    (lambda c: c.mean(axis=1, keepdims=True) + 0.9 * (c - c.mean(axis=1, keepdims=True)),
     "marker size"),
    (lambda c: c[np.random.default_rng(5).permutation(len(c))], WRONG_PLACE),
], ids=["reversed", "size-0.9", "shuffled-ids"])
def test_typing_mistakes_are_refused_and_named(edit, cause):
    mm = sheet_60()
    px = photo(mm, dist=PHONE_LENS, printed=0.17, noise=0.5, seed=2)
    _, _, why = _gate(edit(mm), px)
    assert why is not None and cause in why, why
    if cause != WRONG_PLACE:
        assert WRONG_PLACE not in why


def test_a_fold_is_named_the_paper_not_the_markers():
    """Two creases: the strip of paper between them (one column of markers) displaced
    2 mm along y (not smooth, not a typing mistake): refused as the print or the paper,
    with its size, not as markers elsewhere than declared."""
    mm = sheet_60()
    true = mm.copy()
    true[(mm[:, :, 0] > 0) & (mm[:, :, 0] < 27)] += [0.0, 2.0]
    px = photo(true, dist=PHONE_LENS, noise=0.5, seed=3)
    _, _, why = _gate(mm, px)
    assert why is not None and "the print or the paper" in why, why
    assert WRONG_PLACE not in why


@pytest.mark.parametrize("what", ["lens", "print"])
def test_the_sizes_named_are_what_each_cause_leaves(what):
    """Each part's size is what that cause alone leaves after a homography (noise-free),
    within 15 %; the other part stays small."""
    mm = sheet_60()
    kw = {"dist": PHONE_LENS} if what == "lens" else {"printed": 0.17}
    alone = misfit_parts(mm, photo(mm, **kw), size_px=SIZE).total_mm
    parts = misfit_parts(mm, photo(mm, noise=0.5, seed=4, **kw), size_px=SIZE)
    got, other = ((parts.lens_mm, parts.smooth_mm) if what == "lens"
                  else (parts.smooth_mm, parts.lens_mm))
    assert got == pytest.approx(alone, rel=0.15), (what, parts, alone)
    assert other < 0.5 * alone, (what, parts, alone)
    reason = misfit_reason(mm, photo(mm, noise=0.5, seed=4, **kw), parts.total_mm, 0.0,
                           size_px=SIZE, parts=parts)
    assert f"a lens would explain {parts.lens_mm:.2g} mm" in reason
    assert f"a smooth print or paper field {parts.smooth_mm:.2g} mm" in reason


def test_the_split_is_read_from_the_config_when_called():
    """Too few markers for the field by the config passed: no field is fitted."""
    mm = sheet_60()
    px = photo(mm, printed=0.17, noise=0.5, seed=6)
    cfg = replace(DEFAULT.sheet_fit, smooth_min_markers=61)
    assert misfit_parts(mm, px, size_px=SIZE).smooth_fitted
    assert not misfit_parts(mm, px, size_px=SIZE, config=cfg).smooth_fitted


def test_a_lens_applied_is_a_claim_not_absorbed():
    """The same photo with a lens applied that does not undo the real one (``raw_px``
    given: a declared or estimated lens): the lens terms may not absorb it; refused and
    blamed on camera.dist, not on the sheet."""
    mm = sheet_60()
    px = photo(mm, dist=PHONE_LENS, printed=0.17, noise=0.5, seed=1)
    rms, mmpp, why = _gate(mm, px)
    assert why is None
    why = sheet_misfit(mm, px, rms, mmpp, size_px=SIZE, raw_px=px)
    assert why is not None and "likely cause: camera.dist" in why, why
