"""The action of ``vision-cal locate``: where a pixel of a still camera is, in robot and
sheet mm."""

from __future__ import annotations

import csv
import io
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vision_cal.actions.console import error, say, warn
from vision_cal.camera import handeye_locate as flange
from vision_cal.camera import handeye_valid
from vision_cal.camera.arm import camera_for
from vision_cal.camera.fixed import locate
from vision_cal.dataset.calibration import load_calibration_or_camera
from vision_cal.dataset.covariance import load_covariance
from vision_cal.dataset.csvio import number_field, read_rows
from vision_cal.dataset.io import atomic_write_text
from vision_cal.dataset.out_folder import output_file_of_kind, replacing_files
from vision_cal.dataset.robot import load_robot_file
from vision_cal.dataset.valid_for import check as check_valid_for
from vision_cal.dataset.valid_for import enforce as enforce_valid_for
from vision_cal.dataset.valid_for import of as valid_for_of
from vision_cal.dataset.valid_for import per_item as outside_per_item
from vision_cal.errors import EXIT_PARTIAL, VisionCalError
from vision_cal.model.motion import JOINT4_LIMITS_DEG, JOINT_LIMITS_DEG
from vision_cal.plan.compensate import plan_targets
from vision_cal.plan.extrapolation import beyond_deg, std_limit_mm
from vision_cal.plan.uncertainty import predicted_std_mm



#: the columns PIXELS.csv must have (z_mm optional)
CSV_IN = ("id", "u_px", "v_px")


def _read_pixels(path, z_default: float):
    """(ids, pixels, heights, line numbers) of PIXELS.csv, every cell checked."""
    ids, uv, z, lines = [], [], [], []
    for i, (line, row) in enumerate(read_rows(path, CSV_IN, what="pixels CSV")):
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
    # a camera on a six-axis arm's flange (vision-cal handeye PHOTOS/ --mount arm)
    flange_pose: tuple[float, ...] | None = None   # x y z (mm) qx qy qz qw
    robot_poses: str | None = None   # per-photo pose files or a CSV, as handeye reads them
    plane: str | None = None         # board (default) | robot


@dataclass(frozen=True)
class LocateOutcome:
    """What was located, for the console: one pixel (``point``, its ``joint`` command or
    None), or a CSV of them (its text for stdout, or the file written); and the warnings
    (``--force``: beyond ``valid_for``)."""

    warnings: tuple[str, ...] = ()
    point: object = None          # camera.fixed's located point (one --pixel)
    joint: object = None          # its joint command (with --robot), else None
    flange: str | None = None     # a six-axis arm's camera: the flange pose's source
    camera: int = 0
    elbow: int = 1
    csv_text: str | None = None   # --csv without -o: the table for stdout
    path: Path | None = None      # --csv -o: the file written
    n: int = 0                    # pixels located
    not_located: tuple[str, ...] = ()   # outside valid_for: the pixels' lines (why, cover)
    error: str | None = None      # nothing located (exit 1)

    @property
    def exit_code(self) -> int:
        return 1 if self.error else EXIT_PARTIAL if self.not_located else 0

    def lines(self) -> list[str]:
        """``vision-cal locate --pixel``: the pixel in the robot and sheet frames, and the
        joint command that reaches it (with --robot)."""
        p, j = self.point, self.joint
        if self.flange:   # a camera on any arm's flange (issue 40)
            return [f"pixel {p.pixel[0]:g} {p.pixel[1]:g} at z {p.z_mm:g} mm (camera "
                    f"{self.camera}, flange pose {self.flange})",
                    f"  robot frame: x {p.robot_mm[0]:.4f} y {p.robot_mm[1]:.4f} z "
                    f"{p.robot_mm[2]:.4f} mm  (std {p.robot_std_mm[0]:.4f} "
                    f"{p.robot_std_mm[1]:.4f} {p.robot_std_mm[2]:.4f} mm)",
                    f"  board frame: x {p.sheet_mm[0]:.4f} y {p.sheet_mm[1]:.4f} z "
                    f"{p.sheet_mm[2]:.4f} mm"]
        lines = [f"pixel {p.pixel[0]:g} {p.pixel[1]:g} at z {p.z_mm:g} mm (camera "
                 f"{self.camera})",
                 f"  robot frame: x {p.robot_mm[0]:.4f} y {p.robot_mm[1]:.4f} z "
                 f"{p.robot_mm[2]:.4f} mm  (std {p.robot_std_mm[0]:.4f} "
                 f"{p.robot_std_mm[1]:.4f} mm)",
                 f"  sheet frame: x {p.sheet_mm[0]:.4f} y {p.sheet_mm[1]:.4f} mm"]
        if j is not None:
            lines.append(f"  joint command (compensated, elbow {self.elbow:+d}): q1 "
                         f"{j.q_deg[0]:.4f} q2 {j.q_deg[1]:.4f} deg, approach "
                         f"{j.approach[0]:+d} {j.approach[1]:+d}"
                         if j.status == "ok" else f"  joint command: none ({j.reason})")
        return lines

    def show(self, quiet: bool = False) -> int:
        for w in self.warnings:   # --force: the extrapolation (also in the CSV); not located
            warn(w)
        if self.error:
            error(self.error)
        elif self.point is not None:   # one pixel: the answer itself, even when quiet
            say(self.lines())
        elif self.csv_text is not None:
            sys.stdout.write(self.csv_text)
        elif not quiet:
            print(f"located {self.n} pixels -> {self.path}")
        return self.exit_code


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
    # a hand-eye's calibration holds a camera alone (no robot model: issue 40)
    model, doc = load_calibration_or_camera(req.calibration)
    if flange.is_flange_camera(doc, req.camera):
        return _locate_on_flange(req, doc)
    _refuse_flange_options(req)
    if model is None and req.robot:
        raise VisionCalError("this calibration holds a camera alone (a hand-eye's), no robot "
                             "model to plan joints with", file=req.calibration, field="--robot")
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
    outside = _outside_valid_for(req, doc, ids, z, joints, model)
    whole, items = outside_per_item(outside)
    what = "--csv" if req.csv else "--pixel"
    # said: --force, the extrapolation, for the console (and in the CSV); without it a
    # whole request outside is refused, each pixel outside is not located (why, and what
    # would cover it, in its row)
    said = enforce_valid_for(outside if req.force else whole, file=str(req.calibration),
                             force=req.force, what=what)
    if "--joints" in items:   # the arm's command is every pixel's
        items = {i: items["--joints"] + items.get(i, []) for i in ids}
    why = {} if req.force else {i: " | ".join(items[i]) for i in ids if i in items}
    if why and len(why) == len(ids):
        return LocateOutcome(tuple(said), not_located=tuple(why.values()), error=(
            f"{what}: nothing located: {next(iter(why.values()))}"
            + (f" (and {len(why) - 1} more: see the status column)" if len(why) > 1 else "")))
    said = list(said) + ([f"{req.csv}: {len(why)} of {len(ids)} pixel(s) outside what "
                          f"{req.calibration} was calibrated for (valid_for) not located: "
                          f"{', '.join(list(why)[:3])}{' ...' if len(why) > 3 else ''} "
                          "(why, and what would cover each: the status and reason "
                          "columns; --force locates them, the extrapolation stated)"]
                         if why else [])
    if req.csv:
        flagged: dict = {}
        for o in outside:
            for i in o.ids:
                flagged[i] = (flagged.get(i, "") + " " + o.field).strip()
        text = _csv_text(req, ids, points, joints, flagged if req.force and outside else None,
                         why)
        if req.out:   # the output set's one owner: an earlier file to previous/
            with replacing_files([("-o", req.out)], command="locate", quiet=req.quiet,
                                 inputs=[("CALIBRATION.json", req.calibration),
                                         ("--csv", req.csv), ("--robot", req.robot)]):
                path = atomic_write_text(req.out, text)
            return LocateOutcome(tuple(said), path=path, n=len(points) - len(why),
                                 not_located=tuple(why.values()))
        return LocateOutcome(tuple(said), csv_text=text, n=len(points) - len(why),
                             not_located=tuple(why.values()))
    return LocateOutcome(tuple(said), point=points[0], joint=joints[0], camera=req.camera,
                         elbow=req.elbow, n=1)


def _refuse_flange_options(req: LocateRequest) -> None:
    """A flange pose or plane given for a camera that is not on any arm's flange."""
    given = [o for o, v in (("--flange-pose", req.flange_pose),
                            ("--robot-poses", req.robot_poses), ("--plane", req.plane)) if v]
    if given:
        raise VisionCalError(f"camera {req.camera} is not on a six-axis arm's flange (a "
                             "camera of vision-cal handeye PHOTOS/ --robot-poses POSES --mount "
                             "arm): a still camera needs no flange pose, a SCARA's camera "
                             "takes --joints or --photo", file=req.calibration, field=given[0])


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


def _outside_valid_for(req: LocateRequest, doc: dict, ids, z, joints, model) -> list:
    """What of the request lies outside calibration.json ``valid_for``
    (:func:`vision_cal.dataset.valid_for.check`): heights the camera cannot locate at, the
    arm's ``--joints`` beyond the poses' range or side, joint commands (``--robot``) beyond
    the joints the calibration covered; beyond the joints only where the model's std there
    grows beyond what keeps its stated error (: ``plan/extrapolation.std_limit_mm``)."""
    vf = valid_for_of(doc, file=str(req.calibration))
    cal = str(req.calibration)
    out = check_valid_for(vf, cal=cal, ids=ids, heights_mm=z, camera=req.camera)
    # a camera-only calibration (hand-eye of any arm) has no robot model to extrapolate
    limit = std_limit_mm(model, doc, file=cal) if model is not None else None
    cov = load_covariance(doc, model, file=cal) if limit is not None else None   # it read

    def std(q, a):
        return None if cov is None else list(predicted_std_mm(model, cov, q, a))

    if req.joints is not None:
        q = list(req.joints)
        out += check_valid_for(vf, cal=cal, ids=["--joints"], joints_deg=[q[:2]],
                               approach=[(1, 1)],
                               joint4_deg=[q[2]] if len(q) == 3 else None,
                               std_mm=std([q[:2]], [(1, 1)]), std_limit_mm=limit,
                               beyond_deg=beyond_deg(doc))
    ok = [(i, j) for i, j in zip(ids, joints) if j is not None and j.status == "ok"]
    if ok:
        qs, ap = [j.q_deg for _, j in ok], [j.approach for _, j in ok]
        out += check_valid_for(vf, cal=cal, ids=[i for i, _ in ok], joints_deg=qs,
                               approach=ap, std_mm=std(qs, ap), std_limit_mm=limit,
                               beyond_deg=beyond_deg(doc))
    return out


def _csv_text(req: LocateRequest, ids, points, joints, flagged=None, why=None) -> str:
    """The located pixels' CSV; ``why``: id -> why a pixel outside ``valid_for`` was not
    located (its row's ``status`` "outside valid_for" and ``reason``, its numbers empty);
    ``flagged`` (``--force``): id -> the fields each row lies outside."""
    why = why or {}
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    head = ["id", "u_px", "v_px", "z_mm", "x_mm", "y_mm", "x_std_mm", "y_std_mm",
            "sheet_x_mm", "sheet_y_mm"]
    if req.robot:
        head += ["q1_deg", "q2_deg", "approach1", "approach2"]
    head += ["status", "reason"]
    if flagged is not None:   # written with --force: what lies outside valid_for
        head += ["outside_valid_for"]
    wr.writerow(head)
    for i, p, j in zip(ids, points, joints):
        row = _cells(i, p)
        status, reason = "ok", ""
        if j is not None:
            ok = j.status == "ok"
            row += ([f"{j.q_deg[0]:.5f}", f"{j.q_deg[1]:.5f}"] if ok else ["", ""]) + \
                   [j.approach[0], j.approach[1]]
            status, reason = j.status, j.reason
        wr.writerow(_finished(row, i, status, reason, why, flagged, len(row)))
    return buf.getvalue()


def _cells(i, p) -> list:
    """A located point's first cells: id, pixel, height, robot x y and their std, sheet."""
    return [i, f"{p.pixel[0]:.4f}", f"{p.pixel[1]:.4f}", f"{p.z_mm:g}",
            f"{p.robot_mm[0]:.5f}", f"{p.robot_mm[1]:.5f}", f"{p.robot_std_mm[0]:.5f}",
            f"{p.robot_std_mm[1]:.5f}", f"{p.sheet_mm[0]:.5f}", f"{p.sheet_mm[1]:.5f}"]


def _finished(row, i, status, reason, why, flagged, numbers: int) -> list:
    """``row`` with its status, reason (and ``outside_valid_for``); a pixel not located
    (``why``) keeps its pixel and height, its first ``numbers`` cells' results emptied."""
    if i in why:   # not located: no number that could be taken for a result
        row = row[:4] + [""] * (numbers - 4) + row[numbers:]
        status, reason = "outside valid_for", why[i]
    row = row + [status, reason]
    if flagged is not None:
        row.append(flagged.get(i, ""))
    return row


# --------------------------------------------------------------------------- a six-axis arm

def _flange_rows(req: LocateRequest, doc: dict):
    """(ids, pixels, heights, lines, poses) of the request for a camera on a six-axis arm's
    flange: each pixel's flange pose from --flange-pose, --photo (one of the calibration's
    photos, or of --robot-poses) or the CSV's ``photo`` column."""
    cal = str(req.calibration)
    own = flange.own_poses(doc)
    table, what, units = own, f"{cal} (its photos)", "mm"
    if req.robot_poses:
        table, units = flange.poses_from_file(req.robot_poses)
        what = str(req.robot_poses)
    single = None
    if req.flange_pose is not None:
        if req.photo is not None:
            raise VisionCalError("give either --flange-pose or --photo", field="--photo")
        single = flange.pose_of(req.flange_pose, joints=req.joints)
    elif req.photo is not None:
        if req.joints is not None:
            raise VisionCalError("--joints goes with --flange-pose: --photo's pose has its "
                                 "own joints (joints_deg of its pose file, or of the "
                                 "calibration's photo)", field="--joints")
        single = flange.find_pose(req.photo, table, what=what, file=req.robot_poses,
                                  field="--photo")
    elif req.joints is not None:
        raise VisionCalError("--joints goes with --flange-pose (the arm's joints at that "
                             "pose): a six-axis arm's camera needs the flange pose",
                             field="--joints")
    if req.csv:
        ids, uv, z, lines = _read_pixels(req.csv, req.z_mm)
        names = {line: (row.get("photo") or "").strip()
                 for line, row in read_rows(req.csv, CSV_IN, what="pixels CSV")}
    else:
        ids, uv, z, lines, names = ["pixel"], [req.pixel], [req.z_mm], [None], {}
    poses = []
    for line in lines:
        name = names.get(line, "")
        if name:
            poses.append(flange.find_pose(name, table, what=what,
                                          file=req.robot_poses or req.csv,
                                          field=f"line {line}: photo"))
        elif single is not None:
            poses.append(single)
        else:
            raise VisionCalError("a camera on the arm: give the flange pose the photo was "
                                 "taken at, --flange-pose X Y Z QX QY QZ QW (mm), --photo NAME "
                                 "(one of the calibration's photos, or of --robot-poses) or a "
                                 "photo column in --csv", file=req.csv if line else None,
                                 field="--flange-pose" if line is None else f"line {line}")
    ref = [p.T for p in own.values()]
    if req.flange_pose is not None:
        flange.check_units([single], np.array(ref), read_as="mm", file=None,
                           field="--flange-pose")
    if req.robot_poses:
        flange.check_units(list(table.values()), np.array(ref), read_as=units,
                           file=req.robot_poses, field="--robot-poses")
    return ids, uv, z, lines, poses


def _locate_on_flange(req: LocateRequest, doc: dict) -> LocateOutcome:
    """Pixels of a camera on a six-axis arm's flange located (``camera/handeye_locate``),
    each at its flange pose, checked against ``valid_for.flange_poses``."""
    if req.robot:
        raise VisionCalError("this calibration holds a camera alone (a hand-eye's), no robot "
                             "model to plan joints with", file=req.calibration, field="--robot")
    cam = flange.flange_camera_of(doc, req.camera, file=req.calibration)
    plane = req.plane or "board"
    ids, uv, z, lines, poses = _flange_rows(req, doc)
    w, h = cam.size_px
    for i, (u, v), line in zip(ids, uv, lines):
        if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5):
            raise VisionCalError(f"pixel {u:g} {v:g} ({i}) is outside the camera's {w}x{h} "
                                 "image", file=req.csv if line else None,
                                 field="--pixel" if line is None else f"line {line}: u_px, v_px")
    points = []
    for (u, v), zz, p, line in zip(uv, z, poses, lines):
        try:
            points.append(flange.locate_at(cam, p.T, [(u, v)], zz, plane=plane,
                                           joints=p.joints)[0])
        except VisionCalError as e:
            raise VisionCalError(e.reason, file=req.csv if line else None,
                                 field=("--z-mm" if line is None else f"line {line}: z_mm")
                                 ) from e
    cal = str(req.calibration)
    outside = handeye_valid.check(handeye_valid.read(doc, file=cal), cal=cal, ids=ids,
                                  poses=[p.T for p in poses], joints=[p.joints for p in poses])
    _, items = outside_per_item(outside)
    what = "--csv" if req.csv else "--pixel"
    said = [] if not req.force else [
        f"{what}: outside valid_for of {cal} (located because of --force): {o.line()}"
        for o in outside]
    why = {} if req.force else {i: " | ".join(items[i]) for i in ids if i in items}
    if why and len(why) == len(ids):
        return LocateOutcome(tuple(said), not_located=tuple(why.values()), error=(
            f"{what}: nothing located: {next(iter(why.values()))}"
            + (f" (and {len(why) - 1} more: see the status column)" if len(why) > 1 else "")))
    if why:
        said.append(f"{req.csv}: {len(why)} of {len(ids)} pixel(s) at flange poses outside "
                    f"what {cal} was calibrated for (valid_for) not located: "
                    f"{', '.join(list(why)[:3])}{' ...' if len(why) > 3 else ''} (the status "
                    "and reason columns; --force locates them, the extrapolation stated)")
    if not req.csv:
        return LocateOutcome(tuple(said), point=points[0], camera=req.camera,
                             flange=poses[0].source, n=1)
    flagged = {i: handeye_valid.FIELD for o in outside for i in o.ids} if req.force else None
    text = _flange_csv_text(ids, points, poses, plane, flagged, why)
    if req.out:
        with replacing_files([("-o", req.out)], command="locate", quiet=req.quiet,
                             inputs=[("CALIBRATION.json", req.calibration), ("--csv", req.csv),
                                     ("--robot-poses", req.robot_poses)]):
            path = atomic_write_text(req.out, text)
        return LocateOutcome(tuple(said), path=path, n=len(points) - len(why),
                             not_located=tuple(why.values()))
    return LocateOutcome(tuple(said), csv_text=text, n=len(points) - len(why),
                         not_located=tuple(why.values()))



def _flange_csv_text(ids, points, poses, plane, flagged, why) -> str:
    """The located pixels' CSV of a six-axis arm's camera: the still camera's columns (the
    board's frame as the sheet's), then ``robot_z_mm``, ``z_std_mm``, ``plane`` and
    ``flange_pose`` (where each pixel's flange pose came from)."""
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    head = ["id", "u_px", "v_px", "z_mm", "x_mm", "y_mm", "x_std_mm", "y_std_mm",
            "sheet_x_mm", "sheet_y_mm", "robot_z_mm", "z_std_mm", "plane", "flange_pose",
            "status", "reason"]
    if flagged is not None:
        head.append("outside_valid_for")
    wr.writerow(head)
    for i, p, f in zip(ids, points, poses):
        row = _cells(i, p) + [f"{p.robot_mm[2]:.5f}", f"{p.robot_std_mm[2]:.5f}", plane,
                              f.source]
        wr.writerow(_finished(row, i, "ok", "", why, flagged, 12))
    return buf.getvalue()
