"""``vision-cal render``: make a synthetic dataset folder from a scene file."""

from __future__ import annotations

import argparse

from vision_cal.commands import JOBS, SEED, request

NAME = "render"
HELP = ("render a synthetic dataset (photos, session.json, truth.json) from a scene file "
        "(renders/README.md)")
EXAMPLES = """\
examples:
  vision-cal render renders/default.yaml --out /tmp/d
  vision-cal render renders/small.yaml --out /tmp/s --seed 3 --mode single
  vision-cal /tmp/d                       then calibrate the rendered folder
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="SCENE.yaml", help="scene file (see renders/README.md)")
    parser.add_argument("-o", "--out", metavar="DIR", required=True,
                        help="dataset folder to write (replaced if it holds a previous dataset)")
    parser.add_argument("--seed", type=SEED, metavar="N", default=None,
                        help="override the scene's seed")
    parser.add_argument("--mode", choices=("series", "single"), default=None,
                        help="override photos.mode: a photo after each mark, or one at the end")
    parser.add_argument("-j", "--jobs", type=JOBS, default=None, metavar="N",
                        help="processes that render photos (default: every core); the photos "
                             "are the same for any N")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.render import RenderRequest, render

    return render(request(args, RenderRequest)).show(quiet=args.quiet)
