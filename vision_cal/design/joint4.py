"""Planning joint-4 turns for a calibration (an off-axis tool, docs/format.md "Joint 4 and
the tool").

:func:`circle_triples` adds the seed paper's circle method on joint 4: triples of marks at
one joint-1/joint-2 pose with joint 4 alone turned between them (three angles 120 deg
apart: the joint-4 circle, centre the flange, radius the tool), in both elbows and with
joint 4 approached from both sides (a triple drawn in increasing ``j4_deg``, another in
decreasing), every mark clear of the markers and the printed content as the informative
plan's are. :func:`joint4_vias` gives each mark's joint-4 via point from the side the
format's rule says it was approached.

:func:`turn_joint4` takes a plan made with a model whose tool is folded into link 2 (a
pilot calibration at one ``j4_deg``, or the nominal model) and turns joint 4 over
``j4_values`` (cycled over the marks, so each sheet region sees several tool directions),
re-solving joints 1 and 2 so each mark stays on the sheet point the plan chose (with the
rough ``tool_mm`` of the robot file: marks land within a few millimetres of it, clear of
markers as the plan kept them). The via points keep each joint's planned approach. A mark
no turned tool can keep on its point stays as planned (at ``folded_j4_deg``).
"""

from __future__ import annotations

import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import ScaraParams, forward
from vision_cal.model.robot import RobotModel, Tool
from vision_cal.model.motion import approach_signs
from vision_cal.plan.calibration_plan import PlannedMark, sheet_clearance_mm
from vision_cal.plan.orient import plan_poses, unfold_params

#: joint-4 angles cycled over the marks: six tool directions 60 deg apart
J4_VALUES_DEG = (-150.0, -90.0, -30.0, 30.0, 90.0, 150.0)


def turn_joint4(plan, folded: ScaraParams, tool_mm, *, j4_values=J4_VALUES_DEG,
                overshoot_deg: float = 3.0, folded_j4_deg: float = 0.0
                ) -> tuple[list[PlannedMark], dict[str, float]]:
    """(new plan, mark id -> j4_deg): the same sheet points with joint 4 turned.
    ``folded_j4_deg``: the joint-4 angle at which ``folded`` was calibrated."""
    if np.hypot(*tool_mm) == 0:
        raise VisionCalError("the tool is on the joint-4 axis (tool_mm = [0, 0]): turning "
                             "joint 4 moves no mark; give the robot file's tool_mm",
                             field="tool_mm")
    model = RobotModel(unfold_params(folded, tool_mm, folded_j4_deg),
                       (Tool(tool_mm=tuple(tool_mm)),))
    out, j4 = [], {}
    for i, m in enumerate(plan):
        xy = forward(folded, [m.joints_deg])
        elbow = 1 if np.sin(np.radians(m.joints_deg[1] + folded.z2_deg)) > 0 else -1
        # the cycle's next angle, else the following ones (a point near the edge of the
        # reach may not be kept with the tool turned outward), else joint 4 at 0
        p = None
        for k in range(len(j4_values)):
            a = float(j4_values[(i + k) % len(j4_values)])
            (p,) = plan_poses(model, [m.id], xy, q4_deg=a, elbow=elbow,
                              approach=(*m.approach, 1))
            if p.target.status == "ok":
                break
        if p is None or p.target.status != "ok":
            out.append(m)
            j4[m.id] = float(folded_j4_deg)
            continue
        q = np.asarray(p.target.q_deg)
        via = q - np.asarray(m.approach, dtype=float) * overshoot_deg
        out.append(PlannedMark(m.id, (float(q[0]), float(q[1])), m.role, tuple(m.approach),
                               ((float(via[0]), float(via[1])),)))
        j4[m.id] = a
    return out, j4


def joint4_vias(marks, j4: dict, *, start_deg: float = 0.0, overshoot_deg: float = 3.0
                ) -> dict[str, tuple[float, float]]:
    """Mark id -> (j4_deg at the mark, j4_deg at its via points) for ``marks`` in drawing
    order: joint 4 passes ``overshoot_deg`` short of the mark on the side it is approached
    from by the format's rule (sign of the change from the previous mark's ``j4_deg``,
    kept when it does not move, +1 at the start ``start_deg``), so the sign the session
    resolves is the side the arm really came from."""
    q4 = np.array([j4[m.id] for m in marks], dtype=float)
    s4 = approach_signs(np.column_stack([q4, q4]), (start_deg, start_deg))[:, 0]
    return {m.id: (float(v), float(v - s * overshoot_deg)) for m, v, s in zip(marks, q4, s4)}


def circle_triples(folded: ScaraParams, tool_mm, sheet, *, n_triples: int = 4,
                   avoid_xy=(), clearance_mm: float = 18.6, min_separation_mm: float = 10.0,
                   joint_limits_deg=((-150.0, 150.0), (-150.0, 150.0)),
                   joint4_limits_deg=(-360.0, 360.0), folded_j4_deg: float = 0.0,
                   overshoot_deg: float = 3.0, elbows=(1, -1), min_sin_elbow: float = 0.2,
                   n_candidates: int = 4000, rng=None
                   ) -> tuple[list[PlannedMark], dict[str, float]]:
    """``n_triples`` joint-4 circles (module docstring): (marks, mark id -> j4_deg), three
    marks per triple (ids ``t<k>a``, ``t<k>b``, ``t<k>c``, drawn in that order) sharing
    joints 1 and 2 and their approach, joint 4 turned 120 deg (less when its limits are
    narrower) between them. Triple ``k`` uses elbow ``elbows[k % len(elbows)]`` and turns
    joint 4 upward for ``k % 4 < 2``, downward otherwise, so four triples give both elbows
    both ways. Each mark lands (``folded`` with the rough ``tool_mm`` unfolded) at least
    ``clearance_mm`` from the paper's edges and every obstacle of ``sheet`` (markers,
    printed content, earlier marks as the caller adds them) and ``min_separation_mm`` from
    ``avoid_xy`` (N, 2) and each other; among such poses the one farthest from the marks
    already placed. Raises :class:`VisionCalError` when the sheet holds no such triple."""
    if np.hypot(*tool_mm) == 0:
        raise VisionCalError("the tool is on the joint-4 axis (tool_mm = [0, 0]): joint 4 "
                             "draws no circle; give the robot file's tool_mm", field="tool_mm")
    rng = np.random.default_rng(rng)
    model = RobotModel(unfold_params(folded, tool_mm, folded_j4_deg),
                       (Tool(tool_mm=tuple(tool_mm)),))
    lim = np.asarray(joint_limits_deg, dtype=float).reshape(2, 2)
    lo, hi = lim[:, 0] + overshoot_deg + 1.0, lim[:, 1] - overshoot_deg - 1.0
    lo4, hi4 = joint4_limits_deg[0] + overshoot_deg + 1.0, joint4_limits_deg[1] - overshoot_deg - 1.0
    step = min(120.0, (hi4 - lo4) / 2)
    if step < 30.0:
        raise VisionCalError(f"joint 4's limits {list(joint4_limits_deg)} leave no room for a "
                             "joint-4 circle (three angles at least 30 deg apart)",
                             field="joint4_limits_deg")
    placed = np.asarray(avoid_xy, dtype=float).reshape(-1, 2)
    marks, j4 = [], {}
    for k in range(int(n_triples)):
        elbow = int(elbows[k % len(elbows)])
        up = k % 4 < 2
        q = lo + (hi - lo) * rng.random((int(n_candidates), 2))
        sin_el = np.sin(np.radians(q[:, 1] + model.params.z2_deg))
        q = q[(np.sign(sin_el) == elbow) & (np.abs(sin_el) >= min_sin_elbow)]
        a0 = lo4 + (hi4 - lo4 - 2 * step) * rng.random(len(q))
        angles = a0[:, None] + step * np.arange(3)[None, :]
        if not up:
            angles = angles[:, ::-1]
        pts = model.predict(np.column_stack([np.repeat(q, 3, axis=0), angles.ravel()])
                            ).reshape(-1, 3, 2)
        ok = np.all(sheet_clearance_mm(sheet, pts.reshape(-1, 2)).reshape(-1, 3)
                    >= clearance_mm, axis=1)
        if len(placed):
            d = np.linalg.norm(pts[:, :, None, :] - placed[None, None], axis=3).min(axis=(1, 2))
            ok &= d >= min_separation_mm
        else:
            d = np.full(len(q), np.inf)
        if not ok.any():
            raise VisionCalError(f"no joint-4 circle (|tool| {np.hypot(*tool_mm):.0f} mm, elbow "
                                 f"{elbow:+d}) fits on free paper {clearance_mm:.1f} mm clear "
                                 "of the edges, markers and printed content", field="sheet")
        i = int(np.flatnonzero(ok)[np.argmax(np.where(np.isfinite(d), d, 0.0)[ok])]) \
            if len(placed) else int(np.flatnonzero(ok)[0])
        a12 = ((1, -1), (-1, 1), (-1, -1), (1, 1))[k % 4]
        via = (float(q[i, 0] - a12[0] * overshoot_deg), float(q[i, 1] - a12[1] * overshoot_deg))
        for n, v in zip("abc", angles[i]):
            m = PlannedMark(f"t{k}{n}", (float(q[i, 0]), float(q[i, 1])), "calibration", a12,
                            (via,))
            marks.append(m)
            j4[m.id] = float(v)
        placed = np.concatenate([placed, pts[i]])
    return marks, j4
