"""The synthetic world's robot: where the pen marks really land, and where the arm is.

Frames and units: sheet frame S (x right, y up, mm); joint angles in degrees at the API.

A plan (``list[PlannedMark]``) is followed from ``home_deg``: for each mark the arm passes
its via points, then stops on the commanded joints and puts the pen down once. A *joint
source* says which joint angles the links really reached and from which side each joint
arrived (the sign of its last motion); the default, :func:`kinematic_joints`, is a perfect
controller (links reach the command exactly; arrival signs follow the motion through the
via points, a joint that did not move keeps its previous sign, starting at +1). A simulated
controller can be plugged in with the same signature::

    joint_source(plan, home_deg) -> (link_q_deg (N, 2), approach (N, 2))

:func:`simulated_world` builds one from :mod:`vision_cal.world.simulate` (trajectory, sliding-mode
or PD controller, dynamics, gear play).

The true mark is ``truth.pen_mm(link_q_deg, approach)`` (every hidden effect of the
world's own :class:`~vision_cal.world.truth_model.TrueRobot` included, never the
estimator's model) plus isotropic Gaussian noise of ``repeatability_mm`` per axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.world.truth_model import TrueRobot
from vision_cal.world.simulate import simulate_plan

JointSource = Callable[[Sequence, Sequence[float]], tuple[np.ndarray, np.ndarray]]

#: (width_mm, height_above_sheet_mm) of the link boxes drawn when the arm is in a photo
LINK1_BOX = (60.0, 150.0)
LINK2_BOX = (40.0, 100.0)


@dataclass(frozen=True)
class WorldMarks:
    """Where the marks of a plan really are.

    ``ids`` (N,) mark ids in drawing order; ``xy_mm`` (N, 2) true mark centres in the
    sheet frame; ``approach`` (N, 2) the sign (+1/-1) each joint really arrived from;
    ``q_deg`` (N, 2) the joint angles the links really reached (commanded frame).
    """

    ids: tuple[str, ...]
    xy_mm: np.ndarray
    approach: np.ndarray
    q_deg: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


def kinematic_joints(plan, home_deg=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A perfect controller: (link_q_deg (N, 2), approach (N, 2)) for ``plan``.

    The links reach each command exactly. Each joint's arrival sign is the sign of its
    last motion on the way home -> vias -> mark -> vias -> next mark ...; a joint that did
    not move keeps its previous sign (starting at +1).
    """
    prev = np.asarray(home_deg, dtype=float).reshape(2)
    sign = np.ones(2)
    q = np.empty((len(plan), 2))
    s = np.empty((len(plan), 2))
    for i, m in enumerate(plan):
        for p in (*m.via_deg, m.joints_deg):
            p = np.asarray(p, dtype=float).reshape(2)
            moved = np.sign(p - prev)
            sign = np.where(moved != 0, moved, sign)
            prev = p
        q[i] = prev
        s[i] = sign
    return q, s


def _true(truth) -> TrueRobot:
    if not isinstance(truth, TrueRobot):
        raise VisionCalError(f"expected the world's TrueRobot, got {type(truth).__name__}",
                             field="truth")
    return truth


def joint4_sides(j4_deg, start_deg: float = 0.0) -> np.ndarray:
    """The side (N,) +-1 joint 4 really arrived from at each of ``j4_deg`` (N,) visited in
    order from ``start_deg``: the sign of its last motion, kept when it did not move
    (starting at +1). The world's own tracking (not the estimator's rule)."""
    prev, side, out = float(start_deg), 1.0, []
    for v in np.asarray(j4_deg, dtype=float):
        if v != prev:
            side = 1.0 if v > prev else -1.0
        out.append(side)
        prev = v
    return np.array(out)


def draw_marks(truth: TrueRobot, plan, *, home_deg=(0.0, 0.0), repeatability_mm: float = 0.01,
               joint_source: JointSource | None = None, rng=None,
               joint4_deg=None) -> WorldMarks:
    """Let the true robot follow ``plan`` and return where each pen mark really is.

    ``truth``: the true robot (:class:`TrueRobot`: base params and hidden effects); ``plan``: list of
    ``PlannedMark``; ``joint_source``: see the module docstring (default
    :func:`kinematic_joints`); ``rng``: seed or Generator for the repeatability noise;
    ``joint4_deg`` (N,): joint 4's command at each mark (None: 0), reached kinematically
    (its effects and the tool are the truth's).
    """
    if repeatability_mm < 0 or not np.isfinite(repeatability_mm):
        raise VisionCalError(f"expected a non-negative number, got {repeatability_mm!r}",
                             field="repeatability_mm")
    if not len(plan):
        raise VisionCalError("the plan has no marks", field="plan")
    truth = _true(truth)
    rng = np.random.default_rng(rng)
    source = joint_source or kinematic_joints
    q, s = source(plan, home_deg)
    q = np.asarray(q, dtype=float)
    s = np.asarray(s, dtype=float)
    n = len(plan)
    if q.shape != (n, 2) or s.shape != (n, 2):
        raise VisionCalError(f"joint source returned shapes {q.shape}, {s.shape}; "
                             f"expected ({n}, 2) each", field="joint_source")
    s = np.where(s < 0, -1.0, 1.0)
    # drawing time: 0 at the first mark, 1 at the last (what a drift follows)
    t = np.linspace(0.0, 1.0, n) if n > 1 else np.zeros(n)
    if joint4_deg is None:
        xy = truth.pen_mm(q, s, t=t)
    else:
        j4 = np.asarray(joint4_deg, dtype=float).reshape(n)
        xy = truth.pen_mm(np.column_stack([q, j4]), np.column_stack([s, joint4_sides(j4)]), t=t)
    if repeatability_mm > 0:
        xy = xy + rng.normal(0.0, repeatability_mm, size=xy.shape)
    return WorldMarks(tuple(m.id for m in plan), xy, s.astype(int), q)


def simulated_world(truth: TrueRobot, *, controller: str = "smc", rng=None,
                    **sim_kwargs) -> tuple[JointSource, TrueRobot]:
    """A joint source that runs the simulated controller, and the model to predict with.

    The truth's ``joint_backlash`` effects become the simulator's gear play (the links
    really lag, and the simulator reports the side in contact), so they are taken out of
    the returned model; every other effect stays in it and acts on the reached link angles.
    ``sim_kwargs`` go to :func:`vision_cal.world.simulate.simulate_plan`.
    """
    truth = _true(truth)
    band = np.asarray(truth.backlash_deg, dtype=float)
    rng = np.random.default_rng(rng)

    def source(plan, home_deg):
        r = simulate_plan(plan, home_deg=home_deg, backlash_deg=tuple(band),
                          controller=controller, rng=rng, **sim_kwargs)
        source.report = controller_report(r, controller)
        return r.link_deg, r.approach

    source.report = None
    return source, truth.without_backlash()


def controller_report(r, controller: str) -> dict:
    """How the simulated controller did: tracking error and settle residual (degrees)."""
    return {"controller": controller,
            "tracking_rms_deg": np.asarray(r.tracking_rms_deg).tolist(),
            "tracking_max_deg": np.asarray(r.tracking_max_deg).tolist(),
            "settle_residual_max_deg": np.abs(r.settle_residual_deg).max(axis=0).tolist(),
            "duration_s": float(r.duration_s)}


def arm_points(truth: TrueRobot, q_deg) -> np.ndarray:
    """(3, 2) base, elbow and pen of the true arm at commanded joints ``q_deg`` (2,), in
    printed sheet coordinates (the frame :meth:`TrueRobot.T_render` photographs)."""
    truth = _true(truth)
    pts = truth.arm_points(truth.link_deg(np.reshape(q_deg, (1, 2))))[0]
    return truth.to_sheet(pts)


def arm_boxes(model, q_deg, *, link1=LINK1_BOX, link2=LINK2_BOX) -> list[tuple]:
    """Link boxes ``(p0_xy_mm, p1_xy_mm, width_mm, height_mm)`` of the arm at ``q_deg``.

    Link 1 runs from the base to the elbow, link 2 from the elbow to the pen; ``height_mm``
    is how far above the sheet the box's top is. For ``Photographer.photograph(arm=...)``.
    """
    base, elbow, pen = arm_points(model, q_deg)
    return [(tuple(base), tuple(elbow), float(link1[0]), float(link1[1])),
            (tuple(elbow), tuple(pen), float(link2[0]), float(link2[1]))]


def parking_pose(truth: TrueRobot, extent_mm, *, rng=None, inset_mm: float = 40.0,
                 tries: int = 200) -> np.ndarray:
    """Joints (2,) deg that park the pen over the sheet, ``inset_mm`` inside its edges.

    Picks random commanded joints until the true pen lies over the paper (so the arm hides
    part of it in a photo). Falls back to the reachable point closest to the sheet centre.
    """
    rng = np.random.default_rng(rng)
    x0, y0, x1, y1 = extent_mm
    lo = np.array([x0 + inset_mm, y0 + inset_mm])
    hi = np.array([x1 - inset_mm, y1 - inset_mm])
    q = rng.uniform([-180.0, -150.0], [180.0, 150.0], size=(tries, 2))
    xy = _true(truth).pen_mm(q)
    ok = np.flatnonzero(np.all((xy >= lo) & (xy <= hi), axis=1))
    if ok.size:
        return q[ok[0]]
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    return q[int(np.argmin(np.linalg.norm(xy - centre, axis=1)))]
