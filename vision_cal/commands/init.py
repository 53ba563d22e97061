"""``vision-cal init``: the ``images`` list of a session, found from the photos."""

from __future__ import annotations

from vision_cal.commands import JOBS, request

NAME = "init"
HELP = ("complete a planned session.json with the images list found from a folder of photos "
        "(which marks each photo shows), to check or edit it")
EXAMPLES = """\
examples:
  vision-cal init photos/ --plan plan/session.json -o dataset/session.json
  vision-cal init photos/ --plan plan/session.json > completed.json    (to stdout)

The photo folder is never written: copy the result next to the photos (or point its
images[].file at them) to make a dataset folder. Without an images list, `vision-cal DIR`
does the same inference itself.
"""


def add_arguments(p) -> None:
    p.add_argument("photos", metavar="PHOTOS", help="folder with the photographs")
    p.add_argument("--plan", required=True, metavar="SESSION.json",
                   help="the planned session (no images), e.g. from `vision-cal design`")
    p.add_argument("-o", "--out", default=None, metavar="OUT.json",
                   help="where to write the completed session.json (default: stdout)")
    p.add_argument("-j", "--jobs", type=JOBS, default=None,
                   help="parallel photo measurement (default: the number of cores)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.init import InitSessionRequest, init_session

    return init_session(request(args, InitSessionRequest)).show(quiet=args.quiet)
