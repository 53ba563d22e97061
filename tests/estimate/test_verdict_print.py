"""The print's limit in the verdict (#28): from one camera place never ready, and the
expected target error covers it."""

import pytest

from tests.estimate.test_verdict import _fit_doc
from vision_cal.estimate.verdict import R95_PER_RMS, judge


def test_one_place_print_makes_check_and_adds_to_the_expected_error():
    doc = _fit_doc()
    base = judge(doc)
    assert base.status == "ready"
    one = judge({**doc, "print": {"source": "one place", "seen_rms_mm": 0.06,
                                  "limit_mm": 0.09, "sigma_mm": 0.064}})
    assert one.status == "check"
    assert any("survey" in r for r in one.reasons)
    assert one.expected_target_error_mm >= R95_PER_RMS * 0.09
    assert one.expected_target_error_mm == pytest.approx(
        (base.expected_target_error_mm ** 2 + (R95_PER_RMS * 0.09) ** 2) ** 0.5)


def test_a_surveyed_print_adds_its_uncertainty_without_a_check():
    doc = _fit_doc()
    base = judge(doc)
    v = judge({**doc, "print": {"source": "survey", "rms_mm": 0.17, "limit_mm": 0.005}})
    assert v.status == "ready"
    assert v.expected_target_error_mm > base.expected_target_error_mm


def test_grid_off_its_layout_is_the_print_once_the_print_is_measured():
    doc = _fit_doc()
    doc["diagnosis"] = {"sheet_height": {"claimed": False, "not_claimed_as": "mapping"}}
    doc["marks"]["c00"]["local_minus_global_mm"] = [0.2, 0.1]
    assert judge(doc).status == "check"
    v = judge({**doc, "print": {"source": "views", "rms_mm": 0.17, "limit_mm": 0.002}})
    assert v.status == "ready" and any("as printed" in r for r in v.reasons)


def test_a_layout_found_on_its_declaration_changes_nothing():
    doc = _fit_doc()
    doc["diagnosis"] = {"sheet_height": {"claimed": False, "not_claimed_as": "mapping"}}
    doc["marks"]["c00"]["local_minus_global_mm"] = [0.2, 0.1]
    v = judge({**doc, "print": {"source": "views", "applied": False, "rms_mm": 0.01,
                                "unresolved_mm": 0.01, "limit_mm": 0.0}})
    assert v.status == "check" and v.expected_target_error_mm == judge(doc).expected_target_error_mm


def test_a_print_not_measured_is_check_whatever_the_markers_show():
    """One rule for a fixed camera without a survey (and any run whose photos come from
    fewer than three places): the markers of a clean print show nothing beyond the photo's
    mapping (limit 0), yet the print is not measured - a printer puts ink 0.1-0.3 mm off its
    layout and a homography takes the smooth part: "check", with a printer's 0.07 mm in
    the expected error and in a target's std; a pilot says it at the ready level; a print
    measured from several places, found on its layout, adds nothing."""
    doc = _fit_doc()
    base = judge(doc)
    one = {**doc, "print": {"source": "one place", "seen_rms_mm": 0.0, "limit_mm": 0.0,
                            "sigma_mm": 0.0, "n_places": 1}}
    v = judge(one)
    assert v.status == "check" and any("not measured" in r and "0.070 mm" in r
                                       for r in v.reasons), v.reasons
    assert v.target_std["print_mm"] == pytest.approx(0.07 / 2**0.5)
    assert v.expected_target_error_mm == pytest.approx(
        (base.expected_target_error_mm ** 2 + (R95_PER_RMS * 0.07) ** 2) ** 0.5)
    assert judge(one, stage="pilot").status == "ready"
    views = {**doc, "print": {"source": "views", "applied": False, "limit_mm": 0.0,
                              "n_places": 4}}
    assert judge(views).status == "ready"
    assert judge(views).expected_target_error_mm == base.expected_target_error_mm


def test_a_print_field_found_but_not_held_is_not_a_measured_print():
    """Issue 37: a layout found from several places (or a survey) whose field does not hold
    (it does not replicate, its solve stopped, the views leave it unresolved) measured
    nothing: "check", the size it found (or a printer's) in every target's std; one found
    on its layout (not significant) measured the print: nothing added."""
    doc = _fit_doc()
    base = judge(doc)
    held = judge({**doc, "print": {"source": "survey", "applied": False,
                                   "status": "not significant", "reason": "on its layout",
                                   "rms_mm": 0.01, "unresolved_mm": 0.01, "limit_mm": 0.0}})
    assert held.status == base.status
    assert held.expected_target_error_mm == pytest.approx(base.expected_target_error_mm)
    for status in ("not replicated", "failed", "not resolved"):
        v = judge({**doc, "print": {"source": "views", "applied": False, "status": status,
                                    "reason": "the halves disagree", "rms_mm": 0.2,
                                    "limit_mm": 0.0}})
        assert v.status == "check", (status, v.reasons)
        assert any("not measured" in r and status in r for r in v.reasons), v.reasons
        assert v.target_std["print_mm"] == pytest.approx(0.2 / 2**0.5)
def test_a_measured_print_that_leaves_its_mark_is_named_as_a_cause():
    """Issue 37: a print measured from several places whose layout, between the markers,
    the views cannot tell from the lens leaves about as much on every mark as the marks'
    own noise: the verdict names the print (and what would lower it), and the expected
    target error carries it; a print measured to a few micrometres adds no reason."""
    doc = _fit_doc()
    base = judge(doc)
    pr = {"source": "views", "applied": True, "rms_mm": 0.25, "field_rms_mm": 0.24,
          "n_places": 6, "unresolved_mm": 0.03, "interior_mm": 0.04, "limit_mm": 0.04}
    v = judge({**doc, "print": pr})
    assert v.status == "check"
    (named,) = [r for r in v.reasons if r.startswith("the print:")]
    assert "0.040 mm RMS on every mark" in named and "declare the camera's lens" in named
    assert v.expected_target_error_mm == pytest.approx(
        (base.expected_target_error_mm ** 2 + (R95_PER_RMS * 0.04) ** 2) ** 0.5)
    small = judge({**doc, "print": {**pr, "interior_mm": 0.004, "limit_mm": 0.004}})
    assert small.status == "ready" and not [r for r in small.reasons if "the print:" in r]
    # named but no check where the rest of a target's error is larger (a declared lens: the
    # print leaves 0.012 mm, 0.0085 per axis, beside the rest's 0.0105 mm per axis)
    rest = (base.target_std["total_mm"] ** 2 - base.target_std["print_mm"] ** 2) ** 0.5
    assert 0.012 / 2 ** 0.5 < rest
    part = judge({**doc, "print": {**pr, "limit_mm": 0.012}})
    assert part.status == "ready" and [r for r in part.reasons if r.startswith("the print:")]
