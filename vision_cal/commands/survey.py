"""``vision-cal survey``: the sheet as printed, from photos taken before the robot draws."""

from __future__ import annotations

from vision_cal.commands import request

NAME = "survey"
HELP = ("measure the printed sheet as it really is (markers' corners, lens) from photos "
        "taken from several places before any mark; writes OUT/survey.json")
EXAMPLES = """\
examples:
  vision-cal survey survey-photos/ --sheet sheet/sheet.json --out sheet/
      6-10 photos of the sheet taped in place, each from another place (docs/sheet.md);
      sheet/survey.json is then found beside sheet.json by design and calibrate, which
      apply it only when it claims its print field: the solve converged, the print is
      significant and the two halves of the places agree (exit 1: the solve stopped)
"""


def add_arguments(p) -> None:
    p.add_argument("photos", metavar="PHOTOS", help="folder of photos of the blank sheet")
    p.add_argument("--sheet", required=True, metavar="SHEET.json",
                   help="the sheet's description: vision-cal sheet's sheet.json, or a "
                        "session.json designed on it (which carries it)")
    p.add_argument("-o", "--out", required=True, metavar="OUT",
                   help="output folder (OUT/survey.json)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.survey import SurveyRequest, survey

    return survey(request(args, SurveyRequest)).show(quiet=args.quiet)
