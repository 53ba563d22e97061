"""Measuring a dataset folder: every photo, every pen mark, in sheet millimetres.

Pipeline (``measure_folder``):

1. the photos, listed or found, each checked before anything is decoded
   (:mod:`vision_cal.measure.listing`);
2. per photo, in parallel and cached by content (:mod:`vision_cal.measure.detect`): decode,
   find the sheet's ArUco markers, an approximate homography, ink-dot candidates with small
   raw patches (``vision_cal.measure.dots``). A bad photo is *skipped* with a one-line
   reason; the batch goes on.
3. the lens: ``session.camera`` when declared; otherwise estimated jointly over the photos
   of each image size and kept only when held-out marker corners say it helps
   (``vision_cal.measure.mapping.estimate_lens``), reported as ``lens_distortion``; the
   sheet as printed (:mod:`vision_cal.measure.print_stage`); per photo the final mapping
   (lens + homography) and each dot's centre on the sheet with its covariance
   (:mod:`vision_cal.measure.finish`).
4. which dot is which mark (:mod:`vision_cal.identify.match`, with
   :mod:`vision_cal.identify.associate`) and the combined estimate of each mark, then the
   sheet's height (:mod:`vision_cal.identify.marks`, ``vision_cal.measure.height``).

Each stage is one function (:func:`measure_folder` lists them); what they return are the
types of :mod:`vision_cal.measure.types`, and ``OUT/measurement.json`` is written by
``Measurement.write``. Nothing is ever written into the input folder: results and the
cache go to ``out_dir``. It calls measure/ and identify/, so it lives above both.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.session import Session, load_session
from vision_cal.errors import VisionCalError
from vision_cal.identify.marks import mark_measurements, sheet_height_stage
from vision_cal.identify.match import associate_dots
from vision_cal.measure.asprinted import AsPrinted
from vision_cal.measure.cache import DetectionCache
from vision_cal.measure.detect import detect_all
from vision_cal.measure.finish import finish_all, lens_of_photos
from vision_cal.measure.listing import photos_to_measure
from vision_cal.measure.print_stage import as_printed_stage, print_stage
from vision_cal.measure.types import Measurement

log = logging.getLogger(__name__)


def _is_inside(a: Path, b: Path) -> bool:
    try:
        a.resolve().relative_to(b.resolve())
        return True
    except ValueError:
        return False


def measure_folder(session, *, out_dir, jobs: int | None = None, cache_dir=None,
                   progress=None, config: EstimatorConfig | None = None,
                   survey: AsPrinted | None = None) -> Measurement:
    """Measure every photo of a dataset folder and every pen mark on the sheet.

    ``session``: a :class:`Session` or a folder. ``out_dir``: where results go (never the
    input folder); the cache defaults to ``out_dir/.cache``. ``jobs``: worker processes
    (default ``os.cpu_count()``; 1 runs in this process). ``progress``: a tqdm bar on stderr.
    ``config``: the thresholds of every stage (default ``vision_cal.config.DEFAULT``).
    Without ``images`` in session.json every photo in the folder is measured and which
    marks each shows is inferred (:mod:`vision_cal.identify.infer`). ``survey``: the sheet
    as printed (``vision-cal survey``'s survey.json): the marks are measured against it.

    The stages, one function each: :func:`photos_to_measure` (listing and checks),
    :func:`detect_all` (stage 1, cached, parallel), :func:`lens_of_photos` (stage 2),
    :func:`finish_all` (mapping and dots per photo), :func:`associate_dots` (stage 3),
    :func:`mark_measurements`, :func:`sheet_height_stage` (stage 4); measurement.json is
    written last.
    """
    if not isinstance(session, Session):
        session = load_session(session)
    if session.sheet is None:
        raise VisionCalError("no sheet: photos cannot be measured", file=str(session.path),
                             field="sheet")
    root = Path(session.root)
    out_dir = Path(out_dir)
    if _is_inside(out_dir, root):
        raise VisionCalError("the output folder must not be inside the input folder "
                             "(photos are never written to)", file=str(out_dir))
    cache = DetectionCache(Path(cache_dir) if cache_dir else out_dir / ".cache")
    config = config or DEFAULT
    ac = config.association

    items, warnings, notes = photos_to_measure(session)
    warnings += detect_all(items, session, cache, jobs=jobs, progress=progress, config=config)
    dets = [ph.det for ph in items]
    cached = [ph.cached for ph in items]
    lens, lens_warnings = lens_of_photos(session, dets)
    warnings += lens_warnings
    as_printed, lens, dets, kept_declared = as_printed_stage(session, dets, lens, config,
                                                             survey=survey)
    images, finish_warnings = finish_all(session, dets, cached, lens, config,
                                         listed_marks=[ph.listed_marks for ph in items])
    warnings += finish_warnings
    print_summary = print_stage(session, images, as_printed, config, kept_declared)
    files = [ph.file for ph in items]
    dots = associate_dots(session, items, images, ac, config.dots.default_diameter_mm,
                          config.plan_match)
    warnings += dots.warnings
    marks = mark_measurements(dots, images, files, ac)
    heights, hmap, hnote = sheet_height_stage(session, images, marks, dots, lens, config)
    for r in images:
        if r.status != "ok":
            log.info("skipped %s: %s", r.file, r.reason)
    inferred = dots.inferred
    meas = Measurement(marks, images, lens, dots.unassigned(files), dict(dots.assoc.refused),
                       warnings, tuple(dots.image_marks),
                       None if inferred is None else inferred.mode,
                       () if inferred is None else (*notes, *inferred.warnings),
                       heights, hmap, hnote, str(root.resolve()), as_printed, print_summary)
    if print_summary is not None and np.isfinite(print_summary.get("sigma_mm", np.nan)):
        marks = {k: replace(m, cov_mm2=m.cov_mm2 + print_summary["sigma_mm"] ** 2 * np.eye(2))
                 for k, m in meas.marks.items()}
        meas = replace(meas, marks=marks)
    meas.write(out_dir / "measurement.json")
    return meas
