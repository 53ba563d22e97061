"""The sheet as printed (``vision-cal survey``): photos of the blank sheet measured
(:func:`vision_cal.measure.survey.run_survey`) into OUT/survey.json."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vision_cal.measure.survey import run_survey


@dataclass(frozen=True)
class SurveyRequest:
    """What ``vision-cal survey`` was asked (see its ``--help``)."""

    photos: str
    sheet: str                    # SHEET.json
    out: str
    quiet: bool = False


@dataclass(frozen=True)
class SurveyOutcome:
    """survey.json as written (a dict, docs/format.md) and its path."""

    survey: dict
    path: Path


def survey(req: SurveyRequest) -> SurveyOutcome:
    """Survey the sheet ``req.sheet`` from the photos in ``req.photos``."""
    doc = run_survey(req.photos, req.sheet, req.out)
    return SurveyOutcome(doc, Path(req.out) / "survey.json")
