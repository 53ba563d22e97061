"""A camera on any arm's flange (``vision-cal handeye PHOTOS/ --robot-poses POSES --mount
arm``) used: a pixel of a photo taken at a flange pose, mapped to the robot frame.

The photo's camera stands at ``T_robot_camera = F X`` (``F`` the flange pose the controller
reports, ``X`` = ``T_flange_camera``). A pixel's ray meets a plane: the board's (``plane
"board"``: ``z = H`` in the board's frame, ``T_robot_board`` mapping it; the table the board
lay on) or the robot frame's (``plane "robot"``: ``z = H``). The point is found on the
plane by the hand-eye's own forward model (:class:`vision_cal.camera.handeye_lsq.Problem`:
the point projected through ``X``, ``F`` and the lens lands on the pixel; a few Newton steps
from the ray's undistorted start), and its std by implicit differentiation of the same
model: the pixel held, the point moves with the calibration's unknowns (``X``, ``Y``, the
lens terms it fitted: calibration.json ``covariance``) and with the robot's own pose error
at ``F`` (``handeye.noise``: per photo and kinematic, less what the unknowns took of the
kinematic error there, ``handeye.kinematic``), all raised by the held-out inflation the
calibration found. The pixel itself is taken as exact.

The flange poses a request gives (:class:`FlangePose`: ``--flange-pose``, the calibration's
own photos', a ``--robot-poses`` source's) are checked for their units against the
calibration's photos' distance from the robot's base (:func:`check_units`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from vision_cal.camera import handeye_valid
from vision_cal.camera.fixed import Located
from vision_cal.camera.handeye_closed import inv_T
from vision_cal.camera.handeye_lsq import (LENS_NAMES, POSE_NAMES, Problem, View, lens_K,
                                           lens_vector, project_jacobian)
from vision_cal.camera.handeye_stats import Shared
from vision_cal.camera.robot_poses import LIKELY_UNITS, QUAT_TOL, read_robot_poses
from vision_cal.dataset.camera_block import check_camera_entry
from vision_cal.errors import VisionCalError
from vision_cal.measure.mapping import undistort_px

METHOD = "handeye_photos"
PLANES = ("board", "robot")
#: a located point reproduces its pixel within this (px) or is refused
NEWTON_TOL_PX = 1e-6


@dataclass(frozen=True)
class FlangeCamera:
    """A camera on the flange of any arm: ``X`` = ``T_flange_camera``, ``Y`` =
    ``T_robot_board`` (4, 4, mm), ``lens`` (9: fx fy cx cy k1 k2 p1 p2 k3), ``free`` (9,)
    the lens terms the covariance holds, ``cov`` (P, P) of X's six, Y's six and those
    (calibration.json ``covariance``), ``pose_var`` (6,) the variance of the flange's error
    ``D`` at a new pose (``T_robot_flange D``: rotation deg^2, translation mm^2 per axis)."""

    X: np.ndarray
    Y: np.ndarray
    lens: np.ndarray
    free: np.ndarray
    size_px: tuple[int, int]
    cov: np.ndarray
    pose_var: np.ndarray
    intrinsics: str
    images: tuple[str, ...]
    shared: Shared | None = None     # what the unknowns took of the kinematic error

    @property
    def K(self) -> np.ndarray:
        return lens_K(self.lens)


def is_flange_camera(doc: dict, index: int) -> bool:
    """Whether ``cameras[index]`` of a calibration document is a camera on the flange of a
    hand-eye from photos and the robot's poses (any arm), not a SCARA's."""
    cams = doc.get("cameras") if isinstance(doc, dict) else None
    entry = cams[index] if isinstance(cams, list) and 0 <= index < len(cams) else None
    return (doc.get("method") == METHOD and isinstance(entry, dict)
            and entry.get("mount") == "arm" and "T_flange_camera" in entry)


def _matrix(v, shape, file, field) -> np.ndarray:
    try:
        a = np.asarray(v, float)
    except (TypeError, ValueError) as e:
        raise VisionCalError(f"expected numbers of shape {shape}", file=file,
                             field=field) from e
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise VisionCalError(f"expected finite numbers of shape {shape}", file=file,
                             field=field)
    return a


def _labels(free) -> list[str]:
    return ([f"X.{n}" for n in POSE_NAMES] + [f"Y.{n}" for n in POSE_NAMES]
            + [f"lens.{n}" for n, f in zip(LENS_NAMES, free) if f])


def flange_camera_of(doc: dict, index: int, *, file: str | None = None) -> FlangeCamera:
    """The camera ``cameras[index]`` of a hand-eye's calibration.json (``is_flange_camera``),
    every field it uses checked."""
    where = f"cameras[{index}]"
    entry = doc["cameras"][index]
    check_camera_entry(entry, where, file or "calibration.json", doc=doc)
    X = _matrix(entry["T_flange_camera"], (4, 4), file, f"{where}.T_flange_camera")
    Y = _matrix(doc.get("T_robot_board"), (4, 4), file, "T_robot_board")
    K = _matrix(entry["K"], (3, 3), file, f"{where}.K")
    lens = lens_vector(K, np.asarray(entry["dist"], float).ravel())
    he = doc.get("handeye") if isinstance(doc.get("handeye"), dict) else {}
    terms = he.get("lens_terms", [])
    if not isinstance(terms, list) or not set(terms) <= set(LENS_NAMES):
        raise VisionCalError(f"expected lens term names, got {terms!r}", file=file,
                             field="handeye.lens_terms")
    free = np.array([n in terms for n in LENS_NAMES])
    cov_doc = doc.get("covariance") or {}
    labels = _labels(free)
    if list(cov_doc.get("params") or []) != labels:
        raise VisionCalError(f"expected the parameters {labels}", file=file,
                             field="covariance.params")
    cov = _matrix(cov_doc.get("matrix"), (len(labels), len(labels)), file,
                  "covariance.matrix")
    noise = he.get("noise") if isinstance(he.get("noise"), dict) else {}
    infl = (he.get("heldout") or {}).get("inflation", 1.0)
    vals = [noise.get(k, 0.0) for k in ("robot_rotation_deg", "robot_translation_mm",
                                        "kinematic_rotation_deg", "kinematic_translation_mm")]
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and 0 <= v < 1e3
               for v in vals + [infl]) or infl < 1.0:
        raise VisionCalError("expected the robot's pose error (deg, mm: at least 0) and the "
                             "held-out inflation (at least 1)", file=file,
                             field="handeye.noise")
    rot2 = vals[0] ** 2 + vals[2] ** 2
    tr2 = vals[1] ** 2 + vals[3] ** 2
    size = tuple(int(v) for v in entry["size_px"])
    return FlangeCamera(X, Y, lens, free, size, cov, infl ** 2 * np.r_[[rot2] * 3, [tr2] * 3],
                        str(entry.get("intrinsics", "declared")),
                        tuple(str(i) for i in entry.get("images") or ()),
                        _shared_of(doc, he.get("kinematic"), len(labels), file))


def _shared_of(doc: dict, block, P: int, file) -> Shared | None:
    """calibration.json ``handeye.kinematic`` as a :class:`Shared` (None: no kinematic
    term), the photos' poses from ``images[]`` (status ok)."""
    if block is None:
        return None
    if not isinstance(block, dict) or block.get("over") not in ("joints", "flange poses"):
        raise VisionCalError("expected over: joints | flange poses, length_rad, lever_mm, G",
                             file=file, field="handeye.kinematic")
    F, Q = handeye_valid.photo_poses(doc, over=block["over"], file=file)
    length = handeye_valid.number(block, "length_rad", file, "handeye.kinematic")
    lever = handeye_valid.number(block, "lever_mm", file, "handeye.kinematic")
    G = _matrix(block.get("G"), (len(F), P, 6), file, "handeye.kinematic.G")
    return Shared(G, F, Q, length, lever)


def _plane_frame(cam: FlangeCamera, plane: str) -> np.ndarray:
    if plane not in PLANES:
        raise VisionCalError(f"expected one of {', '.join(PLANES)}, got {plane!r}",
                             field="--plane")
    return cam.Y if plane == "board" else np.eye(4)


def _start(cam: FlangeCamera, F: np.ndarray, uv: np.ndarray, z_mm: float, P: np.ndarray):
    """Where the pixels' rays (undistorted) meet the plane z = ``z_mm`` of frame ``P``: the
    points (N, 3) in that frame."""
    ideal = undistort_px(uv, cam.K, cam.lens[4:])
    d = np.column_stack([(ideal[:, 0] - cam.lens[2]) / cam.lens[0],
                         (ideal[:, 1] - cam.lens[3]) / cam.lens[1], np.ones(len(ideal))])
    T = inv_T(P) @ F @ cam.X                # the camera in the plane's frame
    d = d @ T[:3, :3].T
    o = T[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z_mm - o[2]) / d[:, 2]
    if not np.all(np.isfinite(t) & (t > 0)):
        raise VisionCalError(f"the pixel's ray does not meet the plane z = {z_mm:g} mm in "
                             "front of the camera (the camera is "
                             f"{o[2]:.1f} mm from the plane z = 0)", field="--pixel")
    return o + t[:, None] * d


def locate_at(cam: FlangeCamera, F: np.ndarray, uv_px, z_mm: float = 0.0, *,
              plane: str = "board", joints=None) -> list[Located]:
    """Pixels (N, 2) of a photo taken at flange pose ``F`` (4, 4, mm; the arm's ``joints``
    there, deg, or None) mapped to the plane ``z = z_mm`` of the board's frame (``plane``
    board) or the robot's (robot): robot-frame points, their board-frame coordinates
    (``sheet_mm``: the board is this calibration's sheet) and their std per robot axis
    (module docstring)."""
    uv = np.asarray(uv_px, float).reshape(-1, 2)
    F = np.asarray(F, float)
    Pf = _plane_frame(cam, plane)
    b = _start(cam, F, uv, z_mm, Pf)
    ids = np.arange(len(uv))
    for _ in range(8):       # Newton on the board-plane coordinates: the forward model exact
        pr = Problem([View("locate", F, ids, b, uv)], "arm", cam.X, Pf, cam.lens, cam.free)
        e = (pr.predict(pr.start()) - uv)
        Jb = _pixel_by_point(cam, F, Pf, b)
        b[:, :2] -= np.linalg.solve(Jb, e[:, :, None])[:, :, 0]
        if np.max(np.abs(e)) < 1e-9:
            break
    pr = Problem([View("locate", F, ids, b, uv)], "arm", cam.X, Pf, cam.lens, cam.free)
    miss = float(np.max(np.abs(pr.predict(pr.start()) - uv)))
    if not miss < NEWTON_TOL_PX:
        raise VisionCalError(f"the pixel's ray meets the plane z = {z_mm:g} mm too obliquely "
                             f"to locate it (off by {miss:.2g} px)", field="--pixel")
    std = _std(cam, F, Pf, b, pr, plane, joints)
    p = b @ Pf[:3, :3].T + Pf[:3, 3]
    board = b if plane == "board" else p @ cam.Y[:3, :3] - cam.Y[:3, :3].T @ cam.Y[:3, 3]
    return [Located((float(a), float(c)), float(z_mm), p[i], board[i], std[i])
            for i, (a, c) in enumerate(uv)]


def _pixel_by_point(cam, F, Pf, b) -> np.ndarray:
    """(N, 2, 2) d pixel / d (x, y) of the points ``b`` in the plane's frame."""
    T = inv_T(cam.X) @ inv_T(F) @ Pf
    P = b @ T[:3, :3].T + T[:3, 3]
    _, dP, _ = project_jacobian(P, cam.lens)
    return dP @ T[:3, :2]


def _std(cam, F, Pf, b, pr: Problem, plane: str, joints=None) -> np.ndarray:
    """(N, 3) std (mm) per robot axis of the located points: the pixel held, each point
    moved by the unknowns and the flange's error (first order)."""
    Js, Jd = pr.jacobians(pr.start())
    n = len(b)
    Jb = _pixel_by_point(cam, F, Pf, b)
    J = np.concatenate([Js, Jd], axis=1).reshape(n, 2, -1)
    db = -np.linalg.solve(Jb, J)                           # (N, 2, P + 6)
    R = Pf[:3, :3]
    dp = np.einsum("ij,njk->nik", R[:, :2], db)            # (N, 3, P + 6)
    if plane == "board":   # the plane itself moves with T_robot_board
        q = b @ R.T
        S = np.zeros((n, 3, 3))
        S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = q[:, 2], -q[:, 1], q[:, 0]
        S[:, 1, 0], S[:, 2, 0], S[:, 2, 1] = -q[:, 2], q[:, 1], -q[:, 0]
        dp[:, :, 6:9] += S * (np.pi / 180.0)                # -[q]x per degree
        dp[:, :, 9:12] += np.eye(3)
    else:                  # the robot's plane does not depend on T_robot_board
        dp[:, :, 6:12] = 0.0
    P = cam.cov.shape[0]
    C = np.zeros((P + 6, P + 6))
    C[:P, :P] = cam.cov
    C[P:, P:] = np.diag(cam.pose_var)
    if cam.shared is not None:   # the kinematic error the unknowns took, at this pose too
        X = cam.shared.cross(F, joints)
        C[:P, P:] = -X
        C[P:, :P] = -X.T
    var = np.einsum("nik,kl,nil->ni", dp, C, dp)
    return np.sqrt(np.clip(var, 0.0, None))


# --------------------------------------------------------------------------- the flange poses


@dataclass(frozen=True)
class FlangePose:
    """One flange pose a pixel was seen at: ``T`` (4, 4, mm) ``T_robot_flange``, the arm's
    ``joints`` (deg) or None, and where it came from (``--flange-pose``, a photo's name)."""

    T: np.ndarray
    joints: np.ndarray | None
    source: str


def pose_of(values, *, joints=None, field: str = "--flange-pose") -> FlangePose:
    """``x y z qx qy qz qw`` (mm; the quaternion of norm 1 within the pose files' tolerance)
    as a :class:`FlangePose`."""
    v = np.asarray(values, float).ravel()
    if v.shape != (7,) or not np.all(np.isfinite(v)):
        raise VisionCalError("expected X Y Z QX QY QZ QW: the flange's position (mm) and its "
                             "quaternion, finite", field=field)
    n = float(np.linalg.norm(v[3:]))
    if abs(n - 1.0) > QUAT_TOL:
        raise VisionCalError(f"not a unit quaternion (norm {n:.6g}): expected QX QY QZ QW of "
                             "the flange's rotation", field=field)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(v[3:] / n).as_matrix()
    T[:3, 3] = v[:3]
    return FlangePose(T, None if joints is None else np.asarray(joints, float), field)


#: a flange pose whose distance from the robot's base is more than this factor off the
#: calibration's photos' (their median) is in other units
UNIT_RATIO = 4.0


def check_units(poses, doc_F: np.ndarray, *, read_as: str, file: str | None,
                field: str) -> None:
    """Flange poses whose distance from the robot's base is more than :data:`UNIT_RATIO`
    times off the calibration's photos' (``doc_F``): the unit that brings it back named
    (``read_as``: ``mm`` or ``m``, how the values were read), else refused as not this
    arm's."""
    if not len(poses) or not len(doc_F):
        return
    seen = float(np.median(np.linalg.norm(np.asarray(doc_F)[:, :3, 3], axis=1)))
    read = "metres" if read_as == "m" else "millimetres"
    for p in poses:
        given = float(np.linalg.norm(p.T[:3, 3]))
        ratio = seen / max(given, 1e-9)
        if 1.0 / UNIT_RATIO <= ratio <= UNIT_RATIO:
            continue
        f, unit = min(LIKELY_UNITS[read_as], key=lambda u: abs(np.log(ratio / u[0])))
        head = (f"the flange lies {given:.4g} mm from the robot's base, the calibration's "
                f"photos {seen:.4g} mm")
        if 1.0 / UNIT_RATIO <= ratio / f <= UNIT_RATIO:
            raise VisionCalError(f"{head}: the pose is in {unit}, read as {read}", file=file,
                                 field=field)
        raise VisionCalError(f"{head}: not a pose of this arm (its units are {read})",
                             file=file, field=field)


def own_poses(doc: dict) -> dict[str, FlangePose]:
    """The calibration's own photos' flange poses (``images[]`` of status ok), by name and
    by stem."""
    out: dict[str, FlangePose] = {}
    for im in doc.get("images") or []:
        if isinstance(im, dict) and im.get("status") == "ok" and "T_robot_flange" in im:
            p = FlangePose(np.asarray(im["T_robot_flange"], float),
                           None if im.get("joints_deg") is None
                           else np.asarray(im["joints_deg"], float), str(im["file"]))
            out[str(im["file"])] = p
            out.setdefault(Path(str(im["file"])).stem, p)
    return out


def poses_from_file(path) -> tuple[dict[str, FlangePose], str]:
    """The poses of a ``--robot-poses`` source (a folder of per-photo pose files or a CSV,
    as ``vision-cal handeye`` reads them) by stem, and the unit they were read in."""
    poses, units = read_robot_poses(path, spread=False)
    return {p.stem: FlangePose(p.T, p.joints_deg, p.stem) for p in poses}, units


def find_pose(name: str, table: dict[str, FlangePose], *, what: str, file: str | None,
              field: str) -> FlangePose:
    """The pose named ``name`` (a photo's name or stem) in ``table``."""
    p = table.get(name) or table.get(Path(name).stem)
    if p is None:
        raise VisionCalError(f"no flange pose named {name!r} in {what}", file=file,
                             field=field)
    return p
