"""What a hand-eye from photos and the robot's poses was calibrated for: the arm's
configurations its photos were taken in (calibration.json ``valid_for.flange_poses``), and
the check every use of it runs on a flange pose (``vision-cal locate`` of a camera on the
arm).

The robot's pose error is part noise and part kinematic: a model length or angle off puts
the flange off by an amount that changes with the arm's configuration, shared by two poses
as ``exp(-d^2 / 2 L^2)`` of their distance ``d`` (:mod:`vision_cal.camera.handeye_stats`:
over the joints when the poses gave them, else over the flange poses, position over the
arm's reach and rotation; ``L`` = ``config.handeye_photos.kinematic_length_rad``). The
stated std of a new pose carries the kinematic error's variance in full, and the unknowns'
covariance carries how far the pose lies from the photos; what neither can say is the
kinematic error of a configuration unlike any photo's: more than ``L`` from every photo, it
shares less than ``exp(-1/2)`` (61 %) of its error with any of them, and its size there is
the model's extrapolation, not a measurement. Such a pose is outside ``valid_for``. A flange
pose alone does not say the arm's configuration (the elbow or the wrist flipped: another
kinematic error at the same pose): give the joints with the poses to have it checked.
"""

from __future__ import annotations

import numpy as np

from vision_cal.camera.handeye_stats import joint_distance, pose_distance
from vision_cal.dataset.valid_for import Outside
from vision_cal.errors import VisionCalError

FIELD = "flange_pose"


def build(F: np.ndarray, joints, *, lever_mm: float, length_rad: float) -> dict:
    """``valid_for.flange_poses`` of the photos' flange poses ``F`` (n, 4, 4, mm) and their
    joints (n, J) deg or None; the photos' poses themselves are calibration.json's
    ``images[].T_robot_flange`` and ``joints_deg``."""
    return {"over": "flange poses" if joints is None else "joints",
            "max_distance_rad": float(length_rad), "lever_mm": float(lever_mm),
            "n_photos": int(len(F))}


def of_views(views, *, lever_mm: float, length_rad: float) -> dict:
    """What :func:`read` gives for a calibration of ``views`` (their flange poses and joints)."""
    q = [v.joints_deg for v in views]
    joints = None if any(x is None for x in q) or len({len(x) for x in q}) > 1 else q
    return {"over": "flange poses" if joints is None else "joints", "max": float(length_rad),
            "lever": float(lever_mm), "F": np.array([v.T_robot_flange for v in views]),
            "joints": None if joints is None else np.array(joints, float)}


def _number(block, key, file, lo=0.0, where="valid_for.flange_poses"):
    v = block.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo < v < 1e9:
        raise VisionCalError(f"expected a number above {lo:g}, got {v!r}", file=file,
                             field=f"{where}.{key}")
    return float(v)


def number(block: dict, key: str, file, where: str) -> float:
    """A positive finite number of a calibration.json block (one line naming it)."""
    return _number(block, key, file, where=where)


def photo_poses(doc: dict, *, over: str, file: str | None = None):
    """The calibration's photos' flange poses (n, 4, 4) and, ``over`` joints, their joints
    (n, J) (``images[]`` of status ok; every field checked)."""
    F, Q = [], []
    for k, im in enumerate(doc.get("images") or []):
        if not isinstance(im, dict) or im.get("status") != "ok":
            continue
        try:
            T = np.asarray(im["T_robot_flange"], float)
            ok = T.shape == (4, 4) and np.all(np.isfinite(T))
            q = None if im.get("joints_deg") is None else np.asarray(im["joints_deg"], float)
            ok = ok and (q is None or (q.ndim == 1 and np.all(np.isfinite(q))))
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise VisionCalError("expected the photo's flange pose (4x4, mm) and its joints "
                                 "(deg) or null", file=file,
                                 field=f"images[{k}].T_robot_flange")
        F.append(T)
        Q.append(q)
    if not F:
        raise VisionCalError("no photo with its flange pose (images[].T_robot_flange)",
                             file=file, field="images")
    if over != "joints":
        return np.array(F), None
    if any(q is None for q in Q) or len({len(q) for q in Q}) > 1:
        raise VisionCalError("over joints, but not every photo lists the same joints",
                             file=file, field="images[].joints_deg")
    return np.array(F), np.array(Q, float)


def read(doc: dict, *, file: str | None = None) -> dict | None:
    """calibration.json ``valid_for.flange_poses`` with its photos' poses (``images[]`` of
    status ok), every field checked; None: the file does not say."""
    vf = doc.get("valid_for") if isinstance(doc, dict) else None
    block = vf.get("flange_poses") if isinstance(vf, dict) else None
    if block is None:
        return None
    if not isinstance(block, dict) or block.get("over") not in ("joints", "flange poses"):
        raise VisionCalError(f"expected an object with over: joints | flange poses, got "
                             f"{block!r}", file=file, field="valid_for.flange_poses")
    F, Q = photo_poses(doc, over=block["over"], file=file)
    return {"over": block["over"], "max": _number(block, "max_distance_rad", file),
            "lever": _number(block, "lever_mm", file), "F": F, "joints": Q}


def nearest(vf: dict, F: np.ndarray, q=None) -> tuple[float, str]:
    """The distance (rad) from flange pose ``F`` (with joints ``q`` or None) to the nearest
    photo's, and what it is over (``joints`` when both have them, else ``flange poses``)."""
    if vf["joints"] is not None and q is not None:
        q = np.asarray(q, float)
        if len(q) != vf["joints"].shape[1]:
            raise VisionCalError(f"{len(q)} joints given, the calibration's photos list "
                                 f"{vf['joints'].shape[1]}", field="joints_deg")
        d = joint_distance(np.vstack([q[None], vf["joints"]]))[0, 1:]
        return float(d.min()), "joints"
    d = pose_distance(np.concatenate([np.asarray(F, float)[None], vf["F"]]), vf["lever"])
    return float(d[0, 1:].min()), "flange poses"


def check(vf: dict | None, *, cal: str, ids, poses, joints=None) -> list[Outside]:
    """The flange poses of a request (``ids``, ``poses`` (N, 4, 4) mm, ``joints`` per item
    (J,) deg or None) outside ``vf`` (:func:`read`): one :class:`Outside` naming each item
    farther than ``max_distance_rad`` from every photo (empty: all inside, or ``vf``
    None)."""
    if vf is None:
        return []
    joints = [None] * len(ids) if joints is None else joints
    each = []
    for i, F, q in zip(ids, poses, joints):
        d, over = nearest(vf, F, q)
        if d > vf["max"]:
            what = ("the arm's joints" if over == "joints" else
                    f"flange position over {vf['lever']:.0f} mm and rotation")
            each.append((i, f"{d:.2f} rad from the nearest photo's pose ({what}), more than "
                            f"the {vf['max']:g} over which the robot's kinematic error is "
                            "shared: a configuration the photos did not see"))
    if not each:
        return []
    bad = [i for i, _ in each]
    return [Outside(
        FIELD, f"{len(bad)} of {len(ids)} flange pose(s) far from every pose the calibration's "
        f"photos were taken at ({', '.join(map(str, bad[:3]))}{' ...' if len(bad) > 3 else ''}"
        "): the robot's kinematic error there is extrapolated and the stated std does not "
        "hold", f"take calibration photos in that configuration too and calibrate again "
        f"(vision-cal handeye PHOTOS/ --robot-poses POSES ...: {cal}'s photos with them), "
        "or --force", tuple(bad), tuple(each))]
