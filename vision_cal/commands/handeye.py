"""``vision-cal handeye``: a camera on the arm calibrates the robot and finds its mount."""

from __future__ import annotations

NAME = "handeye"
HELP = ("calibrate the robot and T_flange_camera from photos taken by the arm's camera "
        "(session.json poses; no pen), or a camera from pose pairs another tool measured "
        "(--poses)")
EXAMPLES = """\
examples:
  vision-cal handeye arm_photos/ --out arm_cal/     -> arm_cal/calibration.json
  vision-cal handeye --poses pairs.json --out he/   -> he/calibration.json (T_flange_camera)
  vision-cal handeye --poses pairs.csv --units m --mount fixed --z-mm 12.5 --out he/

--poses: pairs of T_robot_flange and T_camera_target (4x4, or x,y,z,yaw and OpenCV
rvec/tvec; JSON or CSV; docs/format.md, "Hand-eye from pose pairs"). A SCARA's poses cannot
see the camera's height: --z-mm gives the target origin's height (arm: in the robot frame;
fixed: in the flange frame), else it is reported not identifiable.

session.json lists "poses" ({"image", "joints_deg", "j4_deg"}), the declared camera lens,
"camera_mount" (flange | link2) and the marker field (vision-cal sheet --field); see
docs/format.md, "Cameras". At most 500 poses.

Writes OUT/calibration.json only (an earlier run's results go to OUT/previous/): no
report.html yet (no --report); calibration.json's "poses" (each photo's residual) and
"verdict" hold what a report would. The photos are measured in --jobs processes.
"""


def add_arguments(p) -> None:
    p.add_argument("folder", metavar="FOLDER", nargs="?", default=None,
                   help="dataset folder with session.json poses (photos of the arm's camera)")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--poses", metavar="PAIRS", default=None,
                   help="pose pairs file (JSON vision-cal/poses/1, or CSV) instead of FOLDER")
    p.add_argument("--units", choices=("mm", "m"), default=None,
                   help="--poses: the file's lengths (default: the file's units, else mm)")
    p.add_argument("--mount", choices=("arm", "fixed"), default=None,
                   help="--poses: the camera rides on the flange (arm, default) or stands "
                        "still watching a target on the flange (fixed)")
    p.add_argument("--z-mm", type=float, default=None, dest="z_mm", metavar="H",
                   help="--poses: the target origin's height (mm; arm: robot frame, fixed: "
                        "flange frame), which a SCARA's motion cannot see")
    p.add_argument("-j", "--jobs", type=int, default=None, metavar="N",
                   help="processes that measure the photos (default: every core; the same "
                        "result for any N)")


def run(args) -> int:
    # imported here, not at the top: every command module is imported to build the parser,
    # and the library pulls numpy, scipy and OpenCV, which `vision-cal --help` does not need
    import os

    from vision_cal.actions.handeye import HandeyeRequest, handeye_pairs
    from vision_cal.workflows.arm_session import calibrate_arm_camera
    from vision_cal.dataset.io import atomic_write_json
    from vision_cal.dataset.out_folder import writing_into
    from vision_cal.diagnose.verdict import Verdict
    from vision_cal.errors import VisionCalError

    if (args.folder is None) == (args.poses is None):
        raise VisionCalError("give FOLDER (photos of the arm's camera) or --poses PAIRS "
                             "(pose pairs), one of them", field="--poses")
    if args.poses is not None:
        return handeye_pairs(HandeyeRequest(args.poses, args.out, units=args.units,
                                            mount=args.mount, z_mm=args.z_mm,
                                            quiet=args.quiet))
    for name in ("units", "mount", "z_mm"):
        if getattr(args, name) is not None:
            raise VisionCalError("applies to --poses only", field=f"--{name.replace('_', '-')}")
    if args.jobs is not None and args.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {args.jobs}", field="--jobs")
    # the output folder: never the photos' folder; an earlier run's results (this command's
    # or a pen calibration's) go to previous/ first; locked while written (issue 30)
    with writing_into(args.out, command="handeye", inputs=[("FOLDER", args.folder)],
                      quiet=args.quiet) as out:
        doc = calibrate_arm_camera(args.folder, progress=not args.quiet,
                                   jobs=args.jobs or os.cpu_count() or 1)
        path = atomic_write_json(out / "calibration.json", doc)
    if not args.quiet:
        cam = doc["cameras"][0]
        p, sd = doc["params"], doc["std"]
        skipped = [im for im in doc["images"] if im["status"] != "ok"]
        print(f"{len(cam['images'])} photos used, {len(skipped)} skipped; corner RMS "
              f"{cam['corner_rms_px']:.3f} px")
        print(f"L1 {p['L1_mm']:.4f} +- {sd['L1_mm']:.4f} mm, L2 {p['L2_mm']:.4f} +- "
              f"{sd['L2_mm']:.4f} mm, zeros {p['joint_zero_deg'][0]:.4f} "
              f"{p['joint_zero_deg'][1]:.4f} deg, base {p['base_mm'][0]:.3f} "
              f"{p['base_mm'][1]:.3f} mm")
        print(flange_camera_line(cam))
        for e in doc["effects"]:
            print(f"joint {e['joint']} backlash {e['deg']:.4f} +- {e['std']:.4f} deg")
        v = Verdict.from_json(doc["verdict"])
        if v.floor_line:
            print(v.floor_line)
        print(v.text)
        print(f"wrote {path}")
    return 0


def flange_camera_line(cam: dict) -> str:
    """T_flange_camera in words, with units: the camera's x and y in the flange frame with
    their std; its z is the height above the sheet's plane (SCARA motion is planar: the
    flange's own height, hence the camera's height above the flange, is not identifiable)."""
    t = cam["T_flange_camera"]
    sd = cam["T_flange_camera_std"]["translation_mm"]
    return (f"T_flange_camera: camera at x {t[0][3]:.3f} +- {sd[0]:.3f} mm, y {t[1][3]:.3f} +- "
            f"{sd[1]:.3f} mm in the flange frame; its height above the flange is not "
            f"identifiable (planar motion): z {t[2][3]:.3f} mm is its height above the "
            "sheet's plane")
