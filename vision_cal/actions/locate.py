"""The action of ``vision-cal locate``: where a pixel of a still camera is, in robot and
sheet mm."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vision_cal.camera.arm import camera_for
from vision_cal.camera.fixed import locate
from vision_cal.dataset.calibration import load_calibration
from vision_cal.dataset.csvio import number_field, read_rows
from vision_cal.dataset.io import atomic_write_text
from vision_cal.dataset.out_folder import output_file_of_kind
from vision_cal.dataset.robot import load_robot_file
from vision_cal.dataset.valid_for import check as check_valid_for
from vision_cal.dataset.valid_for import enforce as enforce_valid_for
from vision_cal.dataset.valid_for import of as valid_for_of
from vision_cal.errors import VisionCalError
from vision_cal.model.motion import JOINT4_LIMITS_DEG, JOINT_LIMITS_DEG
from vision_cal.plan.compensate import plan_targets


#: the columns PIXELS.csv must have (z_mm optional)
CSV_IN = ("id", "u_px", "v_px")


def _read_pixels(path, z_default: float):
    """(ids, pixels, heights, line numbers) of PIXELS.csv, every cell checked."""
    ids, uv, z, lines = [], [], [], []
    for i, (line, row) in enumerate(read_rows(path, CSV_IN)):
        vals = []
        for k in ("u_px", "v_px", "z_mm"):
            v = (row.get(k) or "").strip()
            if k == "z_mm" and not v:
                vals.append(z_default)
                continue
            vals.append(number_field(v, path, line, k))
        ids.append((row.get("id") or "").strip() or f"p{i}")
        uv.append(vals[:2])
        z.append(vals[2])
        lines.append(line)
    if not ids:
        raise VisionCalError("no pixels", file=str(path))
    return ids, uv, z, lines


@dataclass(frozen=True)
class LocateRequest:
    """What ``vision-cal locate`` was asked (its arguments; see ``vision-cal locate --help``)."""

    calibration: str
    quiet: bool = False
    pixel: tuple[float, float] | None = None
    csv: str | None = None
    out: str | None = None
    camera: int = 0
    z_mm: float = 0.0
    robot: str | None = None
    joints: tuple[float, ...] | None = None
    photo: str | None = None
    elbow: int = 1
    force: bool = False   # locate outside valid_for, the extrapolation stated


@dataclass(frozen=True)
class LocateOutcome:
    """What was located, for the console: one pixel (``point``, its ``joint`` command or
    None), or a CSV of them (its text for stdout, or the file written); and the warnings
    (``--force``: beyond ``valid_for``)."""

    warnings: tuple[str, ...] = ()
    point: object = None          # camera.fixed's located point (one --pixel)
    joint: object = None          # its joint command (with --robot), else None
    camera: int = 0
    elbow: int = 1
    csv_text: str | None = None   # --csv without -o: the table for stdout
    path: Path | None = None      # --csv -o: the file written
    n: int = 0                    # pixels located


def locate_pixels(req: LocateRequest) -> LocateOutcome:
    """Pixels of a still camera (or the camera on the arm) located in the robot and sheet
    frames (and the joint commands that reach them, with a robot file); one pixel returned,
    a CSV of them written (or returned for stdout)."""
    if (req.pixel is None) == (req.csv is None):
        raise VisionCalError("give either --pixel U V or --csv PIXELS.csv", field="--pixel")
    if req.out and not req.csv:
        raise VisionCalError("-o needs --csv", field="-o")
    if not np.isfinite(req.z_mm):
        raise VisionCalError("expected a finite height", field="--z-mm")
    if req.out:  # never over an input or a file of another kind (issue 30)
        output_file_of_kind(req.out, "csv", field="-o",
                            inputs=[("CALIBRATION.json", req.calibration), ("--csv", req.csv),
                                    ("--robot", req.robot)])
    model, doc = load_calibration(req.calibration)
    robot = load_robot_file(req.robot) if req.robot else None
    _refuse_joints_beyond_limits(req, doc, robot)
    cam = camera_for(doc, req.camera, joints_deg=req.joints, photo=req.photo,
                     file=req.calibration)
    if req.csv:
        ids, uv, z, lines = _read_pixels(req.csv, req.z_mm)
    else:
        if not np.all(np.isfinite(req.pixel)):
            raise VisionCalError("expected finite pixel coordinates", field="--pixel")
        ids, uv, z, lines = ["pixel"], [req.pixel], [req.z_mm], [None]
    w, h = cam.size_px

    def where(line, column):
        """(file, field) of a pixel's row: the CSV's line, or the option given."""
        if line is None:
            return None, column
        return req.csv, f"line {line}: {column.lstrip('-').replace('pixel', 'u_px, v_px')}"

    for i, (u, v), line in zip(ids, uv, lines):
        if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5):
            f, fld = where(line, "--pixel")
            raise VisionCalError(f"pixel {u:g} {v:g} ({i}) is outside the camera's "
                                 f"{w}x{h} image", file=f, field=fld)
    points = _located(cam, uv, z, lines, where)
    joints = [None] * len(points)
    if robot is not None:
        joints = plan_targets(model, ids, [p.sheet_mm[:2] for p in points], elbow=req.elbow,
                              joint_limits_deg=robot.joint_limits_deg)
    outside = _outside_valid_for(req, doc, ids, z, joints)
    said = enforce_valid_for(outside, file=str(req.calibration), force=req.force,
                             what="--csv" if req.csv else "--pixel")
    # said: --force, the extrapolation, for the console (and in the CSV)
    if req.csv:
        flagged: dict = {}
        for o in outside:
            for i in o.ids:
                flagged[i] = (flagged.get(i, "") + " " + o.field).strip()
        text = _csv_text(req, ids, points, joints, flagged if said else None)
        if req.out:
            return LocateOutcome(tuple(said), path=atomic_write_text(req.out, text),
                                 n=len(points))
        return LocateOutcome(tuple(said), csv_text=text, n=len(points))
    return LocateOutcome(tuple(said), point=points[0], joint=joints[0], camera=req.camera,
                         elbow=req.elbow, n=1)


def _located(cam, uv, z, lines, where) -> list:
    """The pixels located, each at its height: one :func:`locate` call per height (issue 41:
    100,000 pixels of one height in seconds, not one call each); the first pixel whose ray
    misses its plane named by its line (or the option given)."""
    uv, z = np.asarray(uv, float).reshape(-1, 2), np.asarray(z, float)
    points = [None] * len(uv)
    for zz in np.unique(z):
        at = np.flatnonzero(z == zz)
        try:
            for i, p in zip(at, locate(cam, uv[at], float(zz))):
                points[i] = p
        except VisionCalError as e:   # the ray misses the plane: the height's fault
            i = next((i for i in at if not _meets_plane(cam, uv[i], zz)), at[0])
            f, fld = where(lines[i], "--z-mm" if lines[i] is None else "z_mm")
            cam_z = float(cam.T_robot_camera[2, 3])
            raise VisionCalError(f"{e.reason} (the camera is at z {cam_z:.1f} mm in the robot "
                                 f"frame; the height given is {zz:g} mm)", file=f,
                                 field=fld) from e
    return points


def _meets_plane(cam, pixel, z_mm) -> bool:
    try:
        locate(cam, [pixel], float(z_mm))
        return True
    except VisionCalError:
        return False


def _refuse_joints_beyond_limits(req: LocateRequest, doc: dict, robot) -> None:
    """``--joints`` beyond what the robot can be commanded to (the robot file's
    ``joint_limits_deg`` and ``joint4_limits_deg`` with ``--robot``, else the calibration's
    ``joint_limits_deg``, else the defaults): no photo was taken there, so it is refused,
    ``--force`` or not (``valid_for``, the range the poses covered, is the softer check)."""
    if req.joints is None or not np.all(np.isfinite(req.joints)):
        return   # camera_for names a bad --joints
    if robot is not None:
        lims = [*robot.joint_limits_deg, robot.joint4_limits_deg]
        of = f"joint_limits_deg of {req.robot}"
    elif doc.get("joint_limits_deg") is not None:
        lims = [*doc["joint_limits_deg"], JOINT4_LIMITS_DEG]
        of = f"joint_limits_deg of {req.calibration}"
    else:
        lims = [*JOINT_LIMITS_DEG, JOINT4_LIMITS_DEG]
        of = "the default joint limits (give --robot ROBOT.yaml for the robot's own)"
    for k, (q, name) in enumerate(zip(req.joints, ("joint 1", "joint 2", "joint 4"))):
        lo, hi = (float(v) for v in lims[k])
        if not lo <= q <= hi:
            raise VisionCalError(f"{name} at {q:g} deg is beyond {lo:g}..{hi:g} deg ({of}): "
                                 "the robot cannot be commanded there; joints are degrees",
                                 field="--joints")


def _outside_valid_for(req: LocateRequest, doc: dict, ids, z, joints) -> list:
    """What of the request lies outside calibration.json ``valid_for``
    (:func:`vision_cal.dataset.valid_for.check`): heights the camera cannot locate at, the
    arm's ``--joints`` beyond the poses' range or side, joint commands (``--robot``) beyond
    the joints the calibration covered."""
    vf = valid_for_of(doc, file=str(req.calibration))
    cal = str(req.calibration)
    out = check_valid_for(vf, cal=cal, ids=ids, heights_mm=z, camera=req.camera)
    if req.joints is not None:
        q = list(req.joints)
        out += check_valid_for(vf, cal=cal, ids=["--joints"], joints_deg=[q[:2]],
                               approach=[(1, 1)],
                               joint4_deg=[q[2]] if len(q) == 3 else None)
    ok = [(i, j) for i, j in zip(ids, joints) if j is not None and j.status == "ok"]
    if ok:
        out += check_valid_for(vf, cal=cal, ids=[i for i, _ in ok],
                               joints_deg=[j.q_deg for _, j in ok],
                               approach=[j.approach for _, j in ok])
    return out


def _csv_text(req: LocateRequest, ids, points, joints, flagged=None) -> str:
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    head = ["id", "u_px", "v_px", "z_mm", "x_mm", "y_mm", "x_std_mm", "y_std_mm",
            "sheet_x_mm", "sheet_y_mm"]
    if req.robot:
        head += ["q1_deg", "q2_deg", "approach1", "approach2", "status", "reason"]
    if flagged is not None:   # written with --force: what lies outside valid_for
        head += ["outside_valid_for"]
    wr.writerow(head)
    for i, p, j in zip(ids, points, joints):
        row = [i, f"{p.pixel[0]:.4f}", f"{p.pixel[1]:.4f}", f"{p.z_mm:g}",
               f"{p.robot_mm[0]:.5f}", f"{p.robot_mm[1]:.5f}", f"{p.robot_std_mm[0]:.5f}",
               f"{p.robot_std_mm[1]:.5f}", f"{p.sheet_mm[0]:.5f}", f"{p.sheet_mm[1]:.5f}"]
        if j is not None:
            ok = j.status == "ok"
            row += ([f"{j.q_deg[0]:.5f}", f"{j.q_deg[1]:.5f}"] if ok else ["", ""]) + \
                   [j.approach[0], j.approach[1], j.status, j.reason]
        if flagged is not None:
            row.append(flagged.get(i, ""))
        wr.writerow(row)
    return buf.getvalue()
