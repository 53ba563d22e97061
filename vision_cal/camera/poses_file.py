"""The pose-pairs file of ``vision-cal handeye --poses`` (JSON, or CSV), read and checked.

JSON (the contract's "Pose pairs from other tools", with vision-cal's added fields;
docs/format.md, schema ``vision_cal/schema/poses.schema.json``)::

    {"format": "vision-cal/poses/1", "mount": "arm", "units": "mm", "target_z_mm": 0.0,
     "pairs": [ {"id": "p00", "T_robot_flange": [[...4x4...]], "T_camera_target": [[...]]},
                {"id": "p01", "flange_pose": [x, y, z, yaw_deg],
                 "target_rvec": [rx, ry, rz], "target_tvec": [tx, ty, tz]} ]}

CSV: ``id,x,y,z,yaw_deg,rvec_x,rvec_y,rvec_z,tvec_x,tvec_y,tvec_z`` (``id`` optional), one
pair a row. Lengths in ``units`` (``mm``, ``cm``, ``in`` or ``m``; the command's
``--units`` for a CSV); ``rvec`` is OpenCV's (radians, Rodrigues). Every bad field is one
line naming the file and the field (or line and column); a target height beyond what a
workcell holds (``HandeyeConfig.max_robot_mm``) too. The yaw and rotation vector numbers
are kept as written (:class:`~vision_cal.camera.pose_pairs.PosePair`), so that the fit's
checks can try the readings a tool may have meant (degrees for radians, and back).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from vision_cal.camera.pose_pairs import MOUNTS, PosePair, flange_tilt_deg
from vision_cal.config import DEFAULT
from vision_cal.dataset.csvio import number_field, read_rows
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import read_json
from vision_cal.errors import VisionCalError

FORMAT = "vision-cal/poses/1"
UNITS = {"mm": 1.0, "cm": 10.0, "in": 25.4, "m": 1000.0}
CSV_FIELDS = ("x", "y", "z", "yaw_deg", "rvec_x", "rvec_y", "rvec_z", "tvec_x", "tvec_y",
              "tvec_z")
#: a SCARA's flange turns about the vertical only: a reported tilt beyond this (deg) is
#: not a SCARA's pose (a 6-axis tool's, or rows and columns swapped)
MAX_FLANGE_TILT_DEG = 2.0
#: a rotation matrix off orthonormal by more than this (max |R^T R - I|) is not one
ROTATION_TOL = 1e-3
#: a camera nearer its target than this (mm) cannot focus on it: the lengths are in metres
MIN_CAMERA_DISTANCE_MM = 5.0


@dataclass(frozen=True)
class PosesFile:
    """What the file says: the pairs (mm), the mount, the target's height (or None)."""

    path: Path
    pairs: tuple[PosePair, ...]
    mount: str
    units: str
    target_z_mm: float | None


def _matrix(r: FieldReader, v, where: str, scale: float) -> np.ndarray:
    rows = r.list_(v, where)
    if len(rows) != 4:
        r.fail(where, f"expected a 4x4 matrix, got {len(rows)} rows")
    T = np.array([r.vector(row, f"{where}[{i}]", 4) for i, row in enumerate(rows)])
    if not np.allclose(T[3], [0, 0, 0, 1], atol=1e-9):
        r.fail(f"{where}[3]", f"expected [0, 0, 0, 1], got {T[3].tolist()}")
    _check_rotation(r, T[:3, :3], where)
    T[:3, 3] *= scale
    return T


def _check_rotation(r: FieldReader, R: np.ndarray, where: str) -> None:
    off = float(np.abs(R.T @ R - np.eye(3)).max())
    if off > ROTATION_TOL or np.linalg.det(R) < 0:
        r.fail(where, f"the 3x3 part is not a rotation (R^T R - I up to {off:.3g}, det "
                      f"{np.linalg.det(R):.3f}): a scaled or mirrored frame?")


def _T(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _flange(x, y, z, yaw_deg, scale) -> np.ndarray:
    a = math.radians(yaw_deg)
    return _T([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]],
              np.array([x, y, z]) * scale)


def _target(rvec, tvec, scale) -> np.ndarray:
    return _T(Rotation.from_rotvec(np.asarray(rvec, float)).as_matrix(),
              np.asarray(tvec, float) * scale)


def _units(r: FieldReader, given: str | None, option: str | None, where: str) -> str:
    if given is not None and given not in UNITS:
        r.fail(where, f"expected one of {', '.join(UNITS)}, got {given!r}")
    if option is not None and given is not None and option != given:
        r.fail(where, f"the file says {given!r} and --units says {option!r}")
    return option or given or "mm"


def read_poses(path, *, units: str | None = None, mount: str | None = None,
               target_z_mm: float | None = None) -> PosesFile:
    """The pairs of ``path`` (JSON, or CSV by its ``.csv`` name) in mm; ``units``,
    ``mount``, ``target_z_mm``: the command's options (None: the file's, else ``mm``,
    ``arm``, unknown); an option that contradicts the file is refused naming the field."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        pf = _read_csv(path, units or "mm", mount or "arm", target_z_mm)
    else:
        pf = _read_json(path, units, mount, target_z_mm)
    _check_distances(pf)
    _check_height(pf, given=target_z_mm is not None)
    return pf


def _check_height(pf: PosesFile, *, given: bool) -> None:
    """A target height no workcell has (beyond ``max_robot_mm`` of the frame's origin)
    refused, naming the option or the field it came from."""
    z, limit = pf.target_z_mm, DEFAULT.handeye.max_robot_mm
    if z is not None and not abs(z) <= limit:
        raise VisionCalError(f"the target's height {z:g} mm: expected within {limit:g} mm of "
                             f"the {'robot' if pf.mount == 'arm' else 'flange'} frame's origin "
                             "(millimetres; in micrometres or a typo?)",
                             file=None if given else str(pf.path),
                             field="--z-mm" if given else "target_z_mm")


def _read_json(path: Path, units, mount, target_z_mm) -> PosesFile:
    raw = read_json(path, what="poses file")
    r = FieldReader(str(path))
    fmt = r.get(raw, "format", "")
    if fmt != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {fmt!r}")
    u = _units(r, raw.get("units"), units, "units")
    scale = UNITS[u]
    m = raw.get("mount")
    if m is not None and m not in MOUNTS:
        r.fail("mount", f"expected one of {', '.join(MOUNTS)}, got {m!r}")
    if mount is not None and m is not None and mount != m:
        r.fail("mount", f"the file says {m!r} and --mount says {mount!r}")
    m = mount or m or "arm"
    z = raw.get("target_z_mm")
    if z is not None:
        z = r.number(z, "target_z_mm")
    if target_z_mm is not None:
        if z is not None and abs(z - target_z_mm) > 1e-9:
            r.fail("target_z_mm", f"the file says {z:g} and --z-mm says {target_z_mm:g}")
        z = float(target_z_mm)
    pairs, seen = [], set()
    for i, p in enumerate(r.list_(r.get(raw, "pairs", ""), "pairs", nonempty=True)):
        w = f"pairs[{i}]"
        if not isinstance(p, dict):
            r.fail(w, f"expected an object, got {type(p).__name__}")
        pid = r.string(p["id"], f"{w}.id") if "id" in p else str(i)
        if pid in seen:
            r.fail(f"{w}.id", f"duplicate pair id {pid!r}")
        seen.add(pid)
        raw_yaw, raw_rvec = None, None
        if "T_robot_flange" in p:
            A = _matrix(r, p["T_robot_flange"], f"{w}.T_robot_flange", scale)
            where_a = f"{w}.T_robot_flange"
        elif "flange_pose" in p:
            x, y, zz, yaw = r.vector(p["flange_pose"], f"{w}.flange_pose", 4)
            A = _flange(x, y, zz, yaw, scale)
            where_a = f"{w}.flange_pose"
            raw_yaw = float(yaw)
        else:
            r.fail(w, "missing T_robot_flange (4x4) or flange_pose [x, y, z, yaw_deg]")
        if "T_camera_target" in p:
            B = _matrix(r, p["T_camera_target"], f"{w}.T_camera_target", scale)
        elif "target_rvec" in p or "target_tvec" in p:
            rv = r.vector(r.get(p, "target_rvec", w), f"{w}.target_rvec", 3)
            tv = r.vector(r.get(p, "target_tvec", w), f"{w}.target_tvec", 3)
            B = _target(rv, tv, scale)
            raw_rvec = tuple(float(v) for v in rv)
        else:
            r.fail(w, "missing T_camera_target (4x4) or target_rvec and target_tvec")
        tilt = flange_tilt_deg(A)
        if tilt > MAX_FLANGE_TILT_DEG:
            r.fail(where_a, f"the flange is tilted {tilt:.1f} deg from the vertical: a SCARA's "
                            "flange turns about z only (a 6-axis robot's pose, or T_A_B "
                            "transposed?)")
        pairs.append(PosePair(pid, A, B, raw_yaw, raw_rvec))
    return PosesFile(path, tuple(pairs), m, u, z)


def _read_csv(path: Path, units: str, mount: str, target_z_mm) -> PosesFile:
    if units not in UNITS:
        raise VisionCalError(f"expected one of {', '.join(UNITS)}, got {units!r}",
                             field="--units")
    scale = UNITS[units]
    pairs, seen = [], set()
    for line, row in read_rows(path, CSV_FIELDS, what="poses file"):
        pid = row.get("id") or str(len(pairs))
        if pid in seen:
            raise VisionCalError(f"duplicate id {pid!r}", file=str(path),
                                 field=f"line {line}: id")
        seen.add(pid)
        v = {k: number_field(row[k], path, line, k) for k in CSV_FIELDS}
        A = _flange(v["x"], v["y"], v["z"], v["yaw_deg"], scale)
        rv = (v["rvec_x"], v["rvec_y"], v["rvec_z"])
        B = _target(rv, [v["tvec_x"], v["tvec_y"], v["tvec_z"]], scale)
        pairs.append(PosePair(pid, A, B, v["yaw_deg"], rv))
    if not pairs:
        raise VisionCalError("no pairs", file=str(path))
    return PosesFile(path, tuple(pairs), mount, units, target_z_mm)


def _check_distances(pf: PosesFile) -> None:
    """A camera closer to its target than any can focus: the lengths in metres (both, or
    the target's only when the flange's look like millimetres, reaching as a SCARA does)."""
    d = np.array([np.linalg.norm(p.T_camera_target[:3, 3]) for p in pf.pairs])
    if float(np.median(d)) >= MIN_CAMERA_DISTANCE_MM:
        return
    reach = max(float(np.hypot(*p.T_robot_flange[:2, 3])) for p in pf.pairs)
    mixed = reach >= DEFAULT.handeye.min_reach_mm
    raise VisionCalError(
        f"the camera is {float(np.median(d)):.3g} {pf.units} from the target (median over "
        "the pairs): " + (f"T_camera_target in metres while T_robot_flange (reaching "
                          f"{reach:.0f} {pf.units}) is not? Give both in one unit"
                          if mixed else "the lengths are in metres? (--units m)"),
        file=str(pf.path), field="units")
