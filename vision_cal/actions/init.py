"""The action of ``vision-cal init``: the ``images`` list of a session, found from the photos."""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

from vision_cal.actions.console import warn

from vision_cal.dataset.io import atomic_write_json, distinct_outputs
from vision_cal.dataset.out_folder import replacing_files
from vision_cal.errors import VisionCalError
from vision_cal.workflows.complete import complete_session


@dataclass(frozen=True)
class InitSessionRequest:
    """What ``vision-cal init`` was asked (its arguments; see ``vision-cal init --help``)."""

    photos: str
    plan: str
    quiet: bool = False
    out: str | None = None
    jobs: int | None = None


@dataclass(frozen=True)
class InitOutcome:
    """The session completed (a dict; written to ``out``, or None: for stdout), the warnings
    (photos not used, marks refused) and the summary line (photos, marks found)."""

    session: dict
    out: str | None
    warnings: tuple[str, ...]
    summary: str

    def show(self, quiet: bool = False) -> int:
        for w in self.warnings:
            warn(w)
        if self.out is None:   # the session itself is the output
            sys.stdout.write(json.dumps(self.session, indent=2) + "\n")
        if not quiet:
            print(self.summary, file=sys.stderr)
        return 0


def init_session(req: InitSessionRequest) -> InitOutcome:
    """A session.json completed from photos and a plan: which photo shows which marks,
    written to OUT or returned for the console."""
    if req.jobs is not None and req.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {req.jobs}", field="--jobs")
    if req.out:
        out = Path(req.out)
        try:
            inside = out.resolve().is_relative_to(Path(req.photos).resolve())
        except (OSError, ValueError) as e:
            raise VisionCalError(f"not a usable path: {e}", file=str(req.out)) from e
        if inside:
            raise VisionCalError("init never writes into the photo folder: write the "
                                 "session elsewhere", file=str(req.out))
        if out.is_dir():
            raise VisionCalError("is a folder, expected a .json file to write",
                                 file=str(req.out))
        distinct_outputs([("-o", out)], [("--plan", _plan_file(req.plan))])
    progress = (not req.quiet) and sys.stderr.isatty()
    doc, meas = complete_session(req.photos, req.plan, jobs=req.jobs, progress=progress)
    if not doc["images"]:
        raise VisionCalError(f"no usable photo of the sheet among {len(meas.images)} image "
                             "file(s)" + (f" (first: {meas.images[0].file}: "
                                          f"{meas.images[0].reason})" if meas.images else ""),
                             file=str(req.photos))
    warnings = tuple(f"{req.photos}/{im.file}: not used: {im.reason}"
                     for im in meas.images if im.status != "ok") + tuple(meas.warnings)
    if req.out:   # the output set's one owner: an earlier session.json to previous/
        with replacing_files([("-o", req.out)], command="init", quiet=req.quiet,
                             inputs=[("--plan", _plan_file(req.plan))]):
            atomic_write_json(req.out, doc)
    summary = (f"{len(doc['images'])} photo(s) of the sheet ({meas.inferred or 'none'}), "
               f"{len(meas.marks)} of {len(meas.marks) + len(meas.refused)} marks found"
               + (f" -> {req.out}" if req.out else ""))
    return InitOutcome(doc, req.out, warnings, summary)


def _plan_file(plan) -> Path:
    """The plan's session.json (``--plan`` a folder or the file)."""
    plan = Path(plan)
    return plan / "session.json" if plan.is_dir() else plan
