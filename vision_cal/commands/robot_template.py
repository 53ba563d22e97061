"""``vision-cal robot-template``: a commented robot file to edit (or a simulated robot)."""

from __future__ import annotations

from vision_cal.commands import request

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
    # and the action pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    from vision_cal.actions.robot_template import RobotTemplateRequest, robot_template

    return robot_template(request(args, RobotTemplateRequest)).show(quiet=args.quiet)
