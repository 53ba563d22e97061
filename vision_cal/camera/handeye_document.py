"""calibration.json of a hand-eye from photos and the robot's poses (docs/format.md,
"Photos and the robot's poses"): ``cameras[0]`` as for every camera (``K``, ``dist``,
``T_robot_camera`` or ``T_flange_camera`` with its std and covariance), the board's place
(``T_flange_board`` or ``T_robot_board``) at the top level, each photo's residual and
prediction from the others in ``images``, and the fit's own figures in ``handeye``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vision_cal.camera import handeye_valid
from vision_cal.camera.handeye import HandeyeFit
from vision_cal.camera.handeye_lsq import LENS_NAMES, lens_K
from vision_cal.config import DEFAULT
from vision_cal.dataset.calibration_result import CalibrationResult

METHOD = "handeye_photos"


def _pose_std(std: dict, prefix: str) -> dict:
    return {"rotation_deg": [float(std[f"{prefix}.rot_{a}_deg"]) for a in "xyz"],
            "translation_mm": [float(std[f"{prefix}.{a}_mm"]) for a in "xyz"]}


def camera_covariance(fit: HandeyeFit) -> np.ndarray:
    """(7, 7) of the camera's pose (rotation deg about the parent frame's axes, translation
    mm) and its focal length (the mean of fx and fy, px; 0 when declared): the still
    camera's covariance ``vision-cal locate`` propagates."""
    idx = {n: i for i, n in enumerate(fit.labels)}
    A = np.zeros((7, len(fit.labels)))
    for k in range(6):
        A[k, k] = 1.0
    for name in ("lens.fx", "lens.fy"):
        if name in idx:
            A[6, idx[name]] = 0.5
    return A @ fit.cov @ A.T


def _images(fit: HandeyeFit, skipped) -> list[dict]:
    held = {h.name: h for h in fit.heldout}
    rows = []
    for v in fit.views:
        h = held[v.name]
        rows.append({"file": v.name, "status": "ok", "n_points": int(len(v.px)),
                     "T_robot_flange": np.asarray(v.T_robot_flange, float).tolist(),
                     "joints_deg": (None if v.joints_deg is None
                                    else [float(q) for q in v.joints_deg]),
                     "residual_px": fit.residual_px[v.name],
                     "own_pose_residual_px": fit.pnp_px.get(v.name),
                     "heldout_px": h.rms_px, "heldout_mm": h.rms_mm,
                     "stated_px": h.stated_px * fit.inflation,
                     "stated_mm": h.stated_mm * fit.inflation, "p_value": h.p_value})
    for name, why in fit.left_out.items():
        rows.append({"file": name, "status": "left out", "reason": why,
                     "own_pose_residual_px": fit.pnp_px.get(name)})
    for name, why in skipped:
        rows.append({"file": name, "status": "skipped", "reason": why})
    return rows


def _lever(fit: HandeyeFit) -> float:
    return float(np.median(np.linalg.norm(
        np.array([v.T_robot_flange[:3, 3] for v in fit.views]), axis=1)))


def _kinematic(fit: HandeyeFit) -> dict | None:
    """``handeye.kinematic``: how the robot's kinematic error is shared, and what the
    unknowns took of it (``G``, one (P, 6) per photo of ``images`` with status ok, raised by
    the inflation; ``vision-cal locate`` credits a new pose with it)."""
    sh = fit.shared
    if sh is None:
        return None
    return {"over": fit.noise.kin_over, "length_rad": sh.length_rad, "lever_mm": sh.lever_mm,
            "G": sh.G.tolist()}


def photos_document(fit: HandeyeFit, verdict, *, board, req, units: str, skipped,
                    limit: str) -> dict:
    """calibration.json (as a dict) of ``fit`` judged by ``verdict``."""
    xname, yname = fit.names
    std = dict(zip(fit.labels, fit.std))
    lens_std = {n: float(std.get(f"lens.{n}", 0.0)) for n in LENS_NAMES}
    cam = {"images": [v.name for v in fit.views], "size_px": list(fit.size_px),
           "K": lens_K(fit.lens).tolist(), "dist": [float(v) for v in fit.lens[4:]],
           xname: fit.X.tolist(), f"{xname}_std": _pose_std(std, "X"),
           # added fields
           "mount": fit.mount, "intrinsics": "declared" if fit.declared else "estimated",
           "lens_std": lens_std, "sheet_below": False,
           "n_corners": int(sum(len(v.px) for v in fit.views)),
           "corner_rms_px": float(np.sqrt(np.mean([r ** 2 for r in fit.residual_px.values()])))}
    if fit.mount == "fixed":
        cam["covariance"] = {"params": ["rot_x_deg", "rot_y_deg", "rot_z_deg", "x_mm", "y_mm",
                                        "z_mm", "f_px"],
                             "matrix": camera_covariance(fit).tolist()}
        # the robot frame is the sheet frame here: no sheet (a camera of any arm)
        cam["robot_to_sheet"] = {"z1_deg": 0.0, "base_mm": [0.0, 0.0],
                                 "sheet_matrix": [[1.0, 0.0], [0.0, 1.0]]}
    obs, st, obs_mm, st_mm = fit.heldout_rms()
    extra = {
        yname: fit.Y.tolist(), f"{yname}_std": _pose_std(std, "Y"),
        "handeye": {
            "mount": fit.mount, "board": {"sheet": str(board.path), "kind": board.kind,
                                          "describes": board.describe()},
            "robot_poses": str(req.robot_poses), "units_read": units,
            "lens_terms": [n for n, f in zip(LENS_NAMES, fit.free) if f],
            "lens_models": [{"distortion": t, "heldout_px": o} for t, o in fit.lens_models],
            "noise": fit.noise.to_json(), "limited_by": limit,
            "heldout": {"rms_px": obs, "stated_px": st, "rms_mm": obs_mm, "stated_mm": st_mm,
                        "ratio": fit.heldout_ratio, "p_value": fit.heldout_p,
                        "inflation": fit.inflation,
                        "kind": "each photo predicted from a fit of the others"},
            "robot_scale": fit.robot_scale,
            "left_out": dict(fit.left_out), "kinematic": _kinematic(fit)}}
    vf = None
    if fit.mount == "arm":      # a new flange pose is checked against the photos' (locate)
        near = handeye_valid.of_views(
            fit.views, lever_mm=fit.noise.lever_mm or _lever(fit),
            length_rad=(DEFAULT.handeye_photos.kinematic_length_rad if fit.shared is None
                        else fit.shared.length_rad))
        vf = {"flange_poses": handeye_valid.build(near["F"], near["joints"],
                                                  lever_mm=near["lever"],
                                                  length_rad=near["max"])}
    return CalibrationResult(
        method=METHOD, config=DEFAULT.to_json(), cameras=[cam],
        images=tuple(_images(fit, skipped)),
        covariance={"params": list(fit.labels), "matrix": fit.cov.tolist()},
        initial_guess={"method": "closed form AX = ZB (Kronecker product), then one least "
                                 "squares of every corner",
                       xname: fit.start.Z.tolist(), yname: fit.start.X.tolist(),
                       "rotation_rms_deg": fit.start.rotation_rms_deg,
                       "translation_rms_mm": fit.start.translation_rms_mm},
        verdict=verdict.to_json(), outliers=tuple(fit.left_out), valid_for=vf,
        notes=(f"{xname} and {yname} from {len(fit.views)} photos of "
               f"{Path(board.path).name} and the robot's flange poses; the held-out figures "
               "are each photo predicted from a fit of the others, the stated ones what the "
               "fit's stds, the corners' noise and the robot's pose error say",),
        extra=extra).to_json()
