"""The verdict of a hand-eye from photos and the robot's poses, from the data, not the fit.

The figure it stands on is each photo predicted from the others (leave one out): where the
board's corners should appear from the calibration and the robot's pose alone, against
where they were seen. ``ready`` only when those held-out photos land within what the fit
states for them (its stds, the corners' noise and the robot's pose error, estimated from
the residual), no photo had to be left out, and a declared lens agrees with the photos.
Otherwise ``check`` with each reason, and the stated errors raised to what the held-out
photos show (so the figure given covers what is seen). The robot's own pose error is
named when it, not the corners' detection, limits the calibration.

``expected_target_error_mm``: the radius holding 95 % of a board point's held-out error at
the board (2-D, mm at the board's distance), from the stated RMS.
"""

from __future__ import annotations

import numpy as np

from vision_cal.camera.handeye import HandeyeFit
from vision_cal.config import DEFAULT, HandeyePhotosConfig
from vision_cal.estimate.verdict import R95_PER_RMS, Verdict

_RANK = {"ready": 0, "check": 1, "not reliable": 2}


def limited_by(fit: HandeyeFit, cfg: HandeyePhotosConfig) -> str:
    """What limits the calibration: the robot's pose error or the corners' detection."""
    nz = fit.noise
    apart = ", rotation and translation not told apart" if nz.confounded else ""
    kin = (f"; its kinematic error, shared by nearby configurations (over the {nz.kin_over}), "
           f"about {nz.kin_mm:.2g} mm and {nz.kin_deg:.2g} deg per axis: {nz.kin_px:.2g} px"
           if nz.kin_mm > 0 else "")
    robot_px = float(np.hypot(nz.pose_px, nz.kin_px))
    rob = (f"the robot's own pose error (about {nz.sigma_mm:.2g} mm and {nz.sigma_rot_deg:.2g} "
           f"deg per axis a photo{apart}: {nz.pose_px:.2g} px per axis on the board's "
           f"corners{kin})")
    det = f"the corners' detection ({nz.sigma_px:.2g} px per axis)"
    if robot_px > cfg.dominant_pose_ratio * nz.sigma_px:
        return (f"{rob}, far above {det}: the arm's accuracy, not the camera, limits this "
                "calibration (more photos average it down; a calibrated arm does better)")
    if nz.sigma_px > cfg.dominant_pose_ratio * robot_px:
        return f"{det}, above {rob}: sharper photos or a larger board help most"
    return f"{det} and {rob} alike"


def lens_check(fit: HandeyeFit, free: HandeyeFit | None,
               config: HandeyePhotosConfig | None = None) -> str | None:
    """A declared lens (``fit``'s) against one estimated from the same photos (``free``;
    None: too few photos to estimate one): the sentence naming it when held-out photos are
    predicted ``declared_lens_ratio`` times better by the estimated one, or when a focal
    length or the principal point lies more than ``declared_lens_std`` of its std from the
    estimate (a focal length wrong by some % moves the camera by as much along its axis,
    which the robot's motion shows but the photos' predictions may hide)."""
    cfg = config or DEFAULT.handeye_photos
    if free is None:
        return None
    dec, est = fit.heldout_rms()[0], free.heldout_rms()[0]
    sd = dict(zip(free.labels, free.std))
    names = ("fx", "fy", "cx", "cy")
    off = [k for k, n in enumerate(names)
           if abs(fit.lens[k] - free.lens[k]) > cfg.declared_lens_std * sd[f"lens.{n}"]]
    if dec <= cfg.declared_lens_ratio * est and not off:
        return None
    terms = [f"{n} {fit.lens[k]:.1f} declared, {free.lens[k]:.1f} +- {sd[f'lens.{n}']:.2g} "
             "estimated" for k, n in enumerate(names)]
    return (f"the declared lens disagrees with these photos: held-out photos {dec:.3g} px RMS "
            f"with it, {est:.3g} px with a lens estimated from them ({'; '.join(terms)}): is "
            "it this camera's lens, at this focus and resolution? leave --camera out to "
            "estimate it")


def _reasons(fit: HandeyeFit, cfg: HandeyePhotosConfig, lens_check: str | None
             ) -> list[tuple[str, str]]:
    out = []
    obs, st, obs_mm, st_mm = fit.heldout_rms()
    if fit.inflation > 1.0 and fit.heldout_p < cfg.heldout_alpha:
        out.append(("check", f"held-out photos are predicted {fit.heldout_ratio:.2f}x worse than "
                             f"the fit's own noise says ({obs:.3g} px against "
                             f"{st / fit.inflation:.3g} px RMS, p = {fit.heldout_p:.2g}): the "
                             "robot's pose error varies with its configuration more than the "
                             "photos' residual shows (its kinematics), or the lens or the "
                             "board is not what the model says; every std and stated error is "
                             f"raised {fit.inflation:.2f}x to what they show"))
    if fit.left_out:
        out.append(("check", f"{len(fit.left_out)} photo(s) left out: "
                             + "; ".join(f"{k}: {v}" for k, v in fit.left_out.items())))
    if lens_check:
        out.append(("check", lens_check))
    n = len(fit.views)
    if n < 2 * cfg.min_photos:
        out.append(("check", f"{n} photos: the noise and the stds rest on few; take "
                             f"{2 * cfg.min_photos} or more, the flange turned about different "
                             "axes"))
    return out


def judge_handeye(fit: HandeyeFit, *, lens_check: str | None = None,
                  config: HandeyePhotosConfig | None = None) -> Verdict:
    """The verdict block of ``fit`` (``lens_check``: a sentence when a declared lens
    disagrees with the photos, else None)."""
    cfg = config or DEFAULT.handeye_photos
    reasons = _reasons(fit, cfg, lens_check)
    _, st, _, st_mm = fit.heldout_rms()
    status = max((s for s, _ in reasons), key=_RANK.get, default="ready")
    ordered = tuple(t for s, t in sorted(reasons, key=lambda r: -_RANK[r[0]]))
    return Verdict(status, float(R95_PER_RMS * st_mm), float(fit.heldout_ratio), ordered,
                   repeatability_mm=float(fit.noise.sigma_mm),
                   repeatability_source="the robot's pose error, from the residual")
