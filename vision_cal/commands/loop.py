"""``vision-cal loop``: the closed loop on a synthetic scene, before and after."""

from __future__ import annotations

from vision_cal.commands import JOBS, request

NAME = "loop"
HELP = ("render a calibration session, calibrate it from the photos, plan targets with the "
        "nominal and calibrated models, draw them with the true robot, photograph and measure")
EXAMPLES = """\
examples:
  vision-cal loop renders/default.yaml --out out/demo        (what `make demo` runs)
  vision-cal loop renders/small.yaml --out /tmp/loop --jobs 2
"""


def add_arguments(p) -> None:
    p.add_argument("scene", metavar="SCENE.yaml", help="scene file (see renders/README.md)")
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="folder for the rendered sessions, the calibration, loop.json")
    p.add_argument("-j", "--jobs", type=JOBS, default=None,
                   help="processes that render and measure photos (default: every core)")
    p.add_argument("--elbow", type=int, choices=(1, -1), default=1,
                   help="elbow of the planned targets (+1: sin(q2 + z2) > 0; default 1)")
    p.add_argument("--no-report", dest="report", action="store_false",
                   help="skip DIR/calibration/report.html (written by default)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.loop import LoopRequest, loop

    return loop(request(args, LoopRequest)).show(quiet=args.quiet)
