"""ISO 9283 positioning accuracy (AP) and repeatability (RP) points for a check plan.

ISO 9283 measures a robot at five points of a test plane: P1 at its centre, P2 to P5 on
its diagonals at 10 % of the diagonal from the corners, each reached N times (the
standard: 30 cycles) from the same side. Here the plane is the sheet's drawable box and a
visit is a pen mark, so repeated visits of one point would put every dot on the same spot:
each visit ``j`` of point ``P`` is commanded to ``P + offset_j`` instead, the offsets a
small grid (``PITCH_MM`` apart, wider than a dot) centred on ``P``.

How the offsets are taken out (``vision_cal.estimate.verify``): each visit's error is its measured
mark minus *its own* commanded position (``P + offset_j`` through the calibrated model,
with the sheet's placement refitted), so the offset cancels exactly. This assumes the
robot's systematic error is the same over the few millimetres of the grid (the visits
differ in joint angles by about the grid's size over the reach: hundredths of a degree);
a gear error with a period of millimetres would show up as repeatability.

Then, per point, with ``e_j`` the visits' 2-D errors (mm): AP = |mean(e_j)| (ISO's
AP_P in the plane), ``l_j = |e_j - mean(e)|``, RP = mean(l) + 3 std(l) (sample std):
:func:`vision_cal.estimate.verify.ap_rp`.
"""

from __future__ import annotations

import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.plan.compensate import plan_targets, to_planned_marks

PITCH_MM = 6.0
POINTS = ("P1", "P2", "P3", "P4", "P5")


def iso_points_mm(box) -> np.ndarray:
    """(5, 2) P1..P5 in a rectangle ``box`` = (x0, y0, x1, y1): centre, then the diagonals
    at 10 % of their length from the corners (P2 near (x0, y0)... counter-clockwise)."""
    x0, y0, x1, y1 = (float(v) for v in box)
    c = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    return np.vstack([c, corners + 0.1 * (c - corners) / 0.5])


def offsets_mm(n: int, pitch_mm: float = PITCH_MM) -> np.ndarray:
    """(n, 2) offsets on a centred grid ``pitch_mm`` apart (row by row)."""
    k = int(np.ceil(np.sqrt(n)))
    g = (np.arange(k) - (k - 1) / 2) * pitch_mm
    xx, yy = np.meshgrid(g, g)
    return np.column_stack([xx.ravel(), yy.ravel()])[:n]


def reachable_box(model, box, *, elbow: int = 1, joint_limits_deg=None, margin_mm: float = 10.0):
    """The test plane: ``box`` (x0, y0, x1, y1) shrunk about the centroid of its reachable
    part until P1..P5 (``margin_mm`` around each) can all be planned; None if none can."""
    kw = {} if joint_limits_deg is None else {"joint_limits_deg": joint_limits_deg}
    x0, y0, x1, y1 = (float(v) for v in box)
    X, Y = np.meshgrid(np.linspace(x0, x1, 25), np.linspace(y0, y1, 25))
    grid = np.column_stack([X.ravel(), Y.ravel()])
    ok = [p.status == "ok" for p in plan_targets(model, range(len(grid)), grid, elbow=elbow,
                                                  **kw)]
    if not any(ok):
        return None
    c = grid[np.asarray(ok)].mean(axis=0)
    half = np.array([x1 - x0, y1 - y0]) / 2
    ring = np.array([[dx, dy] for dx in (-margin_mm, 0, margin_mm)
                     for dy in (-margin_mm, 0, margin_mm)])
    for f in np.linspace(1.0, 0.2, 17):
        lo, hi = np.maximum(c - f * half, [x0, y0]), np.minimum(c + f * half, [x1, y1])
        b = (lo[0], lo[1], hi[0], hi[1])
        pts = (iso_points_mm(b)[:, None, :] + ring[None]).reshape(-1, 2)
        if all(p.status == "ok" for p in plan_targets(model, range(len(pts)), pts,
                                                      elbow=elbow, **kw)):
            return b
    return None


def iso_marks(model, box, n_cycles: int, *, elbow: int = 1, overshoot_deg: float = 3.0,
              joint_limits_deg=None):
    """``PlannedMark`` list (role ``validation``, ids ``iso_P1_01`` ...) visiting P1..P5
    ``n_cycles`` times each, in ISO's cycle order P1, P5, P4, P3, P2, each visit from the
    +1 side of both joints; and the per-mark info {id: {point, offset_mm, commanded_mm}}."""
    off = offsets_mm(n_cycles)
    plane = reachable_box(model, box, elbow=elbow, joint_limits_deg=joint_limits_deg,
                          margin_mm=float(np.abs(off).max()) + 3.0)
    if plane is None:
        raise VisionCalError("no test plane for ISO 9283's five points lies within reach on "
                             "the drawable paper", field="--iso9283")
    P = iso_points_mm(plane)
    ids, xy, info = [], [], {}
    for j in range(n_cycles):
        for i in (0, 4, 3, 2, 1):
            mid = f"iso_{POINTS[i]}_{j + 1:02d}"
            t = P[i] + off[j]
            ids.append(mid)
            xy.append(t)
            info[mid] = {"point": POINTS[i], "point_mm": P[i].tolist(),
                         "offset_mm": off[j].tolist()}
    kw = {} if joint_limits_deg is None else {"joint_limits_deg": joint_limits_deg}
    planned = plan_targets(model, ids, np.array(xy), elbow=elbow, approach=(1, 1), **kw)
    bad = [p for p in planned if p.status != "ok"]
    if bad:
        raise VisionCalError(f"ISO 9283 point {bad[0].id} cannot be planned: {bad[0].reason}",
                             field="--iso9283")
    return to_planned_marks(planned, overshoot_deg=overshoot_deg), info
