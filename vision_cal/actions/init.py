"""The action of ``vision-cal init``: the ``images`` list of a session, found from the photos
(a planned session completed from them, :func:`complete_session`), for a user who wants to
check or edit the list."""

from __future__ import annotations

import copy
import json
import sys
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

from vision_cal.actions.console import warn

from vision_cal.dataset.io import atomic_write_json, distinct_outputs
from vision_cal.dataset.out_folder import replacing_files
from vision_cal.dataset.session import load_session
from vision_cal.errors import VisionCalError
from vision_cal.actions.measure_folder import measure_folder


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


def complete_session(photos_dir, plan_path, *, jobs: int | None = None, progress=None):
    """A planned session (one without ``images``, e.g. from ``vision-cal design``)
    completed from its photos: every photo measured against it, which marks each shows
    inferred (:mod:`vision_cal.identify.infer`); (session.json document with ``images``,
    the Measurement). Photos that are not usable (no sheet in them, repeated, unreadable)
    are left out of the list and reported."""
    photos_dir = Path(photos_dir)
    if not photos_dir.is_dir():
        raise VisionCalError("not a folder of photos", file=str(photos_dir))
    plan_path = Path(plan_path)
    if plan_path.is_dir():
        plan_path = plan_path / "session.json"
    planned = load_session(plan_path)
    if any(m.measured_mm is None for m in planned.marks) and planned.sheet is None:
        raise VisionCalError("missing required field (photos need the printed ArUco grid)",
                             file=str(plan_path), field="sheet")
    session = replace(planned, root=photos_dir, images=(), images_listed=False)
    with tempfile.TemporaryDirectory(prefix="vision-cal-init-") as tmp:
        try:
            meas = measure_folder(session, out_dir=tmp, jobs=jobs, progress=progress)
        except VisionCalError as e:
            if e.file != str(session.path):
                raise
            # session.path is PHOTOS/session.json, which init never reads nor writes: name
            # the photo folder (no photos) or the plan (anything else it lacks)
            if e.field == "images":
                raise VisionCalError(e.reason.replace("session.json has no images list and "
                                                      "the folder", "the folder"),
                                     file=str(photos_dir)) from e
            raise VisionCalError(e.reason, file=str(plan_path), field=e.field) from e
    doc = copy.deepcopy(planned.raw)
    doc["images"] = meas.session_images()
    return doc, meas
