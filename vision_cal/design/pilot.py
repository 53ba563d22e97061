"""The pilot plan: a few marks that land on free paper however the robot really stands.

Before any calibration only the catalogue model and a rough guess of the base are known
(the robot file's ``placement_tolerance``: tens of millimetres and several degrees). The
pilot is the seed paper's pattern - a centre pose, joint 1 turned either side of it at a
fixed joint 2 (marks on a circle about the base) and joint 2 turned either side at a fixed
joint 1 (a circle about the elbow) - with two marks on each side instead of one, so a
mark lost on the photo still leaves four on each circle (9 marks; 18 equations for the 6
base parameters, usable by ``--method paper`` and by least squares).

The design is for the worst case: every mark must keep ``pen radius + margin_mm`` clear of
the paper's edges and of every ArUco square for every placement of a grid that spans the
tolerance (the base on a circle of radius ``base_mm`` and at its centre, z1 and z2 at
-t, 0, +t, each link at -t and +t: 324 placements; the pen position is smooth in these,
so its extremes are at the corners). Among the patterns that pass, the widest spans win
(the arcs' circle centres are better determined), then the largest worst-case clearance.

Every mark is approached with both joints turning positive through an overshoot via
point, so a dead band acts the same on all of them (a constant offset absorbed in the
zeros) and cannot bias the pilot's circles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.plan.calibration_plan import PlannedMark, sheet_clearance_mm

#: (joint-1 span, joint-2 span) in degrees, tried widest first; the paper used (20, 60)
SPANS_DEG = tuple((d1, d2) for d1 in (20.0, 16.0, 12.0, 9.0, 6.0, 4.0)
                  for d2 in (60.0, 45.0, 35.0, 25.0, 18.0, 12.0))
ARM_STEPS = (-1.0, -0.5, 0.5, 1.0)


@dataclass(frozen=True)
class PilotDesign:
    marks: tuple[PlannedMark, ...]
    centre_deg: tuple[float, float]
    span_deg: tuple[float, float]
    worst_clearance_mm: float       # smallest clearance of any mark over every placement
    required_clearance_mm: float
    n_placements: int

    def to_json(self) -> dict:
        return {"stage": "pilot", "centre_deg": list(self.centre_deg),
                "span_deg": list(self.span_deg),
                "worst_case_clearance_mm": self.worst_clearance_mm,
                "required_clearance_mm": self.required_clearance_mm,
                "placements_checked": self.n_placements}


def placement_grid(nominal, tolerance, *, n_dirs: int = 8) -> np.ndarray:
    """Parameter vectors (P, 6) [L1, L2, z1_rad, z2_rad, bx, by] spanning the tolerance."""
    L1, L2 = nominal.L1_mm, nominal.L2_mm
    z1, z2 = np.radians(nominal.joint_zero_deg)
    bx, by = nominal.base_mm
    tz = np.radians(tolerance.joint_zero_deg)
    a = 2 * np.pi * np.arange(n_dirs) / n_dirs
    offs = np.vstack([[0.0, 0.0], tolerance.base_mm * np.column_stack([np.cos(a), np.sin(a)])])
    rows = []
    for dl1 in (-tolerance.link_mm, tolerance.link_mm):
        for dl2 in (-tolerance.link_mm, tolerance.link_mm):
            for d1 in (-tz[0], 0.0, tz[0]):
                for d2 in (-tz[1], 0.0, tz[1]):
                    for o in offs:
                        rows.append([L1 + dl1, L2 + dl2, z1 + d1, z2 + d2, bx + o[0], by + o[1]])
    return np.unique(np.array(rows), axis=0)


def pens_mm(placements: np.ndarray, q_deg: np.ndarray) -> np.ndarray:
    """Pen positions (P, M, 2) of marks ``q_deg`` (M, 2) for every placement (P, 6)."""
    q = np.radians(np.asarray(q_deg, dtype=float))
    p = placements[:, None, :]
    a1 = q[None, :, 0] + p[..., 2]
    a12 = a1 + q[None, :, 1] + p[..., 3]
    x = p[..., 4] + p[..., 0] * np.cos(a1) + p[..., 1] * np.cos(a12)
    y = p[..., 5] + p[..., 0] * np.sin(a1) + p[..., 1] * np.sin(a12)
    return np.stack([x, y], axis=-1)


def pattern_deg(centre_deg, span_deg) -> np.ndarray:
    """The pilot poses (9, 2): centre, joint-1 arm, joint-2 arm (drawing order)."""
    c = np.asarray(centre_deg, dtype=float)
    rows = [c]
    rows += [c + [k * span_deg[0], 0.0] for k in ARM_STEPS]
    rows += [c + [0.0, k * span_deg[1]] for k in ARM_STEPS]
    return np.array(rows)


class ClearanceMap:
    """:func:`sheet_clearance_mm` sampled on a grid (``res_mm``), looked up in O(1).

    Lookups are the nearest grid node's value minus ``res_mm`` (a node is at most
    ``res_mm / sqrt(2)`` from the point and clearance is 1-Lipschitz), so a lookup never
    overstates the clearance. Points off the grid read as -1 (off the paper)."""

    def __init__(self, sheet, *, res_mm: float = 1.0):
        # OpenCV takes 0.2 s to import: loaded here, when used
        import cv2

        x0, y0, x1, y1 = sheet.extent_mm
        self.res, self.x0, self.y0 = float(res_mm), x0, y0
        nx = int(np.ceil((x1 - x0) / res_mm)) + 1
        ny = int(np.ceil((y1 - y0) / res_mm)) + 1
        # exact edge distance, marker distance by a distance transform of the marker mask
        # at 4x the resolution (converted to mm), nodes inside a marker read 0
        up = 4
        mask = np.full((ny * up, nx * up), 255, np.uint8)
        for m in sheet.markers:
            c = (np.asarray(m.corners_mm, float) - [x0, y0]) / res_mm * up
            cv2.fillConvexPoly(mask, np.round(c).astype(np.int32), 0)
        dt = cv2.distanceTransform(mask, cv2.DIST_L2, 5)[::up, ::up] * res_mm / up
        gx = x0 + np.arange(nx) * res_mm
        gy = y0 + np.arange(ny) * res_mm
        edge = np.minimum.reduce(np.broadcast_arrays(
            (gx - x0)[None, :], (x1 - gx)[None, :], (gy - y0)[:, None], (y1 - gy)[:, None]))
        self.grid = np.minimum(edge, dt) - res_mm * (1.0 + 1.0 / up)

    def __call__(self, xy_mm) -> np.ndarray:
        xy = np.asarray(xy_mm, dtype=float)
        i = np.rint((xy[..., 0] - self.x0) / self.res).astype(np.int64)
        j = np.rint((xy[..., 1] - self.y0) / self.res).astype(np.int64)
        ny, nx = self.grid.shape
        inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        out = np.full(xy.shape[:-1], -1.0)
        out[inside] = self.grid[j[inside], i[inside]]
        return out


def _worst_clearance(clear, placements: np.ndarray, Q: np.ndarray, need: float,
                     block: int = 16) -> np.ndarray:
    """The smallest clearance (n,) of each pattern ``Q`` (n, 9, 2) over every placement
    (P, 6), placements a block at a time: a pattern below ``need`` is out and dropped
    (its value then some clearance below ``need``), the others' exact (the same values as
    all placements at once; an impossible tolerance no longer checks every placement of
    300 patterns that the first block already rules out)."""
    worst = np.full(len(Q), np.inf)
    alive = np.arange(len(Q))
    for s in range(0, len(placements), block):
        if not len(alive):
            break
        p = placements[s:s + block]
        xy = pens_mm(p, Q[alive].reshape(-1, 2))                      # (p, n*9, 2)
        w = clear(xy.reshape(len(p), len(alive), -1, 2)).min(axis=(0, 2))
        worst[alive] = np.minimum(worst[alive], w)
        alive = alive[worst[alive] >= need]
    return worst


def design_pilot(robot, sheet, *, margin_mm: float = 3.0, min_separation_mm: float = 8.0,
                 min_sin_elbow: float = 0.1, step_deg: float = 2.0) -> PilotDesign:
    """The pilot plan for ``robot`` (a :class:`vision_cal.dataset.robot.RobotFile`) on
    ``sheet``; raises :class:`VisionCalError` when no pattern fits the tolerance."""
    nominal = robot.nominal
    tol = robot.tolerance
    over = robot.overshoot_deg
    need = robot.mark_diameter_mm / 2 + margin_mm
    placements = placement_grid(nominal, tol)
    lim = np.asarray(robot.joint_limits_deg, dtype=float)
    lo, hi = lim[:, 0] + over + 0.5, lim[:, 1] - 0.5
    z2 = np.radians(nominal.joint_zero_deg[1])
    tz2 = np.radians(tol.joint_zero_deg[1])
    allowed = np.asarray(robot.elbows, dtype=int)
    # the worst-case displacement of a pen point (an upper bound, for the message)
    reach = nominal.L1_mm + nominal.L2_mm + tol.link_mm * 2
    bound = tol.base_mm + 2 * tol.link_mm + np.radians(tol.joint_zero_deg[0]) * reach \
        + np.radians(tol.joint_zero_deg[1]) * (nominal.L2_mm + tol.link_mm)
    g1 = np.arange(lo[0], hi[0] + 1e-9, step_deg)
    g2 = np.arange(lo[1], hi[1] + 1e-9, step_deg)
    C = np.array(np.meshgrid(g1, g2, indexing="ij")).reshape(2, -1).T   # candidate centres
    nominal_p = placement_grid(nominal, type(tol)(0.0, (0.0, 0.0), 0.0))
    clear = ClearanceMap(sheet)
    for span in SPANS_DEG:
        Q = C[:, None, :] + pattern_deg((0.0, 0.0), span)[None]           # (K, 9, 2)
        ok = np.all((Q >= lo) & (Q <= hi), axis=(1, 2))
        # one allowed elbow for every mark and every z2 within the tolerance
        for dz in (-tz2, 0.0, tz2):
            s = np.sin(np.radians(Q[..., 1]) + z2 + dz)
            el = np.where(s > 0, 1, -1)
            ok &= np.all(np.abs(s) >= min_sin_elbow, axis=1)
            ok &= np.all(np.isin(el, allowed), axis=1) & np.all(el == el[:, :1], axis=1)
        if not ok.any():
            continue
        K = np.flatnonzero(ok)
        xy0 = pens_mm(nominal_p, Q[K].reshape(-1, 2))[0].reshape(len(K), -1, 2)
        c0 = clear(xy0).min(axis=1)
        sep = np.min([np.linalg.norm(xy0[:, i] - xy0[:, j], axis=1)
                      for i in range(xy0.shape[1]) for j in range(i)], axis=0)
        keep = (c0 >= need) & (sep >= min_separation_mm)
        if not keep.any():
            continue
        K, c0 = K[keep], c0[keep]
        order = K[np.argsort(-c0)][:300]
        worst = _worst_clearance(clear, placements, Q[order], need)
        good = worst >= need
        if not good.any():
            continue
        k = int(np.argmax(np.where(good, worst, -np.inf)))
        # confirm with the exact clearance
        exact = sheet_clearance_mm(sheet, pens_mm(placements, Q[order[k]]).reshape(-1, 2)).min()
        worst[k] = exact
        centre = C[order[k]]
        q = pattern_deg(centre, span)
        marks = []
        for i, qi in enumerate(q):
            qk = (float(qi[0]), float(qi[1]))
            via = ((qk[0] - over, qk[1] - over),)
            marks.append(PlannedMark(f"c{i:02d}", qk, "calibration", (1, 1), via))
        return PilotDesign(tuple(marks), (float(centre[0]), float(centre[1])),
                           (float(span[0]), float(span[1])), float(worst[k]), float(need),
                           len(placements))
    raise VisionCalError(
        f"no pilot pattern keeps {need:.1f} mm clear of the paper's edges and markers for "
        f"every placement within the tolerance (base {tol.base_mm:g} mm, zeros "
        f"{tol.joint_zero_deg[0]:g}/{tol.joint_zero_deg[1]:g} deg, links {tol.link_mm:g} mm, "
        f"up to ~{bound:.0f} mm of pen displacement): use a larger sheet, move the robot so "
        "the sheet lies well inside its reach, or measure the placement better",
        field="placement_tolerance")
