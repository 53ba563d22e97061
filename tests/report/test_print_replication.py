"""The print's replication in words (issue 37): the console's summary and the report say
whether the layout as printed was applied, why not, and whether its halves agreed, from
calibration.json ``print`` alone."""

from vision_cal.report.html import _print_html
from vision_cal.report.summary import _print_replication_lines

REP = {"status": "disagree", "text": "two halves (camera places: 3 + 3 photos) disagree on "
       "the print: chi2/dof 4.80 over 148 corners (at most 2.00)"}


def test_a_print_not_applied_says_why_and_how_its_halves_compared():
    pr = {"source": "views", "applied": False, "status": "not replicated",
          "reason": "the print field (0.466 mm RMS) does not replicate: the halves differ",
          "n_places": 6, "rms_mm": 0.466, "unresolved_mm": 0.324, "replication": REP,
          "seen_rms_mm": 0.2, "limit_mm": 0.2, "sigma_mm": 0.14}
    lines = _print_replication_lines(pr)
    assert lines[0] == ("sheet as printed (views, 6 places): not applied (not replicated): "
                        "the print field (0.466 mm RMS) does not replicate: the halves differ")
    assert lines[1] == "  replication: " + REP["text"]
    html = _print_html(pr)
    assert "not applied (not replicated)" in html and "chi2/dof 4.80" in html
    assert "Every mark carries 0.200 mm" in html


def test_an_applied_print_shows_its_agreement_and_one_place_says_nothing_of_halves():
    agree = {"status": "agree", "text": "two halves agree on the print: chi2/dof 0.70"}
    pr = {"source": "views", "applied": True, "status": "applied", "n_places": 6,
          "rms_mm": 0.17, "replication": agree}
    assert _print_replication_lines(pr) == ["sheet as printed (views, 6 places): applied",
                                             "  replication: " + agree["text"]]
    assert "chi2/dof 0.70" in _print_html(pr)
    assert _print_replication_lines({"source": "one place", "limit_mm": 0.1}) == []


def test_a_print_on_its_layout_is_measured_not_refused():
    """``not significant``: the views measured the print and found it on its layout, so the
    calibration counts it measured (the loop's survey line says "used"): never "not
    applied", which read as the survey refused."""
    pr = {"source": "survey", "applied": False, "status": "not significant", "n_places": 6,
          "reason": "the print is 0.008 mm RMS off its layout: on its layout as far as they "
                    "can tell"}
    line = _print_replication_lines(pr)[0]
    assert line.startswith("sheet as printed (survey, 6 places): measured, no field to apply "
                           "(not significant): the print is 0.008 mm"), line
    assert "not applied" not in line
