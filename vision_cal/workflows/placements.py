"""``vision-cal calibrate A/ B/ C/ --joint``: one robot from several placements of the sheet,
the workflow (measure each folder, fit them together with
:func:`vision_cal.estimate.placements.fit_placements`, judge, write every file together).
The fit itself lives in estimate/; this module orchestrates and writes."""

from __future__ import annotations

import hashlib
from dataclasses import replace
from pathlib import Path

import numpy as np

from vision_cal.estimate.placements import (Placement, PlacementsFit, cv_residuals,
                                             fit_placements, placement_cov,
                                             robot_frame_json, unexplained_seen)
from vision_cal.model.tool_fit import joint4_values
from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.covariance import covariance_json
from vision_cal.dataset.io import written_together
from vision_cal.dataset.nominal import nominal_blocks
from vision_cal.dataset.out_folder import output_names
from vision_cal.dataset.photos import list_photos
from vision_cal.dataset.session import load_session
from vision_cal.dataset.valid_for import build as valid_for_block
from vision_cal.estimate.verdict import judge_placements
from vision_cal.errors import CalibrationError
from vision_cal.model.robot import Tool
from vision_cal.workflows.pipeline import measure_marks


def _mark_json(place: Placement, j: int, xy, r) -> dict:
    """A placement calibration's ``marks`` entry: where it was measured, its residual under
    the shared robot, its command and approach, its noise when measured by camera."""
    d = {"measured_mm": xy.tolist(), "residual_mm": r.tolist(), "role": "calibration",
         "joints_deg": [float(v) for v in place.q_deg[j, :2]],
         "approach": [int(v) for v in place.approach[j, :2]]}
    if place.q_deg.shape[1] == 3:
        d["j4_deg"] = float(place.q_deg[j, 2])
    if place.sigma_mm is not None:
        d["sigma_mm"] = float(place.sigma_mm[j])
    return d


def _verdicts(places: list[Placement], sessions, fit: PlacementsFit, log,
              config: EstimatorConfig):
    """The contract's verdict of the joint fit and of each placement, and each placement's
    agreement with the others (:func:`vision_cal.estimate.verdict.judge_placements`): the
    residuals under the shared robot, the k-fold held-out ones, the robot block's
    repeatability (the first session that gives one)."""
    held = cv_residuals(places, fit, fit.effects, config.selection.k_folds,
                         config.fit.condition_number_limit)
    if held is None:
        held = [np.full((len(p.xy_mm), 2), np.nan) for p in places]
    rep = next((s.robot.repeatability_mm for s, _ in sessions
                if s.robot.repeatability_mm is not None), None)
    seen = unexplained_seen(log)
    reasons = [("check", "structure no candidate explains is left in the residual ("
                + "; ".join(seen) + ")")] if seen else []
    return judge_placements([p.name for p in places], list(fit.residuals_mm),
                            [p.sigma_mm for p in places], held, n_params=len(fit.cov),
                            repeatability_mm=rep, reasons=reasons, config=config.verdict)


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
    places, sessions = [], []
    names = list(names) if names is not None else output_names(folders)
    loaded = [load_session(folder) for folder in folders]
    refuse_same_evidence(loaded)
    for session, name in zip(loaded, names):
        _, data, _ = measure_marks(session, out_dir=out_dir / name, jobs=jobs, progress=progress,
                                   config=config)
        cal = data.select("calibration")
        q, a = cal.q_deg, cal.approach
        if cal.joint4 is not None:
            q = np.column_stack([q, cal.joint4[:, 0]])
            a = np.column_stack([a, cal.joint4[:, 1]])
        places.append(Placement(name, q, cal.xy_mm, a, cal.sigma_mm))
        sessions.append((session, cal))
    with_j4 = [p for p in places if p.q_deg.shape[1] == 3]
    if with_j4 and len(with_j4) != len(places):
        raise CalibrationError("some placements give j4_deg and others do not: give it in "
                               "every session.json or in none")
    tool = None
    if with_j4 and len(joint4_values(np.concatenate([p.q_deg[:, 2] for p in places]))) > 1:
        tool = Tool()
    fit, log = fit_placements(places, tool=tool, config=config)
    joint_v, place_v, agree = _verdicts(places, sessions, fit, log, config)
    rf = robot_frame_json(fit, names)
    effects = list(rf["effects"])
    seen = unexplained_seen(log)
    if seen:   # significant structure that a library effect would only stand in for
        effects.append({"name": "unexplained", "seen": seen})
    for pl, v, a in zip(rf["placements"], place_v, agree):
        pl["verdict"] = v.to_json()
        if a is not None:
            pl["agreement"] = a.to_json()
    joint = CalibrationResult(
        method="lsq-placements", params=rf["params"], std=rf["std"], effects=tuple(effects),
        residual_rms_mm=rf["residual_rms_mm"],
        diagnosis={"selection": log, "alpha": config.selection.alpha},
        config=config.to_json(),
        covariance=covariance_json(list(fit.labels), fit.cov),
        notes=("one robot from several placements: params in the robot frame R "
               "(docs/format.md); each placement's sheet-frame calibration in its "
               "sub-folder",),
        verdict=joint_v.to_json(),
        extra={"frame": rf["frame"], "placements": rf["placements"]})
    subs = []
    for k, ((session, cal), name) in enumerate(zip(sessions, names)):
        m = fit.model_on(k)
        params = m.params.to_json()
        if m.tool is not None:
            params["tool_mm"] = list(m.tool.tool_mm)
        placement = rf["placements"][k]
        sub = CalibrationResult(
            method="lsq-placements", params=params,
            effects=tuple(e.to_json(fit.effect_std(i)) for i, e in enumerate(fit.effects)
                          if not isinstance(e, Tool)),
            covariance=covariance_json(m.param_labels(), placement_cov(fit, k)),
            # the robot file the controller runs (dataset/nominal), not the pilot's model
            **nominal_blocks(session.raw, session.robot.params.to_json()),
            home_deg=tuple(float(v) for v in session.robot.home_deg),
            residual_rms_mm={"final_model": placement["residual_rms_mm"]},
            verdict=place_v[k].to_json(),
            marks={i: _mark_json(places[k], j, xy, r)
                   for j, (i, xy, r) in enumerate(zip(cal.ids, cal.xy_mm,
                                                      fit.residuals_mm[k]))},
            extra={"placement": placement})
        # what plan checks its targets against
        sub = replace(sub, valid_for=valid_for_block(sub.to_json()))
        subs.append((out_dir / name / "calibration.json", sub))
    with written_together():   # every placement's file and the top one, or none
        for path, sub in subs:
            sub.write(path)
        joint.write(out_dir / "calibration.json")
    return joint.to_json()
