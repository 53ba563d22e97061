"""The robot's flange pose for each photo (``vision-cal handeye PHOTOS/ --robot-poses POSES``).

Two layouts (docs/format.md, "Photos and the robot's poses"; schema
``vision_cal/schema/robot_pose.schema.json``):

- a folder with one YAML (or JSON) file per photo, named after the photo's stem (``7.yaml``
  for ``7.png``), holding ``x``, ``y``, ``z`` in **metres** and the quaternion ``qx``,
  ``qy``, ``qz``, ``qw`` of ``T_robot_flange``, the layout ROS tools write
  (industrial_calibration's ``poses/N.yaml``); a ROS ``geometry_msgs/Pose`` written out
  (``position: {x, y, z}``, ``orientation: {x, y, z, w}``) is read too;
- a CSV ``photo,x_mm,y_mm,z_mm,qx,qy,qz,qw`` in **millimetres** (``photo`` the photo's
  file name or stem).

Either may add the arm's joints when the photo was taken (``joints_deg: [q1, ..., qN]`` in
a pose file, columns ``q1_deg ... qN_deg`` in the CSV; degrees, every pose the same number):
the flange pose alone does not say which configuration (elbow, wrist flipped) the arm was
in, and the robot's kinematic error is a function of the joints (``handeye_stats``'s
kinematic term, ``valid_for.flange_poses.joints_deg``).

Every value is checked (one line naming the file and the field): a quaternion of norm 1
within ``QUAT_TOL`` (normalised), finite lengths, and the units by plausibility: an arm's
flange lies within ``MAX_REACH_MM`` of its base and its poses spread over more than
``MIN_SPREAD_MM``; a folder whose lengths read as metres put the flange kilometres away is
in millimetres, a CSV whose poses spread over less than a few millimetres is in metres
(the refusal names the likely unit). The poses' units and conventions are checked again
against what the camera saw (:mod:`vision_cal.camera.handeye`: the robot's motion against
the board's, in scale and in rotation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from vision_cal.dataset.csvio import number_field, read_rows
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import read_json, read_yaml
from vision_cal.dataset.photos import natural_key
from vision_cal.errors import VisionCalError

CSV_FIELDS = ("photo", "x_mm", "y_mm", "z_mm", "qx", "qy", "qz", "qw")
POSE_SUFFIXES = (".yaml", ".yml", ".json")
#: a quaternion's norm within this of 1 (written with 6+ digits); normalised when read
QUAT_TOL = 1e-3
#: the largest arm reaches 4 m: a flange farther than this (mm) is in other units
MAX_REACH_MM = 10000.0
#: an arm moves its flange by more than this (mm) over a hand-eye session
MIN_SPREAD_MM = 5.0
#: the unit lengths were really in, by the factor that turns the values read into mm
#: (``mm`` read: 1000 for metres, 25.4 inches, 10 centimetres; ``m`` read: 0.001 mm)
LIKELY_UNITS = {"mm": ((1000.0, "metres"), (25.4, "inches"), (10.0, "centimetres"),
                       (0.001, "micrometres")),
                "m": ((0.001, "millimetres"), (0.0254, "inches"), (0.01, "centimetres"),
                      (1000.0, "kilometres"))}


@dataclass(frozen=True)
class RobotPose:
    """One photo's flange pose: the photo's stem, where it was read from (file, or file and
    line), the translation (mm) and the quaternion (qx, qy, qz, qw) as read (normalised)."""

    stem: str
    source: str
    t_mm: np.ndarray
    quat_xyzw: np.ndarray
    joints_deg: np.ndarray | None = None   # the arm's joints, when the source gives them

    @property
    def T(self) -> np.ndarray:
        """T_robot_flange (4, 4, mm)."""
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat(self.quat_xyzw).as_matrix()
        T[:3, 3] = self.t_mm
        return T

    def T_read_as(self, convention: str) -> np.ndarray:
        """The pose under another reading (to name a convention mistake): ``wxyz`` (the
        four numbers taken as qw qx qy qz) or ``inverse`` (the file holds T_flange_robot)."""
        if convention == "wxyz":
            q = self.quat_xyzw
            T = np.eye(4)
            T[:3, :3] = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()
            T[:3, 3] = self.t_mm
            return T
        if convention == "inverse":
            return np.linalg.inv(self.T)
        return self.T


def _quaternion(r: FieldReader, q, where: str) -> np.ndarray:
    q = np.asarray(q, float)
    n = float(np.linalg.norm(q))
    if abs(n - 1.0) > QUAT_TOL:
        r.fail(where, f"not a unit quaternion (norm {n:.6g}): expected qx qy qz qw of a "
                      "rotation")
    return q / n


def _read_pose_file(path: Path, stem: str) -> RobotPose:
    raw = read_json(path, what="pose file") if path.suffix == ".json" else \
        read_yaml(path, what="pose file")
    r = FieldReader(str(path))
    if not isinstance(raw, dict):
        r.fail("(top level)", "expected x, y, z (m) and qx, qy, qz, qw")
    if "position" in raw or "orientation" in raw:      # a geometry_msgs/Pose
        pos = r.get(raw, "position", "")
        ori = r.get(raw, "orientation", "")
        t = [r.number(r.get(pos, k, "position"), f"position.{k}") for k in "xyz"]
        q = [r.number(r.get(ori, k, "orientation"), f"orientation.{k}") for k in "xyzw"]
        qwhere = "orientation"
    else:
        t = [r.number(r.get(raw, k, ""), k) for k in "xyz"]
        q = [r.number(r.get(raw, k, ""), k) for k in ("qx", "qy", "qz", "qw")]
        qwhere = "qx, qy, qz, qw"
    t_mm = np.asarray(t, float) * 1000.0
    return RobotPose(stem, str(path), t_mm, _quaternion(r, q, qwhere), _joints(r, raw))


#: the most joints an arm's pose may list (a 7-axis arm on a linear track, and some)
MAX_JOINTS = 12


def _joints(r: FieldReader, raw: dict) -> np.ndarray | None:
    """A pose file's ``joints_deg`` (degrees, finite, within +-720), or None."""
    v = raw.get("joints_deg")
    if v is None:
        return None
    q = r.list_(v, "joints_deg", nonempty=True)
    if len(q) > MAX_JOINTS:
        r.fail("joints_deg", f"expected at most {MAX_JOINTS} joints, got {len(q)}")
    return np.array([r.number(x, f"joints_deg[{k}]", lo=-720.0, hi=720.0, what="angle (deg)")
                     for k, x in enumerate(q)])


def _csv_joints(row: dict, path, line: int, names: list[str]) -> np.ndarray | None:
    if not names:
        return None
    q = [number_field(row.get(k) or "", path, line, k) for k in names]
    bad = [k for k, x in zip(names, q) if abs(x) > 720.0]
    if bad:
        raise VisionCalError("expected a joint in degrees within +-720", file=str(path),
                             field=f"line {line}: {bad[0]}")
    return np.asarray(q, float)


def _check_joints(poses: list[RobotPose], source: str) -> None:
    """Every pose lists the same joints, or none does."""
    n = {None if p.joints_deg is None else len(p.joints_deg) for p in poses}
    if len(n) > 1:
        odd = next(p for p in poses if (p.joints_deg is None) != (poses[0].joints_deg is None)
                   or (p.joints_deg is not None and len(p.joints_deg) != len(
                       poses[0].joints_deg)))
        raise VisionCalError("the poses list different joints (joints_deg): every pose gives "
                             "the arm's joints, or none does", file=odd.source,
                             field="joints_deg")


def _read_folder(folder: Path) -> list[RobotPose]:
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in POSE_SUFFIXES
             and not p.name.startswith(".")]
    stems: dict[str, Path] = {}
    for p in sorted(files, key=lambda p: natural_key(p.name)):
        if p.stem in stems:
            raise VisionCalError(f"two pose files for photo {p.stem!r}: {stems[p.stem].name} "
                                 f"and {p.name}", file=str(folder), field="--robot-poses")
        stems[p.stem] = p
    if not stems:
        raise VisionCalError("no pose files (one per photo: 7.yaml for 7.png, x y z in "
                             "metres and qx qy qz qw)", file=str(folder), field="--robot-poses")
    return [_read_pose_file(p, s) for s, p in stems.items()]


def _read_csv(path: Path) -> list[RobotPose]:
    out, seen = [], {}
    r = FieldReader(str(path))
    rows = read_rows(path, CSV_FIELDS)
    names: list[str] = []
    if rows:    # q1_deg, q2_deg, ... consecutive from q1_deg
        while f"q{len(names) + 1}_deg" in rows[0][1] and len(names) < MAX_JOINTS:
            names.append(f"q{len(names) + 1}_deg")
    for line, row in rows:
        name = (row.get("photo") or "").strip()
        if not name:
            raise VisionCalError("empty photo name", file=str(path), field=f"line {line}: photo")
        stem = Path(name).stem if Path(name).suffix else name
        if stem in seen:
            raise VisionCalError(f"photo {stem!r} again (first on line {seen[stem]})",
                                 file=str(path), field=f"line {line}: photo")
        seen[stem] = line
        v = [number_field(row.get(k) or "", path, line, k) for k in CSV_FIELDS[1:]]
        out.append(RobotPose(stem, f"{path}:{line}", np.asarray(v[:3], float),
                             _quaternion(r, v[3:], f"line {line}: qx, qy, qz, qw"),
                             _csv_joints(row, path, line, names)))
    if not out:
        raise VisionCalError("no poses", file=str(path), field="--robot-poses")
    return out


def likely_unit(factor: float, read_as: str = "mm", tol: float = 0.08) -> str | None:
    """The unit the lengths were really in, when the values (read as ``read_as``: ``mm``
    or ``m``, in mm once read) must be multiplied by about ``factor`` (within ``tol`` of
    one of :data:`LIKELY_UNITS`) to be millimetres; None when no unit explains it."""
    for f, name in LIKELY_UNITS[read_as]:
        if abs(math.log(factor / f)) < tol:
            return name
    return None


def _check_units(poses: list[RobotPose], source: str, metres: bool, *,
                 spread: bool = True) -> None:
    t = np.array([p.t_mm for p in poses])
    far = float(np.linalg.norm(t, axis=1).max())
    moved = float(np.linalg.norm(t - t.mean(axis=0), axis=1).max()) if len(t) > 1 else 0.0
    given = "metres" if metres else "millimetres"
    if far > MAX_REACH_MM:
        hint = ("the file is in millimetres (x y z are metres in a pose file)" if metres
                else "micrometres? the CSV's x_mm y_mm z_mm are millimetres")
        raise VisionCalError(f"read as {given}, the flange lies {far / 1000:.4g} m from the "
                             f"robot's base (no arm reaches beyond {MAX_REACH_MM / 1000:g} m): "
                             f"{hint}", file=source, field="--robot-poses")
    if spread and len(t) > 1 and moved < MIN_SPREAD_MM:
        hint = ("the lengths are in metres (the CSV's x_mm y_mm z_mm are millimetres)"
                if not metres else "the robot hardly moved between photos")
        raise VisionCalError(f"read as {given}, the flange moves by {moved:.3g} mm over all "
                             f"the photos: {hint}", file=source, field="--robot-poses")


def read_robot_poses(path, *, spread: bool = True) -> tuple[list[RobotPose], str]:
    """The poses of a folder of per-photo files or of a CSV, units checked (``spread``
    False: the poses need not spread over the workspace, as a few poses to locate pixels
    at need not); and the unit the source was read in (``m`` for a folder, ``mm`` for a
    CSV)."""
    path = Path(path)
    if not path.exists():
        raise VisionCalError("not found", file=str(path), field="--robot-poses")
    if path.is_dir():
        poses = _read_folder(path)
        _check_units(poses, str(path), metres=True, spread=spread)
        _check_joints(poses, str(path))
        return poses, "m"
    if path.suffix.lower() != ".csv":
        raise VisionCalError("expected a folder of per-photo pose files (7.yaml for 7.png) "
                             "or a CSV photo,x_mm,y_mm,z_mm,qx,qy,qz,qw", file=str(path),
                             field="--robot-poses")
    poses = _read_csv(path)
    _check_units(poses, str(path), metres=False, spread=spread)
    _check_joints(poses, str(path))
    return poses, "mm"


def pair_with_photos(poses: list[RobotPose], photos: list[str], source: str
                     ) -> list[RobotPose]:
    """The pose of each photo (by stem), in the photos' order; a photo without a pose is
    refused (naming it and the file it needs)."""
    by_stem = {p.stem: p for p in poses}
    missing = [ph for ph in photos if Path(ph).stem not in by_stem]
    if missing:
        raise VisionCalError(f"no pose for {len(missing)} photo(s): "
                             + ", ".join(f"{m} (needs {Path(m).stem}.yaml or a CSV row)"
                                         for m in missing[:5])
                             + (", ..." if len(missing) > 5 else ""),
                             file=source, field="--robot-poses")
    return [by_stem[Path(ph).stem] for ph in photos]
