"""``preview.png`` of a design and the check that the robot can reach the sheet at all.

The picture (sheet frame, mm): the paper, its markers and the drawable box; the robot's
base where the plan's model puts it, its reach (L1 + L2) and, drawn with both links, the
arm at joint zero (link 1 along z1: the robot file's ``joint_zero_deg`` includes the
robot's rotation to the sheet, ``docs/conventions.md``; a robot file that forgets it shows
the arm at zero pointing another way than the real one does) and at a few planned marks;
every planned mark where that model puts it.

:func:`reach_fraction` is the share of the drawable paper the arm reaches within its joint
limits (either elbow the robot file allows); ``design`` warns when it is below
``REACH_WARN``: the guessed base (or z1) puts the reach mostly off the sheet.
"""

from __future__ import annotations

import io

import numpy as np

from vision_cal.model.kinematics import forward

REACH_WARN = 0.5
N_ARMS = 4            # planned poses drawn with both links


def reach_fraction(params, sheet, *, joint_limits_deg, elbows=(1, -1), n: int = 60) -> float:
    """Share (0..1) of ``sheet.extent_mm`` (a grid of n x n points) that the arm of
    ``params`` (``ScaraParams``) reaches with joints inside ``joint_limits_deg``."""
    x0, y0, x1, y1 = sheet.extent_mm
    X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
    d = np.column_stack([X.ravel(), Y.ravel()]) - np.asarray(params.base_mm, float)
    L1, L2 = params.L1_mm, params.L2_mm
    r2 = np.sum(d**2, axis=1)
    c2 = (r2 - L1**2 - L2**2) / (2 * L1 * L2)
    ok_any = np.zeros(len(d), bool)
    inside = np.abs(c2) <= 1.0
    c2 = np.clip(c2, -1.0, 1.0)
    (lo1, hi1), (lo2, hi2) = joint_limits_deg
    for e in elbows:
        phi2 = e * np.arccos(c2)                     # link 2 relative to link 1
        phi1 = np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(L2 * np.sin(phi2), L1 + L2 * np.cos(phi2))
        q1 = (np.degrees(phi1) - params.z1_deg + 180.0) % 360.0 - 180.0
        q2 = (np.degrees(phi2) - params.z2_deg + 180.0) % 360.0 - 180.0
        ok_any |= inside & (q1 >= lo1) & (q1 <= hi1) & (q2 >= lo2) & (q2 <= hi2)
    return float(ok_any.mean())


def preview_png(params, sheet, marks, *, paper=None, title: str = "") -> bytes:
    """The preview picture as PNG bytes (see the module docstring). ``params``: the model
    the plan was placed with (``ScaraParams``); ``sheet``: the drawable sheet; ``paper``:
    the whole paper (default ``sheet``); ``marks``: ``PlannedMark`` list."""
    # matplotlib takes 0.2 s to import: loaded here, when used
    import matplotlib

    matplotlib.use("Agg")
    # matplotlib takes 0.2 s to import: loaded here, when used
    import matplotlib.pyplot as plt
    # matplotlib takes 0.2 s to import: loaded here, when used
    from matplotlib.patches import Circle, Polygon, Rectangle

    paper = paper or sheet
    fig, ax = plt.subplots(figsize=(8.0, 6.0))
    px0, py0, px1, py1 = paper.extent_mm
    ax.add_patch(Rectangle((px0, py0), px1 - px0, py1 - py0, fc="#fbfbf6", ec="0.3", lw=1.0,
                           label="paper"))
    if sheet.bottom_left_mm is not None:   # the drawable box (design.stage.drawable_sheet)
        (x0, y0), (w, h) = sheet.bottom_left_mm, sheet.size_mm
        x1, y1 = x0 + w, y0 + h
    else:
        x0, y0, x1, y1 = sheet.extent_mm
    if (x0, y0, x1, y1) != (px0, py0, px1, py1):
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fc="none", ec="#6a9", lw=0.8,
                               ls="--", label="drawable"))
    for m in paper.markers:
        if m.id >= 0:
            ax.add_patch(Polygon(np.asarray(m.corners_mm, float), fc="k", ec="k"))
    base = np.asarray(params.base_mm, float)
    reach = params.L1_mm + params.L2_mm
    ax.add_patch(Circle(base, reach, fc="none", ec="#c66", lw=0.8, ls=":",
                        label=f"reach {reach:.0f} mm"))
    ax.plot(*base, "o", ms=9, color="#c33", label="base (guess)")

    seen = [np.array([px0, py0]), np.array([px1, py1]), base - 40, base + 40]

    def arm(q, **kw):
        q = np.asarray(q, float)
        phi1 = np.radians(q[0] + params.z1_deg)
        elbow = base + params.L1_mm * np.array([np.cos(phi1), np.sin(phi1)])
        pen = forward(params, q.reshape(1, 2))[0]
        seen.extend([elbow, pen])
        ax.plot([base[0], elbow[0], pen[0]], [base[1], elbow[1], pen[1]], "-o", ms=3, **kw)

    arm((0.0, 0.0), color="#c33", lw=2.5, label="arm at joint zero")
    if marks:
        q = np.array([m.joints_deg for m in marks], float)
        xy = forward(params, q)
        for k in np.unique(np.linspace(0, len(marks) - 1, min(N_ARMS, len(marks))).astype(int)):
            arm(q[k], color="#36c", lw=1.2, alpha=0.7,
                label="arm at planned marks" if k == 0 else None)
        ax.plot(xy[:, 0], xy[:, 1], "+", color="#136", ms=7, mew=1.5,
                label=f"{len(marks)} planned marks")
    lo, hi = np.min(seen, axis=0), np.max(seen, axis=0)
    ax.set_xlim(lo[0] - 20, hi[0] + 20)
    ax.set_ylim(lo[1] - 20, hi[1] + 20)
    ax.set_aspect("equal")
    ax.set_xlabel("sheet x [mm]")
    ax.set_ylabel("sheet y [mm]")
    ax.set_title(title or "design preview (sheet frame)", fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return buf.getvalue()
