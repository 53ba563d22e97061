"""``vision-cal robot-template``: a commented robot file to edit (or a simulated robot)."""

from __future__ import annotations

NAME = "robot-template"
HELP = ("write a commented robot file to edit (docs/robot-file.md), or with --simulated a "
        "simulated robot for `vision-cal simulate`")
EXAMPLES = """\
examples:
  vision-cal robot-template -o robot.yaml          then edit the fields marked EDIT
  vision-cal robot-template --simulated -o true_robot.yaml
  vision-cal robot-template                        print it
"""


def add_arguments(p) -> None:
    p.add_argument("--simulated", action="store_true",
                   help="a simulated robot (robot.yaml plus hidden offsets and effects) "
                        "for `vision-cal simulate`")
    p.add_argument("-o", "--out", metavar="FILE",
                   help="write it here (refuses to replace an existing file); default: print")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the library pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from pathlib import Path

    from vision_cal.dataset.io import atomic_write_text
    from vision_cal.errors import VisionCalError
    from vision_cal.templates import template_text

    text = template_text("simulated" if args.simulated else "robot")
    if args.out is None:
        print(text, end="")
        return 0
    out = Path(args.out)
    if out.exists():
        raise VisionCalError("exists: not replaced (remove it or choose another name)",
                             file=str(out), field="--out")
    atomic_write_text(out, text)
    if not args.quiet:
        print(f"wrote {out}: edit the fields marked EDIT" if not args.simulated
              else f"wrote {out}: the `hidden` block is what the simulated robot hides")
    return 0
