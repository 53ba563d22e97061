"""Survey the sheet before the robot draws (``vision-cal survey``, issue 28).

Photos of the sheet taped in place, before any mark, from several places: the markers'
corners are found in each (stage 1, :mod:`vision_cal.measure.detect`), the lens is
estimated when none is declared (stage 2), and the sheet as printed is solved jointly with
the lens and every photo's pose (:mod:`vision_cal.measure.asprinted`). ``OUT/survey.json``
holds the as-printed layout, the lens, each photo's corner residual before and after, the
print's deviation and a verdict on the sheet; ``calibrate`` and ``design`` take it
(``--survey``, or a ``survey.json`` beside session.json / sheet.json) and the marks are
measured against it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset import photos
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import atomic_write_bytes, atomic_write_json, read_json
from vision_cal.dataset.session import NominalRobot, Session, Sheet, load_sheet_file
from vision_cal.errors import CalibrationError, VisionCalError
from vision_cal.measure.asprinted import AsPrinted
from vision_cal.measure.print_stage import as_printed_stage
from vision_cal.measure.detect import detect_image
from vision_cal.measure.finish import lens_of_photos

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
    root, out_dir = Path(photos_dir), Path(out_dir)
    if not root.is_dir():
        raise VisionCalError("not a folder of photos", file=str(root))
    sheet = load_sheet_file(sheet_json)
    session = _session(root, sheet)
    names = photos.list_photos(root)
    if not names:
        raise VisionCalError("no photos (JPEG or PNG) in the folder", file=str(root))
    dets = [detect_image(root / n, session, root=root, name=n, config=config) for n in names]
    lens, warnings = lens_of_photos(session, dets)
    ap, lens, _, on_layout = as_printed_stage(session, dets, lens, config)
    ap = ap or on_layout   # a survey reports the layout it found, on the declared one or not
    ok = [d for d in dets if d.status == "ok"]
    if ap is None:
        raise VisionCalError(
            f"{len(ok)} usable photo(s) from fewer than {config.as_printed.min_places} camera "
            "places: a survey needs photos from several places (docs/sheet.md: 5-10 photos, "
            "the phone moved and tilted 10-30 deg each time)", file=str(root))
    if not math.isfinite(ap.unresolved_mm) or ap.unresolved_mm > config.as_printed.prior_mm:
        # the corners are held by the prior alone: the views do not fix the sheet
        raise CalibrationError(
            f"the views do not fix the sheet as printed: its corners are known only to "
            f"{ap.unresolved_mm:.3g} mm, more than the {config.as_printed.prior_mm:g} mm a "
            "printer can be off; check that --sheet describes the sheet in the photos (its "
            "markers' ids, size and places), then photograph it from further places, tilted "
            "more (docs/sheet.md)", file=str(sheet_json))
    ap = AsPrinted(**{**ap.__dict__, "source": "survey"})
    before = dict(zip(ap.files, ap.rms_px_before))
    after = dict(zip(ap.files, ap.rms_px_after))
    doc = {
        "format": FORMAT,
        "sheet": {"file": str(Path(sheet_json).resolve()),
                  "sheet_id": (sheet.printed or {}).get("sheet_id"),
                  "n_markers": len(sheet.markers)},
        "photos": [{"file": d.file, "status": d.status, "reason": d.reason,
                    "n_markers": int(len(d.marker_ids)),
                    "corner_rms_px_before": before.get(d.file),
                    "corner_rms_px_after": after.get(d.file)} for d in dets],
        "lens": {"K": np.asarray(ap.K).tolist(), "dist": np.asarray(ap.dist).tolist(),
                 "size_px": list(ap.size_px), "estimated": bool(ap.lens_free)},
        "print": {"rms_mm": ap.rms_mm, "max_mm": ap.max_mm, "growth_mm": ap.growth_mm,
                  "field_rms_mm": ap.field_rms_mm, "unresolved_mm": ap.unresolved_mm,
                  "n_places": ap.n_places},
        "paper_height": ({"measured": False,
                          "note": "the corners' heights were not released "
                                  "(config.as_printed.release_heights)"}
                         if ap.height_rms_mm is None else
                         {"measured": True, "rms_mm": ap.height_rms_mm,
                          "unresolved_mm": ap.height_unresolved_mm,
                          "note": "each marker corner's height off the paper's best-fitting "
                                  "plane: as_printed.markers[].height_mm"}),
        "verdict": survey_verdict(ap, config),
        "warnings": warnings,
        "as_printed": ap.to_json(),
    }
    atomic_write_json(out_dir / SURVEY_FILE, doc)
    return doc


def survey_verdict(ap: AsPrinted, config: EstimatorConfig | None = None) -> dict:
    """``good`` when the corners are known to ``config.as_printed.survey_good_mm`` (2-D RMS
    of their std), else ``limited`` with what limits it."""
    good_to = ap.unresolved_mm
    limits = []
    if not math.isfinite(good_to) or good_to > (config or DEFAULT).as_printed.survey_good_mm:
        limits.append(f"the views separate the print from the lens only to {good_to:.3f} mm: "
                      "add photos from further places, tilted more (docs/sheet.md)")
    n_rel = int(ap.released.sum())
    if n_rel < ap.released.size:
        limits.append(f"{ap.released.size - n_rel} marker corners were seen in fewer than "
                      "two photos and are taken as declared")
    text = (f"the sheet as printed is known to {good_to:.3f} mm (RMS); it deviates from its "
            f"layout by {ap.rms_mm:.3f} mm RMS, {ap.max_mm:.3f} mm at most")
    return {"status": "limited" if limits else "good", "good_to_mm": good_to,
            "text": text, "limits": limits}


def load_survey(path, sheet: Sheet | None) -> AsPrinted:
    """survey.json's as-printed layout, checked against ``sheet`` (the same markers,
    declared where the survey's sheet declared them); one-line errors naming the field."""
    path = Path(path)
    d = read_json(path, what="survey")
    r = FieldReader(str(path))
    if d.get("format") != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {d.get('format')!r}")
    if not isinstance(d.get("as_printed"), dict):
        r.fail("as_printed", "missing: write the file with vision-cal survey")
    try:
        ap = AsPrinted.from_json(d["as_printed"])
    except (KeyError, TypeError, ValueError) as e:
        r.fail("as_printed", f"unreadable: {e}")
    ap = AsPrinted(**{**ap.__dict__, "source": "survey"})
    if sheet is not None:
        declared = sheet.corners_by_id()
        for k, (i, c) in enumerate(zip(ap.ids, ap.declared_mm)):
            if int(i) not in declared:
                r.fail(f"as_printed.markers[{k}].id", f"marker {int(i)} is not on this sheet: "
                                                      "the survey is of another sheet")
            if np.abs(np.asarray(declared[int(i)]) - c).max() > 1e-3:
                r.fail(f"as_printed.markers[{k}].declared_mm",
                       f"marker {int(i)} was declared elsewhere when surveyed: the survey is "
                       "of another sheet (or the sheet was changed since)")
    return ap


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
