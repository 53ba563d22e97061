"""The calibration pipeline: load -> measure -> identify -> estimate -> write.

The front's one shared stage: ``calibrate`` (each folder, and each placement of
``--joint``), ``loop`` and ``verify`` call it. :func:`calibrate_dataset` is what
``vision-cal DIR --out OUT`` runs, one stage a function: the session loaded
(:func:`vision_cal.dataset.session.load_session`) -> :func:`measure_marks` (the photos
measured and each dot identified as a mark, :mod:`vision_cal.actions.measure_folder`; the
marks collected:
:func:`vision_cal.estimate.marks.collect_marks`) -> the estimator's fit
(:func:`vision_cal.estimate.fit.fit_marks`) -> the still cameras' poses
(:func:`vision_cal.camera.fixed.cameras_json`) -> the one calibration
(:func:`vision_cal.estimate.document.document`), written once. Summaries and reports are
rendered from the written files.
"""

from __future__ import annotations

import logging
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from vision_cal.camera.fixed import cameras_json
from vision_cal.config import DEFAULT, METHODS, EstimatorConfig
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.session import Session, load_session
from vision_cal.errors import CalibrationError, VisionCalError
from vision_cal.estimate.document import document
from vision_cal.estimate.fit import fit_marks
from vision_cal.estimate.marks import MarkData, collect_marks
from vision_cal.estimate.paper import PaperResult
from vision_cal.estimate.paper_scale import check_bars
from vision_cal.estimate.plausible import check_plausible
from vision_cal.estimate.select import Diagnosis
from vision_cal.measure.survey import load_survey
from vision_cal.measure.types import Measurement
from vision_cal.model.robot import RobotModel
from vision_cal.progress import bar
from vision_cal.actions.measure_folder import measure_folder

log = logging.getLogger(__name__)

#: marks from which the fit + diagnosis and the writing of calibration.json each print a
#: progress line when they start and end (a marks CSV of 2,000 marks takes seconds, of
#: 100,000 minutes: docs/format.md, "Marks from other instruments")
PROGRESS_MARKS = 2000


@dataclass(frozen=True)
class CalibrationRun:
    """One run in memory: the result as written (``result``; ``document`` its JSON), where,
    and what only the live run has (the selection's :class:`Diagnosis` for ``lsq``, the
    circle fits for ``paper``, the photos' measurement, the calibrated model)."""

    session: Session
    result: CalibrationResult
    out_path: Path
    model: RobotModel                 # the calibrated robot (what load_calibration reads back)
    diagnosis: Diagnosis | None = None
    paper: PaperResult | None = None
    measurement: Measurement | None = None

    @cached_property
    def document(self) -> dict:
        """calibration.json as written (``result.to_json()``)."""
        return self.result.to_json()


def photo_reasons(measurement, *, top: int = 3) -> str:
    """The most common reasons photos were skipped, counted, with one example each:
    ``"5 of 6 photos skipped: 4 wrong sheet (img_000.png: wrong sheet: ...), 1 blank image"``.
    Reasons are grouped by what comes before their first colon."""
    skipped = [im for im in measurement.images if im.status != "ok"]
    if not skipped:
        return ""
    groups: dict[str, list] = {}
    for im in skipped:
        groups.setdefault((im.reason or "no reason").split(":", 1)[0], []).append(im)
    ranked = sorted(groups.items(), key=lambda kv: -len(kv[1]))
    parts = [f"{len(ims)} {kind} ({ims[0].file}: {ims[0].reason})" if i == 0 else
             f"{len(ims)} {kind}" for i, (kind, ims) in enumerate(ranked[:top])]
    more = f", {len(ranked) - top} other reasons" if len(ranked) > top else ""
    return (f"{len(skipped)} of {len(measurement.images)} photos skipped: "
            + ", ".join(parts) + more)


def _why_unmeasured(measurement) -> str:
    """Why photos gave no marks (appended to the "too few marks" error), or ""."""
    if measurement is None:
        return ""
    why = photo_reasons(measurement)
    ok = [im for im in measurement.images if im.status == "ok"]
    if ok:
        dots = sum(im.n_dots for im in ok)
        rejected: dict[str, int] = {}
        for im in ok:
            for k, v in (im.rejected or {}).items():
                rejected[k] = rejected.get(k, 0) + v
        top = sorted(rejected.items(), key=lambda kv: -kv[1])[:3]
        seen = (f"{len(ok)} photo(s) measured found {dots} pen mark(s)"
                + (" and rejected " + ", ".join(f"{v} {k}" for k, v in top) if top else "")
                + (f", {len(measurement.unassigned)} not matched to any planned mark"
                   if measurement.unassigned else ""))
        why = f"{why}; {seen}" if why else seen
    return f"; {why}" if why else ""


def calibrate_dataset(folder, *, out_dir, method: str = "lsq", jobs: int | None = None,
                      progress: bool = False, truth: bool = False,
                      config: EstimatorConfig | None = None, survey=None,
                      bars_mm=None) -> CalibrationRun:
    """Measure (if needed), calibrate and diagnose a dataset folder; write calibration.json.

    The stages: :func:`measure_marks`, the estimator's fit
    (:func:`~vision_cal.estimate.fit.fit_marks`), the still cameras, the calibration
    (:func:`~vision_cal.estimate.document.document`). ``config``: the estimator's thresholds (:mod:`vision_cal.config`;
    default ``DEFAULT``), recorded in calibration.json's ``config``. ``survey``: the sheet
    as printed (survey.json's path, or None: a ``survey.json`` beside session.json's sheet
    is not looked for here; :func:`vision_cal.measure.survey.find_survey` does that).
    ``bars_mm``: the sheet's two printed 100 mm bars as measured (x, y), in place of
    ``sheet.printed.measured_bar_mm`` (``calibrate --bars-mm``; calibration.json
    ``printer_scale`` and ``paper_scale``)."""
    if method not in METHODS:
        raise VisionCalError(f"unknown method {method!r} (expected one of {', '.join(METHODS)})")
    config = config or DEFAULT
    if bars_mm is not None:
        bars_mm = check_bars(bars_mm)
    # a folder, or a session already read (a marks CSV: vision_cal.dataset.marks_csv)
    session = folder if isinstance(folder, Session) else load_session(folder)
    out_dir = Path(out_dir)
    measurement, data, missing = measure_marks(session, out_dir=out_dir, jobs=jobs,
                                               progress=progress, config=config,
                                               survey=None if survey is None
                                               else load_survey(survey, session.sheet))
    n_marks = sum(r in ("calibration", "validation") for r in data.roles)
    with _long_stage(progress, n_marks, "fit + diagnosis"):
        fitted = fit_marks(session, data, measurement, method=method, config=config)
    with _long_stage(progress, n_marks, "calibration.json"):
        cameras = cameras_json(session, measurement, fitted.model,
                               covariance=fitted.result.covariance, std=fitted.result.std)
        result = document(session, data, missing, measurement, fitted, method=method,
                          config=config, truth=truth, bars_mm=bars_mm, cameras=cameras)
        check_plausible(result, session)  # radians, metres: stop before any file
        out_path = result.write(out_dir / "calibration.json")
    log.info("wrote %s", out_path)
    return CalibrationRun(session, result, out_path, fitted.model, fitted.diagnosis,
                          fitted.paper, measurement)


@contextmanager
def _long_stage(progress: bool, n_marks: int, desc: str):
    """A progress line as the stage ``desc`` starts and ends, from ``PROGRESS_MARKS``
    marks (with ``progress``); a stage that fails ends its line at 0 marks."""
    line = bar(progress and n_marks >= PROGRESS_MARKS, total=n_marks, unit="mark", desc=desc)
    try:
        yield
        line.update(n_marks)
    finally:
        line.close()


def measure_marks(session: Session, *, out_dir: Path, jobs: int | None = None,
                  progress: bool = False, config: EstimatorConfig = DEFAULT, survey=None
                  ) -> tuple[Measurement | None, MarkData, list[str]]:
    """(measurement or None, MarkData, missing ids): the photos measured when a mark has
    no ``measured_mm``; fewer than 3 calibration marks is a :class:`CalibrationError` that
    names why photos gave none."""
    measurement = None
    if any(m.measured_mm is None for m in session.marks):
        measurement = measure_folder(session, out_dir=out_dir, jobs=jobs, progress=progress,
                                     config=config, survey=survey)
    data, missing = collect_marks(session, measurement)
    n_cal = len(data.select("calibration").ids)
    if n_cal < 3:
        raise CalibrationError(f"{n_cal} calibration marks were measured "
                               f"({len(missing)} missing): at least 3 are needed"
                               + _why_unmeasured(measurement), file=str(session.path))
    return measurement, data, missing
