"""The robot file to fill in (``vision-cal robot-template``): the template's text
(:mod:`vision_cal.templates`), written to a new file or returned for stdout."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vision_cal.dataset.io import atomic_write_text
from vision_cal.dataset.out_folder import replacing_files
from vision_cal.errors import VisionCalError
from vision_cal.templates import template_text


@dataclass(frozen=True)
class RobotTemplateRequest:
    """What ``vision-cal robot-template`` was asked (see its ``--help``)."""

    simulated: bool = False       # the simulated robot's file (with its `hidden` block)
    out: str | None = None        # None: the text goes to stdout
    quiet: bool = False


@dataclass(frozen=True)
class RobotTemplateOutcome:
    """The template's text and the file it was written to (None: not written, for stdout)."""

    text: str
    path: Path | None
    simulated: bool = False

    def show(self, quiet: bool = False) -> int:
        if self.path is None:   # the text itself is the output
            print(self.text, end="")
        elif not quiet:
            print(f"wrote {self.path}: edit the fields marked EDIT" if not self.simulated
                  else f"wrote {self.path}: the `hidden` block is what the simulated robot "
                       "hides")
        return 0


def robot_template(req: RobotTemplateRequest) -> RobotTemplateOutcome:
    """The template; written to ``req.out`` when given (never over an existing file)."""
    text = template_text("simulated" if req.simulated else "robot")
    if req.out is None:
        return RobotTemplateOutcome(text, None, req.simulated)
    out = Path(req.out)
    if out.is_dir():
        raise VisionCalError("is a folder, expected the robot file's name (e.g. "
                             f"{out / 'robot.yaml'})", file=str(out), field="--out")
    if out.exists():   # a robot file being filled in is never replaced
        raise VisionCalError("exists: not replaced (remove it or choose another name)",
                             file=str(out), field="--out")
    with replacing_files([("--out", out)], command="robot-template", quiet=req.quiet):
        atomic_write_text(out, text)
    return RobotTemplateOutcome(text, out, req.simulated)
