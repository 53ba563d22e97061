"""The print field checked by two halves of the camera places, and the rule that applies it
(measure/replicate.py, issue 37). Projected corners, no rendering."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from vision_cal.config import DEFAULT
from vision_cal.measure.asprinted import estimate_as_printed, gauge_projector
from vision_cal.measure.replicate import (AGREE, DISAGREE, FAILED, NOT_CHECKED,
                                          NOT_REPLICATED, NOT_SIGNIFICANT, claim_of,
                                          split_halves, with_replication)

SIZE = (2000, 1500)
K = np.array([[2200.0, 0, 999.5], [0, 2200.0, 749.5], [0, 0, 1]])
DIST = np.array([-0.06, 0.03, 0.0, 0.0, 0.0])
#: camera places (tilt x deg, tilt y deg, centre x mm, centre y mm), alternating sides so
#: that every half of them sees the sheet from round it
PLACES = [(0, 0, 0, 0), (14, 0, -160, 0), (-14, 0, 160, 0), (0, 14, 0, 160),
          (0, -14, 0, -160), (10, 10, -110, 110), (-10, -10, 110, -110), (10, -10, -110, -110)]


def _layout():
    """4 x 3 markers of 30 mm over 420 x 300 mm (ids, corners (M, 4, 2), y up)."""
    xs, ys = np.linspace(-210, 180, 4), np.linspace(-150, 120, 3)
    c = np.array([[[x, y + 30], [x + 30, y + 30], [x + 30, y], [x, y]]
                  for y in ys for x in xs], float)
    return np.arange(len(c)), c


def _field(declared, rms, phase=0.0):
    """A smooth print field in the survey's gauge, ``rms`` mm (2-D RMS)."""
    p = declared.reshape(-1, 2)
    d = np.column_stack([np.sin(2 * np.pi * p[:, 1] / 230 + 1 + phase) + 0.4 * p[:, 0] / 210,
                         np.sin(2 * np.pi * p[:, 0] / 190 + phase) + 0.5 * (p[:, 1] / 150) ** 2])
    d = (gauge_projector(declared, np.ones(declared.shape[:2], bool)) @ d.ravel()).reshape(-1, 2)
    return (d * rms / np.sqrt(np.mean(np.sum(d**2, axis=1)))).reshape(declared.shape)


def _views(printed, ids, declared, places, rng, noise_px=0.1, first=0):
    views = []
    for k, (rx, ry, tx, ty) in enumerate(places):
        rvec = np.array([np.pi + np.radians(rx), np.radians(ry), 0.03 * k])
        R = cv2.Rodrigues(rvec)[0]
        t = -R @ np.array([tx, ty, 760.0])
        P = np.column_stack([printed.reshape(-1, 2), np.zeros(printed.size // 2)])
        px, _ = cv2.projectPoints(P, rvec, t, K, DIST)
        px = px.reshape(-1, 4, 2) + rng.normal(0, noise_px, (len(ids), 4, 2))
        views.append((f"img_{first + k}.png", ids, declared, px))
    return views


def _replicated(views, config=None, lens_free=True):
    cfg = config or DEFAULT.as_printed
    start = (K, DIST * 0.7) if lens_free else (K, DIST)
    ap = estimate_as_printed(views, *start, SIZE, lens_free=lens_free, config=cfg)
    ap = with_replication(ap, views, *start, SIZE, lens_free=lens_free, config=cfg)
    return replace(ap, source="survey")   # judged as a survey (no ratio rule of the stage)


@pytest.fixture(scope="module")
def world():
    ids, declared = _layout()
    return ids, declared, _field(declared, 0.17)


def test_the_halves_of_one_print_agree_and_its_field_is_applied(world):
    """Eight places, a 0.17 mm field, corners with 0.1 px noise: the halves (places
    alternately) agree within what each states (chi2/dof at most 2), follow one field
    (correlation), and the field is significant: applied."""
    ids, declared, dev = world
    ap = _replicated(_views(declared + dev, ids, declared, PLACES, np.random.default_rng(5)))
    r = ap.replication
    assert r["status"] == AGREE and r["split"] == "places"
    assert r["files_a"] == ["img_0.png", "img_2.png", "img_4.png", "img_6.png"]
    assert r["n_corners"] == ids.size * 4 and r["chi2_dof"] <= 2.0
    assert min(r["correlation_xy"]) > 0.8
    assert r["rms_diff_mm"] < 3 * np.hypot(r["unresolved_a_mm"], r["unresolved_b_mm"])
    assert ap.significance["p_value"] < 1e-6
    assert claim_of(ap).applied
    assert "agree on the print: chi2/dof" in r["text"]


def test_halves_that_saw_two_prints_disagree_and_the_field_is_not_applied(world):
    """The second half of the places photographed another print (the field turned by a
    phase): the halves' difference is far beyond what they state, the field is not
    applied, and the reason says so (the lens declared: the halves' solves are quicker)."""
    ids, declared, dev = world
    rng = np.random.default_rng(6)
    other = _field(declared, 0.17, phase=2.0)
    views = []
    for k, place in enumerate(PLACES[:6]):
        printed = declared + (dev if k % 2 == 0 else other)
        views += _views(printed, ids, declared, [place], rng, first=k)
    ap = _replicated(views, lens_free=False)
    assert ap.replication["status"] == DISAGREE
    assert ap.replication["chi2_dof"] > DEFAULT.as_printed.replication_max_chi2_dof
    claim = claim_of(ap)
    assert claim.status == NOT_REPLICATED and "chi2/dof" in claim.reason


def test_a_field_from_too_few_places_is_not_claimed_and_says_what_resolves_it(world):
    """Four places: no two independent halves of three; the field claims nothing and the
    reason counts the places missing."""
    ids, declared, dev = world
    ap = _replicated(_views(declared + dev, ids, declared, PLACES[:4], np.random.default_rng(7)))
    assert ap.replication["status"] == NOT_CHECKED
    claim = claim_of(ap)
    assert claim.status == NOT_REPLICATED and "2 more places" in claim.reason


def test_a_print_on_its_layout_is_not_significant(world):
    """The print exactly as declared: its field is noise, not significant against its own
    covariance (p above 0.001), not applied, however well the halves agree."""
    ids, declared, _ = world
    ap = _replicated(_views(declared, ids, declared, PLACES, np.random.default_rng(8)))
    assert ap.significance["p_value"] > DEFAULT.as_printed.field_alpha
    assert claim_of(ap).status == NOT_SIGNIFICANT


def test_a_solve_stopped_on_its_limit_is_a_failure(world):
    """The bundle adjustment stopped on its evaluation limit: ``stopped`` says so, nothing
    is replicated and the claim is a failure, whatever its figures."""
    ids, declared, dev = world
    cfg = replace(DEFAULT.as_printed, max_evaluations=2)
    ap = _replicated(_views(declared + dev, ids, declared, PLACES, np.random.default_rng(9)),
                     cfg)
    assert ap.stopped and "evaluation limit (2)" in ap.stopped
    assert ap.replication is None
    claim = claim_of(ap, cfg)
    assert claim.status == FAILED and not claim.applied


def test_the_halves_are_camera_places_else_photos():
    assert split_halves([0, 1, 2, 3, 4, 5], 3).split == "places"
    h = split_halves([0, 0, 1, 1, 2, 2, 3], 3)   # 4 places, repeated photos
    assert h.split == "photos" and h.a == (0, 2, 4, 6) and h.b == (1, 3, 5)
    assert split_halves([0, 1, 2, 3, 4], 3) is None


def test_a_field_not_applied_moves_no_mark_and_carries_the_print_in_their_variance(world):
    """measurement.json ``print`` of a layout found but not applied (its halves disagree):
    ``applied`` false with the status and the reason, and the print the photos' mappings
    leave (each marker 0.1 mm off, the same in every photo) carried in every mark's
    variance as from one place; a failed solve writes no figure of its layout."""
    from types import SimpleNamespace

    from vision_cal.measure.asprinted import AsPrinted
    from vision_cal.measure.print_stage import print_stage

    ids, declared, dev = world
    rel = np.ones(declared.shape[:2], bool)
    ap = AsPrinted(ids, declared, declared + dev, np.full(declared.shape, 0.01), rel, K,
                   DIST, SIZE, True, (), (), (), 8, "views",
                   replication={"status": DISAGREE, "reason": "the halves' fields differ"},
                   significance={"chi2_dof": 50.0, "dof": 90, "p_value": 0.0})
    shift = np.random.default_rng(3).normal(0, 0.1 / np.sqrt(2), (len(ids), 2))
    images = [SimpleNamespace(status="ok", marker_ids=ids,
                              markers_px=declared + shift[:, None, :],
                              mapping=SimpleNamespace(image_to_sheet=lambda p: p))
              for _ in range(3)]
    session = SimpleNamespace(sheet=SimpleNamespace(markers=[
        SimpleNamespace(id=i, corners_mm=c) for i, c in zip(ids, declared)]))
    pr = print_stage(session, images, None, DEFAULT, kept_declared=ap)
    assert pr["applied"] is False and pr["status"] == NOT_REPLICATED
    assert "the halves' fields differ" in pr["reason"]
    seen = float(np.sqrt(np.mean(np.sum(shift**2, axis=1))))
    assert abs(pr["limit_mm"] - seen) < 1e-9 and abs(pr["sigma_mm"] - seen / np.sqrt(2)) < 1e-9
    assert pr["replication"]["status"] == DISAGREE and pr["rms_mm"] > 0
    failed = print_stage(session, images, None, DEFAULT,
                         kept_declared=replace(ap, stopped="the bundle adjustment stopped"))
    assert failed["status"] == FAILED and "rms_mm" not in failed and failed["limit_mm"] > 0
    # applied, its halves scattering 1.3 times what they state: the limit on the marks and
    # the field's shared covariance grow by that (the std the halves showed)
    agreed = replace(ap, replication={"status": AGREE, "chi2_dof": 1.69},
                     field_read={"basis": "homography", "centre_mm": [0, 0], "scale_mm": 1.0,
                                 "cov_mm2": np.eye(8).tolist()})
    pr = print_stage(session, images, agreed, DEFAULT)
    assert pr["applied"] and pr["stated_scale"] == pytest.approx(1.3)
    assert pr["limit_mm"] == pytest.approx(1.3 * agreed.unresolved_mm)
    assert np.allclose(pr["field"]["cov_mm2"], 1.69 * np.eye(8))
    calm = print_stage(session, images, replace(agreed, replication={"status": AGREE,
                                                                     "chi2_dof": 0.5}), DEFAULT)
    assert calm["limit_mm"] == pytest.approx(agreed.unresolved_mm)


def test_only_a_field_applied_or_found_on_its_layout_measured_the_print():
    from vision_cal.measure.replicate import (APPLIED, FAILED, NOT_REPLICATED, NOT_RESOLVED,
                                              NOT_SIGNIFICANT, Claim, measures_the_print)
    assert measures_the_print(Claim(APPLIED)) and measures_the_print(Claim(NOT_SIGNIFICANT, "."))
    assert not any(measures_the_print(Claim(s, ".")) for s in (FAILED, NOT_REPLICATED,
                                                               NOT_RESOLVED))
