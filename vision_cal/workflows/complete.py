"""A planned session completed from its photos: the ``images`` list that ``init`` writes.

:func:`complete_session` measures every photo of a folder against a planned session (one
without ``images``, e.g. from ``vision-cal design``), infers which marks each photo shows
(:mod:`vision_cal.identify.infer`) and returns the session.json document with ``images``
filled in, for a user who wants to check or edit the list. Photos that are not usable (no
sheet in them, repeated, unreadable) are left out of the list and reported.
"""

from __future__ import annotations

import copy
import tempfile
from dataclasses import replace
from pathlib import Path

from vision_cal.dataset.session import load_session
from vision_cal.errors import VisionCalError
from vision_cal.workflows.measure_folder import measure_folder


def complete_session(photos_dir, plan_path, *, jobs: int | None = None, progress=None):
    """(session.json document with ``images``, the Measurement)."""
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
