"""``vision-cal survey``: the sheet as printed, from photos taken before the robot draws."""

from __future__ import annotations

NAME = "survey"
HELP = ("measure the printed sheet as it really is (markers' corners, lens) from photos "
        "taken from several places before any mark; writes OUT/survey.json")
EXAMPLES = """\
examples:
  vision-cal survey survey-photos/ --sheet sheet/sheet.json --out sheet/
      5-10 photos of the sheet taped in place, from several places (docs/sheet.md);
      sheet/survey.json is then found beside sheet.json by design and calibrate
"""


def add_arguments(p) -> None:
    p.add_argument("photos", metavar="PHOTOS", help="folder of photos of the blank sheet")
    p.add_argument("--sheet", required=True, metavar="SHEET.json",
                   help="the sheet's description (vision-cal sheet's sheet.json)")
    p.add_argument("-o", "--out", required=True, metavar="OUT",
                   help="output folder (OUT/survey.json)")


def run(args) -> int:
    # imported here: every command module is imported to build the parser
    from pathlib import Path

    from vision_cal.measure.survey import run_survey

    doc = run_survey(args.photos, args.sheet, args.out)
    if not args.quiet:
        v = doc["verdict"]
        print(f"{Path(args.out) / 'survey.json'}: {v['status']}: {v['text']}")
        for line in v["limits"]:
            print(f"  limited by: {line}")
    return 0
