"""Survey the sheet before the robot draws (``vision-cal survey``, issue 28).

Photos of the sheet taped in place, before any mark, from several places: the markers'
corners are found in each (stage 1, :mod:`vision_cal.measure.detect`), the lens is
estimated when none is declared (stage 2), and the sheet as printed is solved jointly with
the lens and every photo's pose (:mod:`vision_cal.measure.asprinted`). ``OUT/survey.json``
holds the as-printed layout, the lens, each photo's corner residual before and after, the
print's deviation and a verdict on the sheet; ``calibrate`` and ``design`` take it
(``--survey``, or a ``survey.json`` beside session.json / sheet.json) and the marks are
measured against it.

Issue 37: the survey checks itself by replication (:mod:`vision_cal.measure.replicate`:
two halves of the camera places, the same estimate on each, compared against what each
states) and claims a print field only when its solve converged, it is significant and its
halves agree (``print.claimed``); a solve that stopped on its evaluation limit is a failed
survey (``verdict.status: failed``, no layout written, exit 1). A survey read back
(:func:`load_survey`) is checked like any input: its sheet, its gauge (no shift, turn or
scale of the layout), its stds and deviations within what a printer and the prior allow;
:func:`applicable` says whether ``design`` and ``calibrate`` may apply it.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from vision_cal.config import DEFAULT, AsPrintedConfig, EstimatorConfig
from vision_cal.dataset import photos
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import atomic_write_bytes, atomic_write_json, read_json
from vision_cal.dataset.session import NominalRobot, Session, Sheet, load_sheet_file
from vision_cal.errors import CalibrationError, VisionCalError
from vision_cal.measure.asprinted import AsPrinted, layout_similarity
from vision_cal.measure.print_stage import as_printed_stage
from vision_cal.measure.detect import detect_image
from vision_cal.measure.finish import lens_of_photos
from vision_cal.measure.replicate import (FAILED, NOT_REPLICATED, NOT_RESOLVED,
                                          NOT_SIGNIFICANT, Claim, claim_of, replication_line,
                                          stated_scale)

FORMAT = "vision-cal/survey/1"
SURVEY_FILE = "survey.json"


def _session(root: Path, sheet: Sheet, camera=None) -> Session:
    """A session of the survey photos: the sheet, no robot, no marks."""
    return Session(root, sheet, NominalRobot(1.0, 1.0, (0.0, 0.0), (0.0, 0.0)), (), (),
                   camera, None, {}, images_listed=False)


def run_survey(photos_dir, sheet_json, out_dir, *, config: EstimatorConfig | None = None
               ) -> dict:
    """Survey: measure the photos in ``photos_dir`` of the sheet ``sheet_json``, write
    ``out_dir/survey.json`` (docs/format.md) and return it. ``out_dir`` is the output
    owner's (``actions/survey``: checked against the inputs, locked)."""
    config = config or DEFAULT
    ap, dets, warnings, sheet = survey_layout(photos_dir, sheet_json, config=config)
    doc = survey_document(sheet_json, sheet, dets, ap, claim_of(ap, config.as_printed),
                          warnings, config)
    atomic_write_json(Path(out_dir) / SURVEY_FILE, doc)
    return doc


def survey_layout(photos_dir, sheet_json, *, config: EstimatorConfig | None = None):
    """The sheet as printed from the photos in ``photos_dir`` (``source`` survey, with its
    significance and replication, applied or not: :func:`vision_cal.measure.replicate.claim_of`
    says which), every photo's detection, the warnings and the sheet; raises when fewer
    than ``config.as_printed.min_places`` places were photographed or the views do not fix
    the corners."""
    config = config or DEFAULT
    root = Path(photos_dir)
    if not root.is_dir():
        raise VisionCalError("not a folder of photos", file=str(root))
    sheet = load_sheet_file(sheet_json)
    session = _session(root, sheet)
    names = photos.list_photos(root)
    if not names:
        raise VisionCalError("no photos (JPEG or PNG) in the folder", file=str(root))
    dets = [detect_image(root / n, session, root=root, name=n, config=config, dots=False)
            for n in names]   # the blank sheet: no pen marks to look for
    lens, warnings = lens_of_photos(session, dets)
    ap, lens, _, not_applied = as_printed_stage(session, dets, lens, config,
                                                replicate_all=True)
    ap = ap or not_applied   # a survey reports the layout it found, applied or not
    ok = [d for d in dets if d.status == "ok"]
    if ap is None:
        raise VisionCalError(
            f"{len(ok)} usable photo(s) from fewer than {config.as_printed.min_places} camera "
            "places: a survey needs photos from several places (docs/sheet.md: 6-10 photos, "
            "the phone moved and tilted 10-30 deg each time)", file=str(root))
    if claim_of(ap, config.as_printed).status == NOT_RESOLVED:
        # the corners are held by the prior alone: the views do not fix the sheet
        raise CalibrationError(
            f"the views do not fix the sheet as printed: its corners are known only to "
            f"{ap.unresolved_mm:.3g} mm, more than the {config.as_printed.prior_mm:g} mm a "
            "printer can be off; check that --sheet describes the sheet in the photos (its "
            "markers' ids, size and places), then photograph it from further places, tilted "
            "more (docs/sheet.md)", file=str(sheet_json))
    return replace(ap, source="survey"), dets, warnings, sheet


def survey_document(sheet_json, sheet: Sheet, dets, ap: AsPrinted, claim: Claim,
                    warnings, config: EstimatorConfig) -> dict:
    """survey.json (docs/format.md) of the layout ``ap`` found from ``dets`` and its
    ``claim``: a failed solve writes no layout, no lens and no print figures."""
    failed = claim.status == FAILED
    before = dict(zip(ap.files, ap.rms_px_before))
    after = dict(zip(ap.files, ap.rms_px_after))
    now = before if not claim.applied else after   # against the layout the survey stands for
    return {
        "format": FORMAT,
        "sheet": {"file": str(Path(sheet_json).resolve()),
                  "sheet_id": (sheet.printed or {}).get("sheet_id"),
                  "n_markers": len(sheet.markers)},
        "photos": [{"file": d.file, "status": d.status, "reason": d.reason,
                    "n_markers": int(len(d.marker_ids)),
                    "corner_rms_px": None if failed else now.get(d.file),
                    "corner_rms_px_before": None if failed else before.get(d.file),
                    "corner_rms_px_after": None if failed else after.get(d.file)}
                   for d in dets],
        "lens": None if failed else {
            "K": np.asarray(ap.K).tolist(), "dist": np.asarray(ap.dist).tolist(),
            "size_px": list(ap.size_px), "estimated": bool(ap.lens_free)},
        "print": ({"claimed": False, **claim.to_json()} if failed else
                  {"claimed": claim.applied, **claim.to_json(),
                   "rms_mm": ap.rms_mm, "max_mm": ap.max_mm, "growth_mm": ap.growth_mm,
                   "field_rms_mm": ap.field_rms_mm, "unresolved_mm": ap.unresolved_mm,
                   "n_places": ap.n_places}),
        "solve": {"status": "stopped" if ap.stopped else "converged", "reason": ap.stopped},
        "replication": ap.replication,
        "paper_height": ({"measured": False,
                          "note": "the corners' heights were not released "
                                  "(config.as_printed.release_heights)"}
                         if ap.height_rms_mm is None or failed else
                         {"measured": True, "rms_mm": ap.height_rms_mm,
                          "unresolved_mm": ap.height_unresolved_mm,
                          "note": "each marker corner's height off the paper's best-fitting "
                                  "plane: as_printed.markers[].height_mm"}),
        "verdict": survey_verdict(ap, config, claim),
        "warnings": warnings,
        "as_printed": None if failed else ap.to_json(),
    }


def survey_verdict(ap: AsPrinted, config: EstimatorConfig | None = None,
                   claim: Claim | None = None) -> dict:
    """The survey's verdict: ``failed`` (its solve stopped on a limit: nothing claimed),
    ``no field`` (the field is not significant, or does not replicate: it moves no mark),
    else ``good`` when the corners are known to ``config.as_printed.survey_good_mm`` (2-D
    RMS of their std) and ``limited`` with what limits it. ``replication``: the halves'
    sentence (:func:`vision_cal.measure.replicate.replication_line`)."""
    cfg = (config or DEFAULT).as_printed
    claim = claim or claim_of(ap, cfg)
    good_to = ap.unresolved_mm * stated_scale(ap.replication)   # as the halves showed it
    rep = replication_line(ap.replication)
    if claim.status == FAILED:
        return {"status": "failed", "good_to_mm": None, "text": claim.reason,
                "limits": [_RESOLVE[FAILED]], "replication": rep}
    if not claim.applied:
        return {"status": "no field", "good_to_mm": good_to,
                "text": f"no print field claimed: {claim.reason}",
                "limits": [_RESOLVE[claim.status]], "replication": rep}
    limits = []
    if not math.isfinite(good_to) or good_to > cfg.survey_good_mm:
        limits.append(f"the views separate the print from the lens only to {good_to:.3f} mm: "
                      "add photos from further places, tilted more (docs/sheet.md)")
    n_rel = int(ap.released.sum())
    if n_rel < ap.released.size:
        limits.append(f"{ap.released.size - n_rel} marker corners were seen in fewer than "
                      "two photos and are taken as declared")
    k = stated_scale(ap.replication)
    text = (f"the sheet as printed is known to {good_to:.3f} mm (RMS"
            + (f"; its halves scatter {k:.2f} times what they state" if k > 1 else "")
            + f"); it deviates from its layout by {ap.rms_mm:.3f} mm RMS, "
            f"{ap.max_mm:.3f} mm at most")
    return {"status": "limited" if limits else "good", "good_to_mm": good_to,
            "text": text, "limits": limits, "replication": rep}


#: what resolves a survey that claims no field, by the claim's status
_RESOLVE = {
    FAILED: "photograph the sheet again from 6-10 places round it, tilted 10-30 deg, the "
            "whole sheet in every photo (docs/sheet.md); a solve that stops is no result",
    NOT_SIGNIFICANT: "nothing for the marks: they are measured against the declared layout "
                     "and the print's size is carried in their variance; photos from "
                     "further places, tilted more, would resolve a smaller print",
    NOT_REPLICATED: "photos from at least 6 camera places round the sheet, tilted 10-30 deg, "
                    "the paper taped flat, the focus fixed, so that each half of the places "
                    "fixes the print on its own (docs/sheet.md); declaring the lens "
                    "(session.json camera) spares the views from fixing it",
    NOT_RESOLVED: "photos from further places, tilted more (docs/sheet.md)",
}


def load_survey(path, sheet: Sheet | None, config: EstimatorConfig | None = None
                ) -> AsPrinted:
    """survey.json's as-printed layout, checked like any input (one-line errors naming the
    file and the field): against ``sheet`` (its ``sheet_id``; the same markers, declared
    where the survey's sheet declared them), and on its own: in its gauge
    (:func:`check_gauge`), its stds and deviations plausible (:func:`check_plausible`). A
    failed survey (no layout) is refused here: :func:`applicable` says so first."""
    cfg = (config or DEFAULT).as_printed
    path = Path(path)
    d = read_json(path, what="survey")
    r = FieldReader(str(path))
    if d.get("format") != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {d.get('format')!r}")
    if not isinstance(d.get("as_printed"), dict):
        why = ((d.get("verdict") or {}).get("text") if isinstance(d.get("verdict"), dict)
               else None)
        r.fail("as_printed", f"no layout: {why}" if why else
               "missing: write the file with vision-cal survey")
    try:
        ap = AsPrinted.from_json(d["as_printed"])
    except (KeyError, TypeError, ValueError) as e:
        r.fail("as_printed", f"unreadable: {e}")
    ap = replace(ap, source="survey")
    if sheet is not None:   # the sheet first: a survey of another sheet is that, not a bad file
        _check_sheet(r, d, ap, sheet)
    check_plausible(r, ap, cfg)
    check_gauge(r, ap, cfg)
    return ap


def _check_sheet(r: FieldReader, d: dict, ap: AsPrinted, sheet: Sheet) -> None:
    """The survey is of ``sheet``: its ``sheet_id`` when both have one, every marker it
    surveyed on the sheet and declared where the sheet declares it."""
    was = (d.get("sheet") or {}).get("sheet_id") if isinstance(d.get("sheet"), dict) else None
    now = (sheet.printed or {}).get("sheet_id")
    if was and now and was != now:
        r.fail("sheet.sheet_id", f"the survey is of sheet {was}, not {now}: survey this sheet "
                                 "(vision-cal survey)")
    declared = sheet.corners_by_id()
    for k, (i, c) in enumerate(zip(ap.ids, ap.declared_mm)):
        if int(i) not in declared:
            r.fail(f"as_printed.markers[{k}].id", f"marker {int(i)} is not on this sheet: "
                                                  "the survey is of another sheet")
        if np.abs(np.asarray(declared[int(i)]) - c).max() > 1e-3:
            r.fail(f"as_printed.markers[{k}].declared_mm",
                   f"marker {int(i)} was declared elsewhere when surveyed: the survey is "
                   "of another sheet (or the sheet was changed since)")


def check_gauge(r: FieldReader, ap: AsPrinted, cfg: AsPrintedConfig) -> None:
    """The layout in its gauge (:mod:`vision_cal.measure.asprinted`): the best-fitting
    similarity of the printed corners to the declared ones (each marker's growth aside) is
    the identity, within ``cfg.gauge_tolerance_mm`` anywhere over the released corners. A
    file whose corners were shifted, turned or scaled after it was written is not a survey
    of the print: the views cannot see a similarity, so a survey never holds one."""
    if not ap.released.any():
        return
    t, scale, turn, worst = layout_similarity(ap.declared_mm, ap.released, ap.deviation_mm)
    if worst > cfg.gauge_tolerance_mm:
        r.fail("as_printed.markers[].corners_mm",
               f"not in the survey's gauge: the printed corners are the declared ones "
               f"scaled {1 + scale:.5f}, turned {np.degrees(turn):.4f} deg and shifted "
               f"({t[0]:.4f}, {t[1]:.4f}) mm ({worst:.3f} mm at the furthest corner; a "
               "survey fixes its layout's best-fitting similarity to the declared layout): "
               "the file was changed after vision-cal survey wrote it; survey again")


def check_plausible(r: FieldReader, ap: AsPrinted, cfg: AsPrintedConfig) -> None:
    """Each released corner's std finite, above zero and within the prior
    (``cfg.prior_mm``, what holds a corner the views do not fix), each deviation within
    ``cfg.max_deviation_mm`` (no printer is further off), the corners not released exactly
    as declared, the lens finite, ``field.cov_mm2`` a covariance (symmetric, not
    negative); else the field is named."""
    for k, (i, dev, sd, rel) in enumerate(zip(ap.ids, ap.deviation_mm, ap.std_mm,
                                              ap.released)):
        where = f"as_printed.markers[{k}]"
        if not (np.all(np.isfinite(dev)) and np.all(np.isfinite(sd))):
            r.fail(where, f"marker {int(i)}: a corner or its std is not a number")
        if np.any(sd[rel] <= 0) or np.any(sd[rel] > cfg.prior_mm):
            r.fail(f"{where}.std_mm", f"marker {int(i)}: a released corner's std of "
                   f"{float(sd[rel].min()):.3g}..{float(sd[rel].max()):.3g} mm is outside "
                   f"(0, {cfg.prior_mm:g}] mm (the views leave some noise, the prior holds "
                   "the rest): not a survey's")
        far = float(np.linalg.norm(dev, axis=1).max())
        if far > cfg.max_deviation_mm:
            r.fail(f"{where}.corners_mm", f"marker {int(i)}: a corner {far:.2f} mm off its "
                   f"layout, more than the {cfg.max_deviation_mm:g} mm any printer is off")
        if np.any(np.abs(dev[~rel]) > 0) or np.any(sd[~rel] != 0):
            r.fail(f"{where}.corners_mm", f"marker {int(i)}: a corner not released (seen in "
                   "fewer than two photos) is not as declared, or has a std")
    K = np.asarray(ap.K, float)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        r.fail("as_printed.K", "not a camera matrix with a positive focal length")
    f = ap.field_read
    if f:
        C = np.asarray(f.get("cov_mm2"), float)
        if (C.shape != (8, 8) or not np.all(np.isfinite(C)) or not np.allclose(C, C.T)
                or np.linalg.eigvalsh(0.5 * (C + C.T)).min() < -1e-9 * max(np.abs(C).max(), 1e-30)):
            r.fail("as_printed.field.cov_mm2", "not an 8 x 8 covariance (symmetric, no "
                   "negative variance)")


def applicable(path, config: EstimatorConfig | None = None) -> Claim:
    """Whether ``design`` and ``calibrate`` may apply the survey at ``path``: its print field
    claimed by the rule of :func:`vision_cal.measure.replicate.claim_of` (a converged solve,
    significant, replicated), judged again on the file (a survey written before the rule,
    whose solve stopped or was never replicated, claims nothing). A failed survey (no
    layout) gives its own reason; a bad file raises as :func:`load_survey`."""
    d = read_json(path)
    if isinstance(d, dict) and d.get("as_printed") is None and isinstance(d.get("print"), dict):
        pr = d["print"]
        return Claim(str(pr.get("status") or FAILED), str(pr.get("reason") or "no layout"))
    ap = load_survey(path, None, config)
    if ap.stopped is None and any("stopped" in n for n in ap.notes):   # written before
        ap = replace(ap, stopped=next(n for n in ap.notes if "stopped" in n))
    return claim_of(ap, (config or DEFAULT).as_printed)


def find_survey(*candidates) -> Path | None:
    """The first survey that exists among those given: a survey file itself (a .json that
    is not sheet.json or session.json), else ``survey.json`` in the folder given or beside
    the file given."""
    for c in candidates:
        if c is None:
            continue
        p = Path(c)
        if p.is_file() and p.name not in ("sheet.json", "session.json"):
            return p
        p = (p if p.is_dir() else p.parent) / SURVEY_FILE
        if p.is_file():
            return p
    return None


def copy_survey(path, sheet: Sheet, out_dir) -> Path:
    """``design --survey``: checked against the designed sheet and copied into the design
    folder, where the calibration finds it beside session.json."""
    load_survey(path, sheet)
    dest = Path(out_dir) / SURVEY_FILE
    if Path(path).resolve() != dest.resolve():   # written as the design's own file
        atomic_write_bytes(dest, Path(path).read_bytes())
    return dest
