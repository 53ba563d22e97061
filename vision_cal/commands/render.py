"""``vision-cal render``: make a synthetic dataset folder from a scene file."""

from __future__ import annotations

import argparse

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
    parser.add_argument("--seed", type=int, metavar="N", default=None,
                        help="override the scene's seed")
    parser.add_argument("--mode", choices=("series", "single"), default=None,
                        help="override photos.mode: a photo after each mark, or one at the end")
    parser.add_argument("-j", "--jobs", type=int, default=None, metavar="N",
                        help="processes that render photos (default: every core); the photos "
                             "are the same for any N")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the library pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.errors import VisionCalError
    from vision_cal.render.dataset import render_dataset
    from vision_cal.render.scene import load_scene

    if args.seed is not None and args.seed < 0:
        raise VisionCalError(f"expected a non-negative integer, got {args.seed}", field="--seed")
    scene = load_scene(args.scene).with_overrides(seed=args.seed, mode=args.mode)
    progress = not getattr(args, "quiet", False)  # a bar on a terminal, else one line per stage
    if args.jobs is not None and args.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {args.jobs}", field="--jobs")
    import os

    from vision_cal.calibrate.paper import pilot_params

    out = render_dataset(scene, args.out, progress=progress, pilot=pilot_params,
                         jobs=args.jobs or os.cpu_count())
    print(out)
    return 0
