"""The sheet as printed (``vision-cal survey``): photos of the blank sheet measured
(:func:`vision_cal.measure.survey.run_survey`) into OUT/survey.json."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from vision_cal.actions.console import say
from vision_cal.dataset.io import distinct_outputs
from vision_cal.dataset.out_folder import writing_into
from vision_cal.measure.survey import SURVEY_FILE, run_survey


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

    def lines(self) -> list[str]:
        """``vision-cal survey``: the verdict, the halves' agreement (issue 37) and what
        limits it (what would resolve it, when it claims no field)."""
        v = self.survey["verdict"]
        head = "limited by" if v["status"] in ("good", "limited") else "to resolve"
        return ([f"{self.path}: {v['status']}: {v['text']}"]
                + ([f"  replication: {v['replication']}"] if v.get("replication") else [])
                + [f"  {head}: {line}" for line in v["limits"]])

    def show(self, quiet: bool = False) -> int:
        """The lines; exit 1 when the survey failed (its solve stopped: no result), said on
        stderr even when quiet."""
        failed = self.survey["verdict"]["status"] == "failed"
        if not quiet:
            say(self.lines())
        elif failed:
            print(self.lines()[0], file=sys.stderr)
        return 1 if failed else 0


def survey(req: SurveyRequest) -> SurveyOutcome:
    """Survey the sheet ``req.sheet`` from the photos in ``req.photos`` into OUT, through
    the output folders' one owner: never the photos' folder; an earlier survey goes to
    OUT/previous/survey/ (OUT may hold the sheet itself, and other commands' files stay where
    they are; a plan's copy of a survey is refused, not replaced); locked while written."""
    out = Path(req.out)
    distinct_outputs([("--out", out / SURVEY_FILE)], [("--sheet", req.sheet)])
    with writing_into(req.out, command="survey", inputs=[("PHOTOS/", req.photos)],
                      reads=[req.sheet], displace=False, quiet=req.quiet) as out:
        doc = run_survey(req.photos, req.sheet, out)
    return SurveyOutcome(doc, Path(out) / SURVEY_FILE)
