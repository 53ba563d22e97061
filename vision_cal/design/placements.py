"""Where to tape the sheet next: placements for a joint calibration (``vision-cal design
... --placements N``; issue #21, docs/format.md "Joint 4, the tool and placements").

The robot file's ``base_mm`` and ``joint_zero_deg`` say where the robot stands in the frame
of the sheet at its first placement. Turning the sheet about the joint-1 axis by ``delta``
(counter-clockwise seen from above) keeps the base at the same sheet coordinates and changes
only the sheet's angle: in the new placement's frame ``z1' = z1 - delta``. So placement
``k`` is the first one turned by ``delta_k``: its robot block is the robot file's with
``joint_zero_deg[0] - delta_k``; its sheet spans the joint-1 range of the first, shifted
by ``delta_k``. The turns are multiples of the sheet's angular width seen from the base
(so the placements do not overlap), alternately counter-clockwise and clockwise, kept
where the whole joint-1 range they need is within ``joint_limits_deg``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from vision_cal.dataset.io import atomic_write_json, atomic_write_text
from vision_cal.dataset.robot import load_robot_file, read_robot_tree
from vision_cal.dataset.session import load_sheet_file
from vision_cal.design.stage import design_stage
from vision_cal.errors import VisionCalError


def joint1_span_deg(nominal, extent_mm) -> tuple[float, float]:
    """The commanded joint-1 range (lo, hi) deg over which the sheet ``extent_mm`` (x0, y0,
    x1, y1) lies, seen from the base (the angle of each paper corner, less z1)."""
    x0, y0, x1, y1 = extent_mm
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]) - np.asarray(nominal.base_mm)
    ang = np.degrees(np.arctan2(corners[:, 1], corners[:, 0])) - nominal.joint_zero_deg[0]
    centre = np.degrees(np.arctan2(*np.mean(corners, axis=0)[::-1])) - nominal.joint_zero_deg[0]
    rel = (ang - centre + 180.0) % 360.0 - 180.0
    return float(centre + rel.min()), float(centre + rel.max())


def plan_placements(robot, sheet, n: int = 3) -> list[dict]:
    """``n`` placements (the first is the robot file's): each ``delta_deg`` (the turn about
    the joint-1 axis from the first), ``robot`` (its session robot block), ``q1_range_deg``
    and ``sheet_centre_mm`` (where the sheet's centre goes, in the first placement's sheet
    frame). Raises :class:`VisionCalError` when the joint-1 limits leave room for fewer."""
    if n < 1:
        raise VisionCalError(f"expected at least 1 placement, got {n}", field="--placements")
    nom = robot.nominal
    ext = sheet.extent_mm
    lo, hi = joint1_span_deg(nom, ext)
    width = hi - lo
    lim_lo, lim_hi = robot.joint_limits_deg[0]
    deltas = [0.0]
    k = 1
    while len(deltas) < n and k <= int(360 // max(width, 1.0)):
        for d in (k * width, -k * width):
            if len(deltas) < n and lim_lo <= lo + d and hi + d <= lim_hi:
                deltas.append(float(d))
        k += 1
    if len(deltas) < n:
        raise VisionCalError(f"the sheet spans {width:.0f} deg of joint 1 ({lo:.0f}..{hi:.0f}); "
                             f"joint 1's limits [{lim_lo:g}, {lim_hi:g}] leave room for "
                             f"{len(deltas)} placement(s), not {n}", field="--placements")
    centre = np.array([(ext[0] + ext[2]) / 2, (ext[1] + ext[3]) / 2])
    base = np.asarray(nom.base_mm)
    out = []
    for d in deltas:
        a = np.radians(d)
        c = base + np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]) @ (centre - base)
        block = nom.to_json()
        block["joint_zero_deg"] = [nom.joint_zero_deg[0] - d, nom.joint_zero_deg[1]]
        out.append({"delta_deg": d, "robot": block, "q1_range_deg": [lo + d, hi + d],
                    "sheet_centre_mm": c.tolist()})
    return out


def design_placements(robot_path, sheet_path, out_dir, n: int, *, program: str | None = "spel",
                      seed: int = 0) -> list[dict]:
    """Plan ``n`` placements and, for each, a robot file (``OUT/placeK/robot.yaml``: the
    robot file with that placement's ``joint_zero_deg``) and its pilot design
    (``OUT/placeK/``, :func:`vision_cal.design.stage.design_stage`); ``OUT/placements.json``
    lists them. Draw, photograph and calibrate each as the README says, then
    ``vision-cal calibrate OUT/place1 OUT/place2 ... --joint``."""
    robot = load_robot_file(robot_path)
    places = plan_placements(robot, load_sheet_file(sheet_path), n)
    tree = read_robot_tree(Path(robot_path))
    out = Path(out_dir)
    for k, p in enumerate(places, start=1):
        d = out / f"place{k}"
        rt = dict(tree, joint_zero_deg=p["robot"]["joint_zero_deg"])
        rpath = atomic_write_text(d / "robot.yaml", yaml.safe_dump(rt, sort_keys=False))
        r = design_stage(rpath, sheet_path, d, program=program, seed=seed)
        p.update(folder=str(d), robot_file=str(rpath), n_marks=r.n_marks,
                 instruction=(f"turn the sheet {p['delta_deg']:+.1f} deg about the robot's "
                              f"joint-1 axis (counter-clockwise seen from above is +): its "
                              f"centre goes to ({p['sheet_centre_mm'][0]:.0f}, "
                              f"{p['sheet_centre_mm'][1]:.0f}) mm in the first placement's "
                              "sheet frame"))
    atomic_write_json(out / "placements.json", {"placements": places})
    return places
