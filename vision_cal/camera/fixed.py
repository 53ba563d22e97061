"""A camera that stood still: its pose in the robot frame, and pixel -> robot mapping.

Frames (``docs/format.md``, "The robot frame and cameras"): robot frame R has its origin on
the joint-1 axis in the sheet's plane, x along link 1 at commanded ``q1 = 0``, z up; a
sheet point is ``p_S = base + Rot(z1) p_R`` (with a ``sheet_affine`` effect ``M``:
``p_S = M (base + Rot(z1) p_R)``, the arm's plane mapped to the printed sheet). Heights z
are the same in both. Camera frame C is OpenCV's; ``T_A_B`` (4, 4) maps B to A, mm.

How a still camera is found: every usable photo's marker mapping (``SheetMapping``) is
compared with the first photo of each group at the sheet markers' corners; photos that
agree within ``same_pose_px`` are one camera pose. A group of two or more photos (or any
photo when session.json declares ``camera.fixed: true``) gives a ``cameras`` entry.

The pose: marker corners averaged over the group's photos (so corner noise shared by the
photos, such as print error, is in the residual and therefore in the std), then
``T_camera_sheet`` by least squares on the reprojection error, with the declared ``K`` and
``dist``; with no declared camera also the focal length (principal point and distortion
from the measurement's lens estimate, else the image centre and none). A camera looking
straight down cannot tell its focal length from its distance: the fit then says so through
``f_px``'s std, and heights away from the sheet plane carry that std (``locate``).

The std: the fit's covariance (scaled by the residual variance) plus the calibration's
covariance of ``z1`` and ``base`` propagated to a 7-vector: small rotation of
``T_robot_camera`` (deg, about the robot axes), its translation (mm) and ``f_px``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision_cal.dataset.camera_block import check_camera_entry
from vision_cal.dataset.fields import FieldReader
from vision_cal.errors import VisionCalError
from vision_cal.measure.mapping import undistort_px
from vision_cal.model.rms import rms_2d
from vision_cal.model.solve import solve

#: photos whose marker mappings differ by less than this at every marker corner (px) were
#: taken from one camera pose
SAME_POSE_PX = 0.5
#: names of the covariance's parameters (the entry's ``covariance.params``)
#: a fitted focal length with a std above this fraction of itself is not used: the camera
#: looks (nearly) square at the sheet, so only points on the sheet's plane can be located
F_REL_STD_MAX = 0.1
UNDETERMINED = "focal length undetermined"
COV_PARAMS = ("rot_x_deg", "rot_y_deg", "rot_z_deg", "x_mm", "y_mm", "z_mm", "f_px")
#: the pose fit's parameters (``T_camera_sheet``'s rotation vector and translation, f)
POSE_PARAMS = ("rvec_x", "rvec_y", "rvec_z", "tvec_x_mm", "tvec_y_mm", "tvec_z_mm", "f_px")


# --------------------------------------------------------------------------- transforms

def rot_z(angle_rad: float) -> np.ndarray:
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def homogeneous(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, float).reshape(3)
    return T


def T_sheet_robot(z1_deg: float, base_mm, sheet_matrix=None) -> np.ndarray:
    """(4, 4) robot frame -> sheet frame (the contract's ``p_S = base + Rot(z1) p_R``, z
    unchanged); ``sheet_matrix`` (2, 2) a ``sheet_affine`` effect's M applied after it."""
    T = homogeneous(rot_z(np.radians(z1_deg)), [base_mm[0], base_mm[1], 0.0])
    if sheet_matrix is not None:
        A = np.eye(4)
        A[:2, :2] = np.asarray(sheet_matrix, float)
        T = A @ T
    return T


def _perturb(T: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``T`` turned by rotation vector d[:3] (rad, about the target frame's axes) and moved
    by d[3:6] (mm)."""
    R = cv2.Rodrigues(np.asarray(d[:3], float).reshape(3, 1))[0]
    return homogeneous(R @ T[:3, :3], T[:3, 3] + d[3:6])


# --------------------------------------------------------------------------- results

@dataclass(frozen=True)
class FixedCamera:
    """One still camera. ``K`` (3, 3), ``dist`` (n,), ``T_robot_camera`` (4, 4);
    ``cov`` (7, 7) in :data:`COV_PARAMS` (``f_px`` variance 0 when ``K`` was declared), or
    (9, 9) with ``k1``, ``k2`` after them (an arm camera whose lens was estimated, at one
    command: ``camera/arm.camera_for``);
    ``sheet_matrix`` (2, 2) the calibration's sheet_affine (identity without one)."""

    images: tuple[str, ...]
    size_px: tuple[int, int]
    K: np.ndarray
    dist: np.ndarray
    intrinsics: str                    # "declared" | "estimated"
    T_robot_camera: np.ndarray
    cov: np.ndarray
    corner_rms_px: float
    n_corners: int
    z1_deg: float
    base_mm: tuple[float, float]
    sheet_matrix: np.ndarray

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    def to_json(self) -> dict:
        sd = self.std
        d = {"images": list(self.images), "size_px": list(self.size_px),
             "K": self.K.tolist(), "dist": [float(v) for v in self.dist],
             "T_robot_camera": self.T_robot_camera.tolist(),
             # added fields
             "intrinsics": self.intrinsics,
             "T_robot_camera_std": {"rotation_deg": sd[:3].tolist(),
                                    "translation_mm": sd[3:6].tolist()},
             "covariance": {"params": list(COV_PARAMS), "matrix": self.cov.tolist()},
             "corner_rms_px": self.corner_rms_px, "n_corners": self.n_corners,
             "robot_to_sheet": {"z1_deg": self.z1_deg, "base_mm": list(self.base_mm),
                                "sheet_matrix": self.sheet_matrix.tolist()}}
        if self.intrinsics == "estimated":
            d["f_px_std"] = float(sd[6])
        if self.intrinsics == UNDETERMINED:
            d["note"] = ("the camera looks square at the sheet, so its focal length and its "
                         "height cannot be told apart: pixels map to the sheet's plane only "
                         "(its height and T_robot_camera's z are not known); declare camera K "
                         "in session.json, or tilt the camera")
        return d


def camera_from_json(entry: dict, *, where: str = "cameras[0]", file: str | None = None
                     ) -> FixedCamera:
    """A ``cameras`` entry written by :meth:`FixedCamera.to_json` (shapes checked; its values
    by the one validator, :func:`vision_cal.dataset.camera_block.check_camera_entry`, which
    :func:`camera_of` runs first)."""
    def arr(key, shape):
        try:
            a = np.asarray(entry[key], dtype=float)
        except (KeyError, TypeError, ValueError) as e:
            raise VisionCalError("missing or not numeric", file=file, field=f"{where}.{key}") from e
        if shape is not None and a.shape != shape or not np.all(np.isfinite(a)):
            raise VisionCalError(f"expected finite numbers of shape {shape}", file=file,
                                 field=f"{where}.{key}")
        return a

    if not isinstance(entry, dict):
        raise VisionCalError("expected an object", file=file, field=where)
    if "T_robot_camera" not in entry:
        raise VisionCalError("no T_robot_camera (a camera on the arm cannot map a pixel "
                             "without the arm's pose)", file=file, field=f"{where}.T_robot_camera")
    K, T = arr("K", (3, 3)), arr("T_robot_camera", (4, 4))
    dist = arr("dist", None).ravel()
    size = arr("size_px", (2,))
    try:
        cov = np.asarray(entry["covariance"]["matrix"], float)
        if cov.shape != (7, 7):
            raise ValueError
    except (KeyError, TypeError, ValueError):
        cov = np.zeros((7, 7))      # no std known: locate prints none
    r2s = entry.get("robot_to_sheet") or {}
    try:
        z1 = float(r2s["z1_deg"])
        base = tuple(float(v) for v in r2s["base_mm"])
        M = np.asarray(r2s.get("sheet_matrix", np.eye(2)), float).reshape(2, 2)
    except (KeyError, TypeError, ValueError) as e:
        raise VisionCalError("expected z1_deg, base_mm and sheet_matrix", file=file,
                             field=f"{where}.robot_to_sheet") from e
    imgs = entry.get("images", [])
    return FixedCamera(tuple(str(i) for i in imgs) if isinstance(imgs, list) else (),
                       (int(size[0]), int(size[1])), K, dist,
                       str(entry.get("intrinsics", "declared")), T, cov,
                       float(entry.get("corner_rms_px", float("nan"))),
                       int(entry.get("n_corners", 0)), z1, base, M)


# --------------------------------------------------------------------------- grouping

def still_groups(images, corners_mm: np.ndarray, *, same_pose_px: float = SAME_POSE_PX
                 ) -> list[list[int]]:
    """Indices of ``images`` (measured ``ImageResult``) grouped by camera pose.

    ``corners_mm`` (N, 2): sheet points where the mappings are compared (the markers'
    corners). Photos without a mapping (skipped) are left out."""
    groups: list[list[int]] = []
    ref_px: list[np.ndarray] = []
    for i, im in enumerate(images):
        if im.status != "ok" or im.mapping is None:
            continue
        px = im.mapping.sheet_to_image(corners_mm)
        for g, ref in zip(groups, ref_px):
            if (images[g[0]].size_px == im.size_px
                    and np.max(np.hypot(*(px - ref).T)) < same_pose_px):
                g.append(i)
                break
        else:
            groups.append([i])
            ref_px.append(px)
    return groups


def mean_corners(images, idx) -> tuple[np.ndarray, np.ndarray]:
    """Marker corners averaged over photos ``idx``: (ids (M,), corners_px (M, 4, 2))."""
    acc: dict[int, list[np.ndarray]] = {}
    for i in idx:
        im = images[i]
        for mid, c in zip(im.marker_ids, im.markers_px):
            acc.setdefault(int(mid), []).append(np.asarray(c, float))
    ids = np.array(sorted(acc), int)
    return ids, np.array([np.mean(acc[m], axis=0) for m in ids]).reshape(-1, 4, 2)


# --------------------------------------------------------------------------- the pose fit

def _project(p, obj, K, dist, free_f):
    Kp = K.copy()
    if free_f:
        Kp[0, 0] = Kp[1, 1] = p[6]
    out, _ = cv2.projectPoints(obj.reshape(-1, 1, 3), p[:3], p[3:6], Kp, dist)
    return np.asarray(out, float).reshape(-1, 2)


def fit_pose(obj_mm: np.ndarray, img_px: np.ndarray, K, dist, *, free_f: bool
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``T_camera_sheet`` (4, 4), ``K`` used, covariance (7, 7) of (rvec rad, tvec mm, f px)
    and the corner RMS (px) from sheet points ``obj_mm`` (N, 2) seen at ``img_px`` (N, 2).
    The covariance by the one policy (:func:`vision_cal.model.solve.covariance`): a
    direction the corners do not fix (f against the distance for a camera square to the
    sheet) has an infinite variance; f's row is zero when it is not fitted."""
    obj = np.column_stack([obj_mm, np.zeros(len(obj_mm))]).astype(np.float64)
    img = np.asarray(img_px, np.float64).reshape(-1, 2)
    K = np.asarray(K, float).copy()
    dist = np.asarray(dist, float).ravel()
    ok, rvec, tvec = cv2.solvePnP(obj.reshape(-1, 1, 3), img.reshape(-1, 1, 2), K, dist,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise VisionCalError("the camera pose could not be found from the markers")
    p0 = np.concatenate([np.ravel(rvec), np.ravel(tvec), [K[0, 0]]])
    n_free = 7 if free_f else 6

    def res(x):
        p = np.concatenate([x, p0[n_free:]])
        return (_project(p, obj, K, dist, free_f) - img).ravel()

    sol = solve(res, p0[:n_free], x_scale="jac", xtol=1e-8, ftol=1e-8)
    if not sol:
        raise VisionCalError(f"the camera pose could not be fitted: {sol.reason}")
    p = np.concatenate([sol.x, p0[n_free:]])
    r = sol.residuals
    cov = np.zeros((7, 7))
    cov[:n_free, :n_free] = sol.covariance(POSE_PARAMS[:n_free], s2=float(r @ r) / max(
        len(r) - n_free, 1)).stated
    if free_f:
        K[0, 0] = K[1, 1] = p[6]
    T = homogeneous(cv2.Rodrigues(p[:3].reshape(3, 1))[0], p[3:6])
    return T, K, cov, rms_2d(r.reshape(-1, 2))


def _robot_camera(p7, robot3, M) -> np.ndarray:
    """T_robot_camera from pose params (rvec, tvec, f) and robot (z1 deg, bx, by)."""
    T_cs = homogeneous(cv2.Rodrigues(np.asarray(p7[:3], float).reshape(3, 1))[0], p7[3:6])
    T_sr = T_sheet_robot(robot3[0], robot3[1:3], M)
    return np.linalg.inv(T_sr) @ np.linalg.inv(T_cs)


def pose_delta(T: np.ndarray, T0: np.ndarray) -> np.ndarray:
    """(rotation vector rad, translation mm) taking T0 to T (rotation in the target frame)."""
    R = T[:3, :3] @ T0[:3, :3].T      # near the identity: its skew part (first order;
    w = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return np.concatenate([w, T[:3, 3] - T0[:3, 3]])   # cv2.Rodrigues rounds it to 0)


def robot_block(model, cov_doc: dict | None, std_doc: dict | None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(z1 deg, base x, base y), their covariance (3, 3) from calibration.json's
    ``covariance`` (else ``std``, correlations ignored) and the sheet_affine matrix."""
    p = model.params
    robot3 = np.array([p.joint_zero_deg[0], p.base_mm[0], p.base_mm[1]], float)
    names = ("z1_deg", "base_x_mm", "base_y_mm")
    cov3 = np.zeros((3, 3))
    if cov_doc and all(n in cov_doc.get("params", []) for n in names):
        ix = [list(cov_doc["params"]).index(n) for n in names]
        cov3 = np.asarray(cov_doc["matrix"], float)[np.ix_(ix, ix)]
    elif std_doc:
        sd = [std_doc["joint_zero_deg"][0], std_doc["base_mm"][0], std_doc["base_mm"][1]]
        cov3 = np.diag(np.square(np.asarray(sd, float)))
    return robot3, cov3, np.asarray(model.sheet_matrix(), float)


def fixed_camera(images, idx, sheet_corners: dict, *, K, dist, free_f: bool, robot3,
                 cov3, sheet_matrix, intrinsics: str) -> FixedCamera:
    """The :class:`FixedCamera` of photos ``idx`` of ``images``; ``sheet_corners``: marker
    id -> corners (4, 2) mm."""
    ids, px = mean_corners(images, idx)
    keep = np.array([int(m) in sheet_corners for m in ids], bool)
    ids, px = ids[keep], px[keep]
    if len(ids) < 2:
        raise VisionCalError(f"{len(ids)} markers seen: at least 2 are needed for the "
                             "camera's pose")
    obj = np.concatenate([np.asarray(sheet_corners[int(m)], float) for m in ids])
    T_cs, K_used, cov_p, rms_px = fit_pose(obj, px.reshape(-1, 2), K, dist, free_f=free_f)
    if free_f and not (K_used[0, 0] > 0 and np.sqrt(cov_p[6, 6]) < F_REL_STD_MAX * K_used[0, 0]):
        # square to the sheet: f and the distance trade; the plane's mapping is still exact
        T_cs, K_used, cov_p, rms_px = fit_pose(obj, px.reshape(-1, 2), K, dist, free_f=False)
        intrinsics = UNDETERMINED
    rvec = cv2.Rodrigues(T_cs[:3, :3])[0].ravel()
    p7 = np.concatenate([rvec, T_cs[:3, 3], [K_used[0, 0]]])
    T0 = _robot_camera(p7, robot3, sheet_matrix)
    # first-order propagation: pose params and robot params -> (rot, trans) of T0, and f
    x0 = np.concatenate([p7, robot3])
    C = np.zeros((10, 10))
    C[:7, :7] = cov_p
    C[7:, 7:] = cov3
    J = np.zeros((7, 10))
    steps = np.array([1e-6] * 3 + [1e-4] * 3 + [1e-2] + [1e-6, 1e-4, 1e-4])
    for k in range(10):
        x = x0.copy()
        x[k] += steps[k]
        xm = x0.copy()
        xm[k] -= steps[k]
        dp = pose_delta(_robot_camera(x[:7], x[7:], sheet_matrix), T0)
        dm = pose_delta(_robot_camera(xm[:7], xm[7:], sheet_matrix), T0)
        J[:6, k] = (dp - dm) / (2 * steps[k])
    J[6, 6] = 1.0
    cov = J @ C @ J.T
    s = np.array([np.degrees(1.0)] * 3 + [1.0] * 4)
    cov = cov * np.outer(s, s)
    return FixedCamera(tuple(images[i].file for i in idx),
                       tuple(int(v) for v in images[idx[0]].size_px), K_used,
                       np.asarray(dist, float).ravel(), intrinsics, T0, cov, rms_px,
                       int(obj.shape[0]), float(robot3[0]),
                       (float(robot3[1]), float(robot3[2])), np.asarray(sheet_matrix, float))


def cameras_json(session, measurement, model, *, covariance: dict | None,
                 std: dict | None) -> tuple[list[dict], list[str]]:
    """calibration.json's ``cameras``: one entry per still camera found in the photos (two
    or more photos from one pose, or any photo with ``camera.fixed: true`` declared), and
    the notes for calibration.json (``covariance``, ``std``: the calibration's blocks)."""
    notes: list[str] = []
    if measurement is None:
        return [], notes
    sheet_corners = {int(m.id): np.asarray(m.corners_mm, float) for m in session.sheet.markers}
    pts = np.concatenate(list(sheet_corners.values())) if sheet_corners else np.zeros((0, 2))
    images = measurement.images
    cam_raw = session.raw.get("camera")
    declared_fixed = (isinstance(cam_raw, dict) and FieldReader(str(session.path)).boolean(
        cam_raw.get("fixed", False), "camera.fixed"))
    robot3, cov3, M = robot_block(model, covariance, std)
    out = []
    groups = still_groups(images, pts)
    if declared_fixed and len(groups) > 1:
        notes.append(
            f"camera.fixed is declared but the photos were taken from {len(groups)} places "
            f"(their marker mappings differ by {SAME_POSE_PX} px or more): one camera entry "
            "per place")
    for g in groups:
        if len(g) < 2 and not declared_fixed:
            continue
        size = tuple(images[g[0]].size_px)
        if session.camera is not None:
            K, dist, free_f, how = session.camera.K, session.camera.dist, False, "declared"
        else:
            lens = measurement.lens
            if lens is not None and tuple(lens.size_px) == size:
                K = np.asarray(lens.K, float).copy()
                dist = np.asarray(lens.dist, float) if lens.kept else np.zeros(5)
            else:
                w, h = size
                f0 = 1.2 * max(size)
                K, dist = np.array([[f0, 0, (w - 1) / 2], [0, f0, (h - 1) / 2], [0, 0, 1.0]]), np.zeros(5)
            free_f, how = True, "estimated"
        try:
            cam = fixed_camera(images, g, sheet_corners, K=K, dist=dist, free_f=free_f,
                               robot3=robot3, cov3=cov3, sheet_matrix=M, intrinsics=how)
        except VisionCalError as e:
            notes.append(
                f"still camera of {images[g[0]].file} (+{len(g) - 1} photos): {e}")
            continue
        out.append(cam.to_json())
    return out, notes


# --------------------------------------------------------------------------- pixel -> robot

@dataclass(frozen=True)
class Located:
    """A pixel mapped to height ``z_mm``: ``robot_mm`` (3,), ``sheet_mm`` (3,) and the
    std (3,) of ``robot_mm`` from the camera's covariance (the pixel itself taken exact)."""

    pixel: tuple[float, float]
    z_mm: float
    robot_mm: np.ndarray
    sheet_mm: np.ndarray
    robot_std_mm: np.ndarray


def _ray_to_plane(uv, K, dist, T_rc, z_mm) -> np.ndarray:
    """Points (N, 3) in R where the pixels' rays (N, 2) meet the plane z = z_mm."""
    ideal = undistort_px(uv, K, dist)
    d_c = np.column_stack([(ideal[:, 0] - K[0, 2]) / K[0, 0],
                           (ideal[:, 1] - K[1, 2]) / K[1, 1], np.ones(len(ideal))])
    d_r = d_c @ T_rc[:3, :3].T
    o = T_rc[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z_mm - o[2]) / d_r[:, 2]
    bad = ~(np.isfinite(t) & (t > 0))
    if bad.any():
        raise VisionCalError(f"the pixel's ray does not meet the plane z = {z_mm:g} mm in "
                             "front of the camera", field="--pixel")
    return o + t[:, None] * d_r


def locate(cam: FixedCamera, uv_px, z_mm: float = 0.0) -> list[Located]:
    """Pixels (N, 2) of this camera's photos -> robot-frame and sheet-frame points at
    height ``z_mm`` above the sheet's plane, with their std."""
    uv = np.asarray(uv_px, float).reshape(-1, 2)
    if cam.intrinsics == UNDETERMINED and z_mm != 0.0:
        raise VisionCalError("this camera's focal length is undetermined (it looks square at "
                             "the sheet): only z = 0 can be located; declare camera K in "
                             "session.json and calibrate again", field="--z-mm")
    T = cam.T_robot_camera
    p = _ray_to_plane(uv, cam.K, cam.dist, T, z_mm)
    # std: the covariance's parameters perturbed (deg, mm, px; then k1, k2 where the
    # camera carries its estimated lens's: an arm camera's), central differences
    n = len(cam.cov)
    J = np.zeros((len(uv), 3, n))
    steps = np.array([1e-4] * 3 + [1e-3] * 3 + [1e-2] + [1e-5] * (n - 7))
    dist0 = np.zeros(max(5, len(np.ravel(cam.dist))))
    dist0[:len(np.ravel(cam.dist))] = np.ravel(cam.dist)
    for k in range(n):
        dp = []
        for sgn in (1.0, -1.0):
            d = np.zeros(n)
            d[k] = sgn * steps[k]
            Tk = _perturb(T, np.concatenate([np.radians(d[:3]), d[3:6]]))
            Kk = cam.K.copy()
            Kk[0, 0] += d[6]
            Kk[1, 1] += d[6]
            dk = dist0.copy()
            dk[:n - 7] += d[7:]
            dp.append(_ray_to_plane(uv, Kk, dk, Tk, z_mm))
        J[:, :, k] = (dp[0] - dp[1]) / (2 * steps[k])
    var = np.einsum("nik,kl,nil->ni", J, cam.cov, J)
    std = np.sqrt(np.clip(var, 0.0, None))
    T_sr = T_sheet_robot(cam.z1_deg, cam.base_mm, cam.sheet_matrix)
    ps = p @ T_sr[:3, :3].T + T_sr[:3, 3]
    return [Located((float(a), float(b)), float(z_mm), p[i], ps[i], std[i])
            for i, (a, b) in enumerate(uv)]


def camera_of(doc: dict, index: int, *, file: str | None = None) -> FixedCamera:
    """The still camera ``cameras[index]`` of a calibration document."""
    cams = doc.get("cameras")
    if not isinstance(cams, list) or not cams:
        raise VisionCalError("no still camera in this calibration (cameras is absent: the "
                             "photos came from different places; take two or more photos "
                             "from the fixed camera, or declare camera.fixed)", file=file,
                             field="cameras")
    if not 0 <= index < len(cams):
        raise VisionCalError(f"camera {index} does not exist (cameras holds {len(cams)}: "
                             f"0..{len(cams) - 1})", file=file, field="--camera")
    # the one validator of a camera block (K, dist, a rotation in mm, covariances)
    check_camera_entry(cams[index], f"cameras[{index}]", file or "calibration.json", doc=doc)
    return camera_from_json(cams[index], where=f"cameras[{index}]", file=file)
