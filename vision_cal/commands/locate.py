"""``vision-cal locate``: where a pixel of a still camera is, in robot and sheet mm."""

from __future__ import annotations

NAME = "locate"
HELP = ("map a pixel of a calibrated camera (calibration.json cameras: still, or on the arm at "
        "given joints) to the robot frame")
EXAMPLES = """\
examples:
  vision-cal locate out/calibration.json --pixel 812.5 433.0
  vision-cal locate out/calibration.json --pixel 812.5 433.0 --z-mm 50 --robot robot.yaml
  vision-cal locate out/calibration.json --csv pixels.csv -o points.csv
  vision-cal locate arm_cal/calibration.json --pixel 320 240 --joints 30 60 45
  vision-cal locate arm_cal/calibration.json --pixel 320 240 --photo pose_003.png

A camera on the arm (vision-cal handeye) needs the arm's command when the photo was taken:
--joints Q1 Q2 [Q4] (deg), or --photo NAME for one of its calibration photos; its std then
holds the robot's repeatability.

--csv reads id,u_px,v_px (and optionally z_mm) and writes id,u_px,v_px,z_mm,x_mm,y_mm,
x_std_mm,y_std_mm,sheet_x_mm,sheet_y_mm (+ q1_deg,q2_deg,status with --robot). The std is
the camera's (its pose, focal length and the robot's base), the pixel taken as exact.
"""

CSV_IN = ("id", "u_px", "v_px")


def add_arguments(p) -> None:
    p.add_argument("calibration", metavar="CALIBRATION.json")
    p.add_argument("--pixel", type=float, nargs=2, metavar=("U", "V"),
                   help="pixel (OpenCV convention: the top-left pixel's centre is 0 0)")
    p.add_argument("--csv", metavar="PIXELS.csv", help="a list: id,u_px,v_px[,z_mm]")
    p.add_argument("-o", "--out", metavar="POINTS.csv", help="with --csv: write here "
                   "(default: print)")
    p.add_argument("--camera", type=int, default=0, metavar="N",
                   help="which of calibration.json's cameras (default 0)")
    p.add_argument("--z-mm", type=float, default=0.0, metavar="H",
                   help="height of the point above the sheet's plane (default 0)")
    p.add_argument("--robot", metavar="ROBOT.yaml", help="robot file: also print the "
                   "compensated joint command (its joint limits)")
    p.add_argument("--joints", type=float, nargs="+", metavar="Q",
                   help="a camera on the arm: the commanded joints Q1 Q2 [Q4] (deg) the photo "
                        "was taken at")
    p.add_argument("--photo", metavar="NAME", help="a camera on the arm: the command of this "
                   "calibration photo (calibration.json poses)")
    p.add_argument("--elbow", type=int, choices=(1, -1), default=1,
                   help="elbow solution of the joint command (default +1)")


def _read_pixels(path, z_default: float):
    import csv
    import io
    import math

    from vision_cal.dataset.io import read_text
    from vision_cal.errors import VisionCalError

    reader = csv.DictReader(io.StringIO(read_text(path)))
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [f for f in CSV_IN if f not in header]
    if missing:
        raise VisionCalError(f"header lacks {', '.join(missing)} (expected id,u_px,v_px"
                             "[,z_mm])", file=str(path), field="line 1")
    reader.fieldnames = header
    ids, uv, z = [], [], []
    for i, row in enumerate(reader):
        line = i + 2
        vals = []
        for k in ("u_px", "v_px", "z_mm"):
            v = (row.get(k) or "").strip()
            if k == "z_mm" and not v:
                vals.append(z_default)
                continue
            try:
                x = float(v)
            except ValueError as e:
                raise VisionCalError(f"expected a number, got {v!r}", file=str(path),
                                     field=f"line {line}: {k}") from e
            if not math.isfinite(x):
                raise VisionCalError(f"expected a finite number, got {v!r}", file=str(path),
                                     field=f"line {line}: {k}")
            vals.append(x)
        ids.append((row.get("id") or "").strip() or f"p{i}")
        uv.append(vals[:2])
        z.append(vals[2])
    if not ids:
        raise VisionCalError("no pixels", file=str(path))
    return ids, uv, z


def run(args) -> int:
    import numpy as np

    from vision_cal.camera.arm import camera_for
    from vision_cal.camera.fixed import locate
    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.errors import VisionCalError

    if (args.pixel is None) == (args.csv is None):
        raise VisionCalError("give either --pixel U V or --csv PIXELS.csv", field="--pixel")
    if args.out and not args.csv:
        raise VisionCalError("-o needs --csv", field="-o")
    if not np.isfinite(args.z_mm):
        raise VisionCalError("expected a finite height", field="--z-mm")
    model, doc = load_calibration(args.calibration)
    cam = camera_for(doc, args.camera, joints_deg=args.joints, photo=args.photo,
                     file=args.calibration)
    if args.csv:
        ids, uv, z = _read_pixels(args.csv, args.z_mm)
    else:
        if not np.all(np.isfinite(args.pixel)):
            raise VisionCalError("expected finite pixel coordinates", field="--pixel")
        ids, uv, z = ["pixel"], [args.pixel], [args.z_mm]
    w, h = cam.size_px
    for i, (u, v) in zip(ids, uv):
        if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5):
            raise VisionCalError(f"pixel {u:g} {v:g} ({i}) is outside the camera's "
                                 f"{w}x{h} image", field="--csv" if args.csv else "--pixel")
    points = [locate(cam, [p], zz)[0] for p, zz in zip(uv, z)]
    joints = [None] * len(points)
    if args.robot:
        from vision_cal.dataset.robot import load_robot_file
        from vision_cal.plan.compensate import plan_targets

        robot = load_robot_file(args.robot)
        joints = plan_targets(model, ids, [p.sheet_mm[:2] for p in points], elbow=args.elbow,
                              joint_limits_deg=robot.joint_limits_deg)
    if args.csv:
        return _write_csv(args, ids, points, joints)
    p, j = points[0], joints[0]
    print(f"pixel {p.pixel[0]:g} {p.pixel[1]:g} at z {p.z_mm:g} mm (camera {args.camera})")
    print(f"  robot frame: x {p.robot_mm[0]:.4f} y {p.robot_mm[1]:.4f} z {p.robot_mm[2]:.4f} mm"
          f"  (std {p.robot_std_mm[0]:.4f} {p.robot_std_mm[1]:.4f} mm)")
    print(f"  sheet frame: x {p.sheet_mm[0]:.4f} y {p.sheet_mm[1]:.4f} mm")
    if j is not None:
        if j.status == "ok":
            print(f"  joint command (compensated, elbow {args.elbow:+d}): q1 {j.q_deg[0]:.4f} "
                  f"q2 {j.q_deg[1]:.4f} deg, approach {j.approach[0]:+d} {j.approach[1]:+d}")
        else:
            print(f"  joint command: none ({j.reason})")
    return 0


def _write_csv(args, ids, points, joints) -> int:
    import csv
    import io
    import sys

    from vision_cal.dataset.io import atomic_write_text, output_file

    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    head = ["id", "u_px", "v_px", "z_mm", "x_mm", "y_mm", "x_std_mm", "y_std_mm",
            "sheet_x_mm", "sheet_y_mm"]
    if args.robot:
        head += ["q1_deg", "q2_deg", "approach1", "approach2", "status", "reason"]
    wr.writerow(head)
    for i, p, j in zip(ids, points, joints):
        row = [i, f"{p.pixel[0]:.4f}", f"{p.pixel[1]:.4f}", f"{p.z_mm:g}",
               f"{p.robot_mm[0]:.5f}", f"{p.robot_mm[1]:.5f}", f"{p.robot_std_mm[0]:.5f}",
               f"{p.robot_std_mm[1]:.5f}", f"{p.sheet_mm[0]:.5f}", f"{p.sheet_mm[1]:.5f}"]
        if j is not None:
            ok = j.status == "ok"
            row += ([f"{j.q_deg[0]:.5f}", f"{j.q_deg[1]:.5f}"] if ok else ["", ""]) + \
                   [j.approach[0], j.approach[1], j.status, j.reason]
        wr.writerow(row)
    if args.out:
        output_file(args.out, field="-o")
        path = atomic_write_text(args.out, buf.getvalue())
        if not args.quiet:
            print(f"located {len(points)} pixels -> {path}")
    else:
        sys.stdout.write(buf.getvalue())
    return 0
