"""``--program csv``: a neutral point list, one row per point in the order to drive::

    id,kind,j1_deg,j2_deg,j3_mm,j4_deg,elbow,approach1,approach2,pen_z_mm,role

``kind`` is ``home``, ``via`` (the overshoot point: drive through it to the mark without
lowering the pen) or ``mark`` (stop, lower joint 3 to ``pen_z_mm``, dwell, raise it to
``j3_mm``). ``j3_mm`` is the travel height (pen up) at every point. ``elbow`` +1 means
sin(q2 + z2) > 0 (docs/conventions.md); ``approach1/2`` are the signs of each joint's
last motion onto the mark (the via point lies on the other side). Joints 1, 2, 4 in
degrees (6 decimals), joint 3 and pen z in millimetres.
"""

from __future__ import annotations

import csv
import io

FIELDS = ("id", "kind", "j1_deg", "j2_deg", "j3_mm", "j4_deg", "elbow", "approach1",
          "approach2", "pen_z_mm", "role")


def point_list(points, robot) -> str:
    up, down = robot.require_pen_heights()
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(FIELDS)
    for p in points:
        a = p.approach or ("", "")
        w.writerow([p.id, p.kind, f"{p.q_deg[0]:.6f}", f"{p.q_deg[1]:.6f}", f"{up:.3f}",
                    f"{robot.j4_deg if p.q4_deg is None else p.q4_deg:.6f}", p.elbow, a[0], a[1],
                    f"{down:.3f}" if p.kind == "mark" else "", p.role])
    return buf.getvalue()
