"""One validator for a camera block (issue 29): session.json ``camera`` (the lens) and
calibration.json ``cameras[]`` (a still camera's ``T_robot_camera`` or an arm camera's
``T_flange_camera``), read by ``locate``, ``export``, ``verify`` and ``handeye``.

Every check names the file and the field in one line (:class:`FieldReader`), exit 2:

- ``size_px``: two whole positive pixel counts;
- ``K``: an OpenCV camera matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, finite, ``fx``,
  ``fy`` positive, the principal point inside the image;
- ``dist``: 4, 5, 8, 12 or 14 finite coefficients (the lengths OpenCV takes), each within
  ``MAX_DIST``;
- a pose (``T_robot_camera``, ``T_flange_camera``): 4x4, finite, bottom row 0 0 0 1, its
  rotation a rotation (orthonormal within ``ROTATION_TOL``, determinant +1), its
  translation in millimetres by plausibility: the camera at least ``MIN_HEIGHT_MM`` above
  the sheet's plane (z up in the robot and flange frames, both in that plane; a pose in
  metres puts a camera 0.8 mm above the paper) and within ``MAX_REACH_FACTOR`` reaches
  (L1 + L2) of the robot's axis;
- covariances (``covariance.matrix``) square, finite, symmetric and positive
  semi-definite (within ``PSD_TOL`` of the largest variance), stds finite and non-negative;
- ``robot_to_sheet.sheet_matrix`` a sheet scaled by less than 50 % (invertible).
"""

from __future__ import annotations

import numpy as np

from vision_cal.dataset.fields import MAX_DIST, MAX_IMAGE_PX, MAX_K_PX, FieldReader

#: the distortion vector lengths OpenCV takes (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]])
DIST_LENGTHS = (4, 5, 8, 12, 14)
#: |R^T R - I| and |det R - 1| within this: a rotation written with 6+ digits
ROTATION_TOL = 1e-4
#: a camera looking at the sheet stands at least this far above its plane (mm)
MIN_HEIGHT_MM = 10.0
#: and within this many arm reaches (L1 + L2) of the robot's axis
MAX_REACH_FACTOR = 20.0
#: a covariance's most negative eigenvalue and asymmetry, relative to its largest variance
PSD_TOL = 1e-9


def _matrix(r: FieldReader, v, where: str, shape: tuple[int, int]) -> np.ndarray:
    rows = r.list_(v, where)
    if len(rows) != shape[0]:
        r.fail(where, f"expected a {shape[0]}x{shape[1]} matrix, got {len(rows)} rows")
    return np.array([r.vector(row, f"{where}[{i}]", shape[1], lo=-1e12, hi=1e12)
                     for i, row in enumerate(rows)], float)


def read_lens(r: FieldReader, cam, where: str = "camera", *, principal_inside: bool = True
              ) -> tuple[tuple[int, int], np.ndarray, np.ndarray]:
    """``size_px``, ``K`` and ``dist`` of a camera block, every field checked:
    ((w, h), K (3, 3), dist (n,)). ``principal_inside``: the principal point must lie in the
    image (a calibration's camera; session.json's declared lens is read as it always was)."""
    if not isinstance(cam, dict):
        r.fail(where, f"expected an object with size_px, K and dist, got {type(cam).__name__}")
    size = r.vector(r.get(cam, "size_px", where), f"{where}.size_px", 2, lo=1, hi=MAX_IMAGE_PX,
                    what="image size in pixels")
    if any(x != int(x) for x in size):
        r.fail(f"{where}.size_px", f"expected whole pixels, got {list(size)}")
    w, h = int(size[0]), int(size[1])
    K_raw = r.list_(r.get(cam, "K", where), f"{where}.K")
    if len(K_raw) != 3:
        r.fail(f"{where}.K", "expected a 3x3 matrix")
    K = np.array([r.vector(row, f"{where}.K[{i}]", 3, lo=-MAX_K_PX, hi=MAX_K_PX,
                           what="pixel value") for i, row in enumerate(K_raw)])
    for i in (0, 1):
        if not K[i, i] > 0:
            r.fail(f"{where}.K[{i}][{i}]", f"expected a positive focal length in pixels, got "
                                           f"{K[i, i]:g}")
    if K[1, 0] != 0 or tuple(K[2]) != (0.0, 0.0, 1.0):
        r.fail(f"{where}.K", "expected an OpenCV camera matrix [[fx,s,cx],[0,fy,cy],[0,0,1]]")
    if principal_inside and not (-0.5 <= K[0, 2] <= w - 0.5 and -0.5 <= K[1, 2] <= h - 0.5):
        r.fail(f"{where}.K", f"the principal point ({K[0, 2]:g}, {K[1, 2]:g}) px is outside "
                             f"the {w}x{h} image")
    dist_raw = r.list_(r.get(cam, "dist", where), f"{where}.dist")
    if len(dist_raw) not in DIST_LENGTHS:
        r.fail(f"{where}.dist", f"expected {', '.join(map(str, DIST_LENGTHS[:-1]))} or "
                                f"{DIST_LENGTHS[-1]} OpenCV coefficients, got {len(dist_raw)}")
    dist = np.array([r.number(x, f"{where}.dist[{i}]", lo=-MAX_DIST, hi=MAX_DIST,
                              what="distortion coefficient") for i, x in enumerate(dist_raw)])
    return (w, h), K, dist


def read_pose(r: FieldReader, v, where: str, *, reach_mm: float | None = None,
              sheet_below: bool = True) -> np.ndarray:
    """A camera pose (4, 4) in mm whose z axis is the sheet's normal (up) and whose origin
    lies in the sheet's plane (``T_robot_camera``, ``T_flange_camera``), checked: a
    rotation, a camera above the sheet looking at it, millimetres. ``sheet_below`` False
    (a camera entry's ``sheet_below: false``: a hand-eye of any arm, whose robot frame has
    no sheet in its plane): the camera may stand and look anywhere."""
    T = _matrix(r, v, where, (4, 4))
    if not np.allclose(T[3], [0, 0, 0, 1], atol=1e-12):
        r.fail(where, f"expected a bottom row 0 0 0 1, got {T[3].tolist()}")
    R = T[:3, :3]
    err = float(np.max(np.abs(R.T @ R - np.eye(3))))
    if err > ROTATION_TOL or abs(np.linalg.det(R) - 1.0) > ROTATION_TOL:
        r.fail(where, f"its 3x3 part is not a rotation (R^T R off the identity by {err:.3g}, "
                      f"det {np.linalg.det(R):.6g}): a scaled or mirrored matrix")
    height = float(T[2, 3])
    if not sheet_below:
        return T
    if not height >= MIN_HEIGHT_MM:
        r.fail(where, f"the camera is {height:.4g} mm above the sheet's plane (at least "
                      f"{MIN_HEIGHT_MM:g} mm for a camera that sees it): "
                      + ("a translation in metres? vision-cal writes mm" if 0 < height < 5
                         else "z is up, the camera above the sheet"))
    if float(R[2, 2]) >= 0:
        r.fail(where, "the camera looks away from the sheet (its optical axis points up)")
    if reach_mm is not None and reach_mm > 0:
        d = float(np.linalg.norm(T[:3, 3]))
        if d > MAX_REACH_FACTOR * reach_mm:
            r.fail(where, f"the camera is {d:.4g} mm from the robot, {d / reach_mm:.0f} arm "
                          f"reaches: not in millimetres?")
    return T


def read_covariance(r: FieldReader, v, where: str, *, n: int | None = None) -> np.ndarray:
    """A covariance ``{"matrix": [[...]]}`` (or the matrix itself): square (n x n when
    given), finite, symmetric and positive semi-definite."""
    m = v.get("matrix") if isinstance(v, dict) else v
    w = f"{where}.matrix" if isinstance(v, dict) else where
    rows = r.list_(m, w, nonempty=True)
    k = len(rows)
    if n is not None and k != n:
        r.fail(w, f"expected a {n}x{n} matrix, got {k} rows")
    C = _matrix(r, rows, w, (k, k))
    scale = max(float(np.max(np.abs(np.diag(C)))), 1e-300)
    if np.max(np.abs(C - C.T)) > PSD_TOL * scale + 1e-15:
        r.fail(w, "not symmetric")
    lo = float(np.min(np.linalg.eigvalsh((C + C.T) / 2)))
    if lo < -PSD_TOL * scale - 1e-15:
        r.fail(w, f"not positive semi-definite (an eigenvalue of {lo:.3g})")
    return C


def read_std(r: FieldReader, v, where: str) -> None:
    """A std block (``{"rotation_deg": [...], "translation_mm": [...]}``): finite, >= 0."""
    if v is None:
        return
    if not isinstance(v, dict):
        r.fail(where, f"expected an object, got {type(v).__name__}")
    for key, x in v.items():
        for i, s in enumerate(x if isinstance(x, list) else [x]):
            r.number(s, f"{where}.{key}" + (f"[{i}]" if isinstance(x, list) else ""),
                     lo=0.0, hi=1e9, what="standard deviation")


def check_camera_entry(entry, where: str, file: str, *, doc: dict | None = None) -> None:
    """A calibration.json ``cameras[]`` entry, every field a reader uses checked (still:
    ``T_robot_camera``, its covariance 7x7 and ``robot_to_sheet``; on the arm:
    ``T_flange_camera`` with the document's ``covariance``)."""
    r = FieldReader(file)
    read_lens(r, entry, where)
    reach = None
    params = (doc or {}).get("params")
    if isinstance(params, dict):
        try:
            reach = float(params["L1_mm"]) + float(params["L2_mm"])
        except (KeyError, TypeError, ValueError):
            reach = None
    below = entry.get("sheet_below", True) is not False
    if "T_flange_camera" in entry:
        read_pose(r, entry["T_flange_camera"], f"{where}.T_flange_camera", reach_mm=reach,
                  sheet_below=below)
        read_std(r, entry.get("T_flange_camera_std"), f"{where}.T_flange_camera_std")
        if doc is not None:
            read_covariance(r, r.get(doc, "covariance", ""), "covariance")
    elif "T_robot_camera" in entry:
        read_pose(r, entry["T_robot_camera"], f"{where}.T_robot_camera", reach_mm=reach,
                  sheet_below=below)
        read_std(r, entry.get("T_robot_camera_std"), f"{where}.T_robot_camera_std")
        if entry.get("covariance") is not None:
            read_covariance(r, entry["covariance"], f"{where}.covariance", n=7)
        r2s = entry.get("robot_to_sheet")
        if isinstance(r2s, dict) and r2s.get("sheet_matrix") is not None:
            M = _matrix(r, r2s["sheet_matrix"], f"{where}.robot_to_sheet.sheet_matrix", (2, 2))
            det = float(np.linalg.det(M))
            if not 0.25 < det < 2.25:
                r.fail(f"{where}.robot_to_sheet.sheet_matrix",
                       f"expected a sheet scaled by less than 50 %, got determinant {det:.4g}")
    for key in ("f_px_std",):
        if entry.get(key) is not None:
            r.number(entry[key], f"{where}.{key}", lo=0.0, hi=MAX_K_PX, what="std in pixels")


def check_cameras(doc: dict, file: str) -> None:
    """Every ``cameras[]`` entry of a calibration document (none: nothing to check)."""
    cams = doc.get("cameras") if isinstance(doc, dict) else None
    if cams is None:
        return
    r = FieldReader(file)
    for i, e in enumerate(r.list_(cams, "cameras")):
        check_camera_entry(e, f"cameras[{i}]", file, doc=doc)
