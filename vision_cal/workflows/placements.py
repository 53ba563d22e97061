"""``vision-cal calibrate A/ B/ C/ --joint``: one robot from several placements of the sheet,
the workflow: refuse a placement given twice, measure each folder, pose the placements to
the estimator (:func:`vision_cal.estimate.placements.calibrate_placed`: the fit, the
selection, the verdicts, the calibrations) and write every file together."""

from __future__ import annotations

import hashlib
from pathlib import Path

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.io import written_together
from vision_cal.dataset.out_folder import output_names
from vision_cal.dataset.photos import list_photos
from vision_cal.dataset.session import load_session
from vision_cal.errors import CalibrationError
from vision_cal.estimate.placements import calibrate_placed
from vision_cal.workflows.pipeline import measure_marks


def refuse_same_evidence(sessions) -> None:
    """Refuse placements that share a photo (the same content, whatever its name) or whose
    marks are the same measurements: one placement counted twice shrinks every std by
    sqrt 2 and tests nothing (the same photos under two names took L1's std from 0.0043 to
    0.0030 mm)."""
    seen: dict[str, tuple[Path, Path]] = {}     # content hash -> (folder, photo)
    marks_seen: dict[str, Path] = {}
    for s in sessions:
        root = Path(s.root)
        files = ([im.file for im in s.images] if s.images_listed and s.images
                 else list_photos(root) if root.is_dir() else [])
        for f in files:
            p = root / f
            try:
                h = hashlib.sha256(p.read_bytes()).hexdigest()
            except OSError:
                continue        # the measurement says why it cannot read it
            if h in seen and seen[h][0].resolve() != root.resolve():
                raise CalibrationError(f"{p} and {seen[h][1]} are the same photo (same "
                                       "content): each placement is a sheet placed and "
                                       "photographed on its own; give each folder once")
            seen.setdefault(h, (root, p))
        given = [(m.joints_deg, m.measured_mm) for m in s.marks if m.measured_mm is not None]
        if given:
            h = hashlib.sha256(repr(sorted(given)).encode()).hexdigest()
            if h in marks_seen:
                raise CalibrationError(f"{s.path} and {marks_seen[h]} give the same marks "
                                       "(same commands, same measured_mm): one placement "
                                       "given twice; give each folder once")
            marks_seen[h] = s.path


def calibrate_placements(folders, *, out_dir, jobs: int | None = None,
                         progress: bool = False,
                         config: EstimatorConfig | None = None, names=None) -> dict:
    """``vision-cal calibrate A/ B/ C/ --joint --out X``: measure each folder, fit one robot
    and one sheet pose per placement, write ``X/calibration.json`` (robot frame R) and
    ``X/<folder>/calibration.json`` (each placement's sheet frame, for ``plan``).
    Returns the robot-frame document. ``config``: the thresholds (default ``DEFAULT``),
    recorded as its ``config``. ``names``: each placement's sub-folder (default
    :func:`~vision_cal.dataset.out_folder.output_names`: ``d1-plan`` and ``d2-plan`` for two
    folders named ``plan``)."""
    config = config or DEFAULT
    out_dir = Path(out_dir)
    names = list(names) if names is not None else output_names(folders)
    loaded = [load_session(folder) for folder in folders]
    refuse_same_evidence(loaded)
    cals = []
    for session, name in zip(loaded, names):
        _, data, _ = measure_marks(session, out_dir=out_dir / name, jobs=jobs, progress=progress,
                                   config=config)
        cals.append(data.select("calibration"))
    joint, subs = calibrate_placed(names, loaded, cals, config)
    with written_together():   # every placement's file and the top one, or none
        for name, sub in zip(names, subs):
            sub.write(out_dir / name / "calibration.json")
        joint.write(out_dir / "calibration.json")
    return joint.to_json()
