"""Poses for a camera on the arm (``vision-cal design --camera-on-arm``) and their program.

The poses put the flange (nominal model) over the marker field, ``margin_mm`` inside the
markers' extent so the camera sees markers whatever its offset; half with each elbow
(``elbows`` of the robot file), spread over the field (the candidate farthest from those
already chosen, among random reachable ones), joint 4 stepped evenly over its range when the
camera is on the flange (so ``L2`` and the camera's offset along link 2 can be told
apart: ``camera/arm.py``). The program (Epson SPEL+) drives to each pose with joint 3 at
``pen_up_mm``, waits ``settle_s``, then triggers the camera: an output pulse
(``On N; Wait t; Off N``) or, with ``trigger="wait"``, a pause for a photo taken by hand;
then waits for the exposure before moving on.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vision_cal.dataset.io import atomic_write_json, atomic_write_text
from vision_cal.dataset.robot import OUTPUT_BITS
from vision_cal.dataset.session import MAX_POSES
from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import forward
from vision_cal.model.motion import approach_signs
from vision_cal.progress import bar
from vision_cal.program.spel import spel_comment, spel_joints

TRIGGERS = ("output", "wait")
#: from this many poses on, choosing them takes seconds: a progress line shows it
PROGRESS_FROM = 100
#: how far before a repeated pose its via point lies (deg, each joint on its approach side)
REPEAT_VIA_DEG = 5.0


def add_repeats(poses: list[dict], n_repeats: int, home_deg=(0.0, 0.0),
                j4_start: float = 0.0, limits_deg=None, j4_limits_deg=None) -> list[dict]:
    """``poses`` with ``n_repeats`` of them (spread over the order) taken twice: right after
    the first photo the arm leaves through a via point ``REPEAT_VIA_DEG`` before the pose
    on each joint's approach side (``via_deg``: program only, no photo) and comes back, so
    the second photo (``repeat_of``) is reached from the same sides after a real move: the
    two differ by the robot's repeatability alone, which the verdict then measures
    (``estimate/verdict.judge_camera_poses``). Images renumbered in driving order."""
    if n_repeats <= 0:
        return poses
    q = np.array([p["joints_deg"] for p in poses], float)
    j4 = np.array([p["j4_deg"] for p in poses], float)
    s = approach_signs(q, home_deg)
    s4 = approach_signs(np.column_stack([j4, j4]), (j4_start, j4_start))[:, 0]
    lim = np.asarray(limits_deg if limits_deg is not None else [[-1e9, 1e9]] * 2, float)
    lim4 = np.asarray(j4_limits_deg if j4_limits_deg is not None else [-1e9, 1e9], float)
    vias = np.column_stack([q - s * REPEAT_VIA_DEG, j4 - s4 * REPEAT_VIA_DEG])
    ok = [k for k in range(len(poses))
          if np.all((vias[k, :2] >= lim[:, 0]) & (vias[k, :2] <= lim[:, 1]))
          and lim4[0] <= vias[k, 2] <= lim4[1]]
    pick = set()
    for want in np.linspace(0, len(poses) - 1, min(n_repeats, len(ok))):
        free = [k for k in ok if k not in pick]
        if free:
            pick.add(min(free, key=lambda k: abs(k - want)))
    out = []
    for k, p in enumerate(poses):
        out.append(dict(p))
        if k in pick:
            via = [round(float(v), 4) for v in vias[k]]
            out.append({**p, "repeat_of": None, "via_deg": via})
    names = {}
    for i, p in enumerate(out):
        new = f"pose_{i:03d}.png"
        if "via_deg" in p:
            p["repeat_of"] = names[p["image"]]
        else:
            names[p["image"]] = new
        p["image"] = new
    return out


def plan_poses(robot, sheet, *, n_poses: int = 24, margin_mm: float = 60.0,
               mount: str = "flange", j4_range_deg=(-170.0, 170.0), rng=None,
               progress: bool = False) -> list[dict]:
    """``poses`` entries ({image, joints_deg, j4_deg}) in driving order; ``progress``: a
    bar (or a line at the start and the end) while they are chosen."""
    rng = np.random.default_rng(rng)
    p = robot.nominal.params
    hull = sheet.markers_hull_mm()
    if hull is None:
        raise VisionCalError("the sheet has no markers", field="--sheet")
    x0, y0, x1, y1 = hull
    x0, y0, x1, y1 = x0 + margin_mm, y0 + margin_mm, x1 - margin_mm, y1 - margin_mm
    if x1 <= x0 or y1 <= y0:
        raise VisionCalError(f"the marker field is smaller than twice the {margin_mm:g} mm "
                             "margin", field="--sheet")
    lim = np.asarray(robot.joint_limits_deg, float)
    chosen: list[np.ndarray] = []
    qs: list[np.ndarray] = []
    pbar = bar(progress and n_poses >= PROGRESS_FROM, total=n_poses, desc="plan camera poses",
               unit="pose")
    for k in range(n_poses):
        elbow = robot.elbows[k % len(robot.elbows)]
        q = rng.uniform(lim[:, 0], lim[:, 1], (4000, 2))
        xy = forward(p, q)
        ok = ((xy[:, 0] > x0) & (xy[:, 0] < x1) & (xy[:, 1] > y0) & (xy[:, 1] < y1)
              & (np.sign(np.sin(np.radians(q[:, 1] + p.z2_deg))) == elbow)
              & (np.abs(np.sin(np.radians(q[:, 1] + p.z2_deg))) > 0.2))
        if not ok.any():
            raise VisionCalError(f"no pose with elbow {elbow:+d} puts the flange over the marker "
                                 "field within the joint limits", field="--sheet")
        q, xy = q[ok], xy[ok]
        if chosen:
            d = np.min(np.linalg.norm(xy[:, None] - np.array(chosen)[None], axis=2), axis=1)
            i = int(np.argmax(d))
        else:
            i = 0
        chosen.append(xy[i])
        qs.append(q[i])
        pbar.update()
    pbar.close()
    if mount == "flange":
        j4 = np.linspace(j4_range_deg[0], j4_range_deg[1], n_poses)
        j4 = j4[rng.permutation(n_poses)]
    else:
        j4 = np.zeros(n_poses)
    order = np.argsort(np.arctan2(np.array(chosen)[:, 1] - p.base_y_mm,
                                  np.array(chosen)[:, 0] - p.base_x_mm))
    return [{"image": f"pose_{k:03d}.png", "joints_deg": [round(float(qs[i][0]), 4),
                                                          round(float(qs[i][1]), 4)],
             "j4_deg": round(float(j4[i]), 4)} for k, i in enumerate(order)]


def spel_camera_program(poses, robot, *, trigger: str = "output", output_bit: int = 8,
                        pulse_s: float = 0.05, exposure_s: float = 0.3,
                        wait_s: float = 3.0) -> str:
    up, _ = robot.require_pen_heights()
    prog = robot.program
    lines = [spel_comment(f"vision-cal design --camera-on-arm: {len(poses)} camera poses for robot "
                      f"{robot.name}"),
             spel_comment("Points are joint angles JA(j1 deg, j2 deg, j3 mm, j4 deg); joint 3 "
                      "stays up. At each pose the arm settles, then the camera is triggered "
                      + (f"by a {pulse_s:g} s pulse on output {output_bit}."
                         if trigger == "output" else f"by hand during a {wait_s:g} s pause.")),
             spel_comment("Do not edit the points: the calibration reads the commanded joints "
                      "from session.json poses."),
             "", "Function main", "    Motor On",
             f"    Power {'High' if prog.power == 'high' else 'Low'}",
             f"    Speed {prog.speed_percent:g}",
             f"    Accel {prog.accel_percent[0]:g}, {prog.accel_percent[1]:g}"]
    for k, p in enumerate(poses):
        lines.append(f"    Print \"pose {k + 1} of {len(poses)}: {p['image']}\"")
        if p.get("via_deg") is not None:   # a repeat: away and back from the same sides
            v = p["via_deg"]
            lines.append(f"    Go {spel_joints(v[:2], up, v[2])}  ' away, then back to "
                         f"{p['repeat_of']}'s pose")
        lines.append(f"    Go {spel_joints(p['joints_deg'], up, p['j4_deg'])}")
        if prog.settle_s > 0:
            lines.append(f"    Wait {prog.settle_s:g}")
        if trigger == "output":
            lines += [f"    On {output_bit}", f"    Wait {pulse_s:g}", f"    Off {output_bit}",
                      f"    Wait {exposure_s:g}"]
        else:
            lines.append(f"    Wait {wait_s:g}  ' take the photo {p['image']} now")
    lines += [f"    Print \"done: {len(poses)} poses\"", "Fend"]
    return "\r\n".join(lines) + "\r\n"


def check_design(*, n_poses: int, trigger: str, seed: int, output_bit: int = 8) -> None:
    """The arguments of a camera-on-arm design, each bounded (one line naming the option)."""
    if trigger not in TRIGGERS:
        raise VisionCalError(f"expected one of {', '.join(TRIGGERS)}", field="--trigger")
    lo, hi = OUTPUT_BITS
    if isinstance(output_bit, bool) or not isinstance(output_bit, int) \
            or not lo <= output_bit <= hi:   # else "On -5" in the program
        raise VisionCalError(f"expected an output bit number {lo}..{hi}, got {output_bit!r}",
                             field="--trigger-output")
    if not 8 <= n_poses <= MAX_POSES:
        raise VisionCalError(f"expected 8 to {MAX_POSES} poses (at least 8: 12 parameters and "
                             f"both elbows; at most {MAX_POSES}: more adds nothing the fit "
                             f"can use), got {n_poses}", field="--n-poses")
    if seed < 0:
        raise VisionCalError(f"expected a non-negative integer, got {seed}", field="--seed")


def design_camera_on_arm(robot, sheet, sheet_json: dict, out, *, n_poses: int = 24,
                         mount: str = "flange", trigger: str = "output", output_bit: int = 8,
                         seed: int = 0, repeats: int = 0,
                         progress: bool = False) -> tuple[Path, Path]:
    """session.json (poses, no camera yet) and program.prg in ``out``; ``repeats`` of the
    poses taken twice (:func:`add_repeats`)."""
    check_design(n_poses=n_poses, trigger=trigger, seed=seed, output_bit=output_bit)
    poses = plan_poses(robot, sheet, n_poses=n_poses, mount=mount, rng=seed,
                       progress=progress)
    if mount != "flange" and repeats:
        poses = add_repeats(poses, repeats, robot.nominal.home_deg,
                            limits_deg=robot.joint_limits_deg)
        for p in poses:       # a camera on link 2 never turns joint 4: its via stays at 0
            if p.get("via_deg") is not None:
                p["via_deg"][2] = 0.0
    elif repeats:
        poses = add_repeats(poses, repeats, robot.nominal.home_deg,
                            robot.j4_deg if robot.j4_deg is not None else 0.0,
                            limits_deg=robot.joint_limits_deg,
                            j4_limits_deg=robot.joint4_limits_deg)
    prg = spel_camera_program(poses, robot, trigger=trigger, output_bit=output_bit)
    out = Path(out)
    session = {"format": "vision-cal/1", "sheet": sheet_json,
               "robot": robot.nominal.to_json(), "camera_mount": mount, "poses": poses}
    a = atomic_write_json(out / "session.json", session)
    b = atomic_write_text(out / "program.prg", prg)
    return a, b
