"""Calibration plans: which poses the robot marks, in which order, from which side.

``PlannedMark.via_deg`` are overshoot via points the arm passes just before the mark, so
that each joint arrives from the side ``approach`` says (the sign of its last motion).

- :func:`paper_plan`: the seed paper's five marks (joint 1 +-20 deg, joint 2 +-60 deg).
- :func:`informative_plan`: many marks spread over the reachable sheet in both elbows,
  each joint approaching from + on half of them and from - on the other half, one
  overshoot via point per mark; identifies backlash, gear scale and cyclic errors (see
  docs/plans.md). Sheet positions use the nominal model (mm, sheet frame). With
  ``n_repeats`` it also returns to a few of its poses (:func:`add_repeats`): the robot's
  repeatability measured, not assumed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import forward, inverse
from vision_cal.model.motion import SPEED_DEG_S, approach_signs


@dataclass(frozen=True)
class PlannedMark:
    id: str
    joints_deg: tuple[float, float]
    role: str = "calibration"
    approach: tuple[int, int] = (1, 1)
    via_deg: tuple[tuple[float, float], ...] = ()
    repeat_of: str | None = None   # the mark whose pose this one returns to (add_repeats)

    def to_json(self) -> dict:
        """The mark's entry of session.json (what a real user knows)."""
        d = {"id": self.id, "joints_deg": [float(self.joints_deg[0]), float(self.joints_deg[1])],
             "approach": [int(self.approach[0]), int(self.approach[1])], "role": self.role}
        if self.repeat_of is not None:
            d["repeat_of"] = self.repeat_of
        return d


#: how far a repeated mark lands from its twin (mm): two dots of a pen cannot share a spot,
#: so the return is commanded this far off (as ISO 9283's visits in design/iso9283.py); over
#: it the joints differ by about 0.6 deg, over which a systematic error barely changes
REPEAT_SHIFT_MM = 6.0
#: marks drawn later than their twin (in drawing order): the arm leaves and comes back
REPEAT_GAP = 3


def add_repeats(plan: list[PlannedMark], nominal, sheet, n_repeats: int, *,
                min_separation_mm: float = 10.0,
                clearance_mm: float = 18.6, overshoot_deg: float = 3.0,
                joint_limits_deg=((-150.0, 150.0), (-150.0, 150.0))) -> list[PlannedMark]:
    """The plan with ``n_repeats`` calibration marks drawn a second time (docs/plans.md).

    Twins are spread along the drawing order; each repeat ``r00..`` returns to its twin's
    pose, from the same side (same approach and overshoot), ``REPEAT_SHIFT_MM`` off so the
    two dots are apart (the first of eight directions whose spot keeps ``clearance_mm`` from
    the edges and markers and ``min_separation_mm`` from every other mark), and is drawn
    ``REPEAT_GAP`` marks after it. Its ``repeat_of`` names the twin: the pair's residuals
    differ by measurement noise and twice the robot's repeatability alone
    (``vision_cal.estimate.verdict.repeatability_from_repeats``). A twin with no such spot
    is replaced by another calibration mark; fewer than asked come back only when none is
    left."""
    if n_repeats <= 0:
        return list(plan)
    # twins with REPEAT_GAP marks after them first (then the last ones, returned to at the end)
    cal = [k for k, m in enumerate(plan) if m.role == "calibration" and m.repeat_of is None]
    cal = ([k for k in cal if k < len(plan) - REPEAT_GAP]
           + [k for k in cal if k >= len(plan) - REPEAT_GAP])
    if not cal:
        return list(plan)
    early = sum(k < len(plan) - REPEAT_GAP for k in cal) or len(cal)
    spread = [cal[int(i)] for i in np.unique(
        np.linspace(0, early - 1, min(n_repeats, early)).round().astype(int))]
    picks = spread + [k for k in cal if k not in spread]   # the rest stand in for a skipped one
    lim = np.asarray(joint_limits_deg, dtype=float).reshape(2, 2)
    taken = forward(nominal, np.array([m.joints_deg for m in plan]))
    out = list(plan)
    n_done = 0
    for k in picks:
        if n_done == n_repeats:
            break
        m = plan[k]
        q = np.asarray(m.joints_deg, float)
        p = forward(nominal, q[None])[0]
        elbow = 1 if np.sin(np.radians(q[1] + nominal.z2_deg)) > 0 else -1
        for a in np.radians(np.arange(0.0, 360.0, 45.0)):
            xy = p + REPEAT_SHIFT_MM * np.array([np.cos(a), np.sin(a)])
            others = np.delete(taken, k, axis=0)
            if sheet_clearance_mm(sheet, xy[None])[0] < clearance_mm or (
                    len(others) and np.min(np.linalg.norm(others - xy, axis=1))
                    < min_separation_mm):
                continue
            q2 = inverse(nominal, xy[None], elbow=elbow, on_fail="nan")[0]
            q2 = q2 + 360.0 * np.round((q - q2) / 360.0)     # the same turn as the twin
            if not np.all(np.isfinite(q2)) or np.any(np.abs(q2 - q) > 5.0) or np.any(
                    q2 - overshoot_deg - 1.0 < lim[:, 0]) or np.any(
                    q2 + overshoot_deg + 1.0 > lim[:, 1]):
                continue
            s = m.approach
            via = (float(q2[0] - s[0] * overshoot_deg), float(q2[1] - s[1] * overshoot_deg))
            rep = PlannedMark(f"r{n_done:02d}", (float(q2[0]), float(q2[1])), "calibration", s,
                              (via,), repeat_of=m.id)
            at = min(out.index(m) + REPEAT_GAP, len(out))
            out.insert(at, rep)
            taken = np.vstack([taken, xy])
            n_done += 1
            break
    return out


def paper_plan() -> list[PlannedMark]:
    """The seed paper's plan: zero, joint 1 at +-20 deg, joint 2 at +-60 deg.

    From home (0, 0) the joints move directly, so each approach is the sign of the move
    (a joint that did not move keeps +1).
    """
    poses = [("c00", (0.0, 0.0)), ("j1p", (20.0, 0.0)), ("j1n", (-20.0, 0.0)),
             ("j2p", (0.0, 60.0)), ("j2n", (0.0, -60.0))]
    signs = approach_signs([q for _, q in poses])
    return [PlannedMark(mid, q, "calibration", (int(s[0]), int(s[1])))
            for (mid, q), s in zip(poses, signs)]


# --------------------------------------------------------------------------------------
# Informative plan
# --------------------------------------------------------------------------------------

def _polygon_distance_mm(xy: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance (N,) from points ``xy`` (N, 2) to a convex polygon ``poly`` (V, 2); 0 inside."""
    a = poly
    b = np.roll(poly, -1, axis=0)
    ab = b - a                                              # (V, 2)
    ap = xy[:, None, :] - a[None, :, :]                     # (N, V, 2)
    t = np.clip(np.einsum("nvk,vk->nv", ap, ab) / np.einsum("vk,vk->v", ab, ab), 0.0, 1.0)
    d = np.linalg.norm(ap - t[..., None] * ab[None], axis=2).min(axis=1)
    cross = ab[None, :, 0] * ap[..., 1] - ab[None, :, 1] * ap[..., 0]   # (N, V)
    inside = np.all(cross >= 0, axis=1) | np.all(cross <= 0, axis=1)
    return np.where(inside, 0.0, d)


def sheet_clearance_mm(sheet, xy_mm) -> np.ndarray:
    """Clearance (N,) of sheet points from the paper edge and every ArUco square (mm).

    Negative outside the paper; 0 on or inside a marker.
    """
    xy = np.atleast_2d(np.asarray(xy_mm, dtype=float))
    x0, y0, x1, y1 = sheet.extent_mm
    edge = np.minimum.reduce([xy[:, 0] - x0, x1 - xy[:, 0], xy[:, 1] - y0, y1 - xy[:, 1]])
    out = edge
    for m in sheet.markers:
        poly = np.asarray(m.corners_mm, dtype=float)
        # a point farther from the marker's bounding box than its clearance so far keeps
        # it (the box is never farther than the square): the exact distance only for the
        # others (40,000 candidates x 24 markers: 0.45 -> 0.05 s)
        gap = np.maximum(np.maximum(poly.min(axis=0) - xy, xy - poly.max(axis=0)), 0.0)
        near = np.flatnonzero(np.hypot(gap[:, 0], gap[:, 1]) <= out + 1e-6)
        out[near] = np.minimum(out[near], _polygon_distance_mm(xy[near], poly))
    return out


def _balanced_signs(q_deg: np.ndarray, elbow: np.ndarray, rng, tries: int = 400) -> np.ndarray:
    """Approach signs (N, 2): per joint half +1 and half -1, decorrelated from the poses.

    Among ``tries`` random balanced assignments, keep the one whose largest absolute
    correlation with q1, q2, the elbow and the other joint's signs is smallest.
    """
    n = len(q_deg)
    base = np.where(np.arange(n) < (n + 1) // 2, 1.0, -1.0)
    if n < 2:
        return np.ones((n, 2))
    cov = np.column_stack([q_deg, elbow]).astype(float)
    cov = cov - cov.mean(axis=0)
    norms = np.linalg.norm(cov, axis=0)
    cov = cov[:, norms > 0] / norms[norms > 0]
    best, best_score = None, np.inf
    for _ in range(tries):
        s = np.column_stack([rng.permutation(base), rng.permutation(base)])
        sc = s - s.mean(axis=0)
        sc = sc / np.maximum(np.linalg.norm(sc, axis=0), 1e-12)
        score = max(np.abs(sc.T @ cov).max() if cov.size else 0.0, abs(sc[:, 0] @ sc[:, 1]))
        if score < best_score:
            best, best_score = s, score
    return best.astype(int)


def informative_plan(nominal, sheet, *, n_calibration: int = 30, n_validation: int = 8,
                     pen_diameter_mm: float = 1.2, min_separation_mm: float = 10.0,
                     joint_limits_deg=((-150.0, 150.0), (-150.0, 150.0)), rng=None,
                     margin_mm: float = 3.0, safety_mm: float = 15.0,
                     overshoot_deg: float = 3.0, min_sin_elbow: float = 0.2,
                     home_deg=(0.0, 0.0), n_candidates: int = 40000, elbows=(1, -1),
                     speed_deg_s=SPEED_DEG_S, n_repeats: int = 0) -> list[PlannedMark]:
    """A plan that identifies the base model *and* backlash, gear scale and cyclic errors.

    Poses are drawn uniformly in joint space, kept where the pen (nominal model) lands on
    the paper at least ``pen_diameter_mm / 2 + margin_mm + safety_mm`` from the edges and
    from every ArUco square (the safety absorbs a nominal model tens of mm / several deg
    off), inside ``joint_limits_deg`` with room for the overshoot, and away from the
    stretched-arm singularity (``|sin(q2 + z2)| >= min_sin_elbow``). A greedy max-min
    design in normalised joint space then picks ``n_calibration + n_validation`` poses,
    alternating the elbow (sign of sin(q2 + z2)) so both solutions are used, at least
    ``min_separation_mm`` apart on the sheet. Validation marks are a random subset of the
    design (both elbows, never the first extreme picks), so they are spread like the
    calibration marks.

    Each joint's approach sign is +1 for half the marks of each role and -1 for the other
    half, chosen to be uncorrelated with the joint angles, the elbow and the other joint.
    Every mark gets one overshoot via point ``q - approach * overshoot_deg``, so both
    joints make their last motion (``overshoot_deg``) from the planned side.

    ``elbows`` limits the poses to those elbow solutions (a robot that may only use one);
    ``speed_deg_s`` are the joint speeds the drawing order is timed with.

    Marks are drawn in a nearest-neighbour tour (in joint travel time) from ``home_deg``;
    ids are ``c00..`` and ``v00..`` in drawing order. ``n_repeats``: that many calibration
    marks drawn again (:func:`add_repeats`, ids ``r00..``). Deterministic for a given
    ``rng``. Raises :class:`VisionCalError` when the sheet does not hold enough such poses.
    """
    rng = np.random.default_rng(rng)
    n_total = int(n_calibration) + int(n_validation)
    if n_calibration < 0 or n_validation < 0 or n_total == 0:
        raise VisionCalError(f"need at least one mark, got n_calibration={n_calibration}, "
                             f"n_validation={n_validation}")
    lim = np.asarray(joint_limits_deg, dtype=float).reshape(2, 2)
    lo, hi = lim[:, 0] + overshoot_deg + 1.0, lim[:, 1] - overshoot_deg - 1.0
    if np.any(hi <= lo):
        raise VisionCalError(f"joint limits {lim.tolist()} leave no room for a "
                             f"{overshoot_deg} deg overshoot", field="joint_limits_deg")
    clearance = pen_diameter_mm / 2 + margin_mm + safety_mm
    q, xy, elbow = _candidate_poses(nominal, sheet, lo, hi, rng, n_candidates, n_total,
                                    clearance, min_sin_elbow, elbows)
    chosen = _max_min_design(q, xy, elbow, lo, hi, n_total, min_separation_mm)
    role = _validation_roles(elbow[chosen], n_total, int(n_validation), rng)
    qs = q[chosen]
    els = elbow[chosen]
    signs = np.empty((n_total, 2), dtype=int)
    for r in ("calibration", "validation"):
        idx = np.flatnonzero(role == r)
        if len(idx):
            signs[idx] = _balanced_signs(qs[idx], els[idx], rng)
    order = _drawing_order(qs, home_deg, speed_deg_s)
    out = _planned_marks(qs, role, signs, order, overshoot_deg)
    return add_repeats(out, nominal, sheet, n_repeats, min_separation_mm=min_separation_mm,
                       clearance_mm=clearance,
                       overshoot_deg=overshoot_deg, joint_limits_deg=lim)


def _candidate_poses(nominal, sheet, lo, hi, rng, n_candidates: int, n_total: int,
                     clearance: float, min_sin_elbow: float, elbows):
    """``(q, xy, elbow)`` of the poses drawn uniformly in ``[lo, hi]`` whose pen (nominal
    model) lands ``clearance`` mm clear of the sheet's edges and markers, away from the
    stretched arm and with an allowed elbow; refuses fewer than ``n_total`` of them."""
    q = lo + (hi - lo) * rng.random((int(n_candidates), 2))
    xy = forward(nominal, q)
    ok = sheet_clearance_mm(sheet, xy) >= clearance
    sin_el = np.sin(np.radians(q[:, 1] + nominal.z2_deg))
    ok &= np.abs(sin_el) >= min_sin_elbow
    ok &= np.isin(np.where(sin_el > 0, 1, -1), np.asarray(elbows, dtype=int))
    q, xy, elbow = q[ok], xy[ok], np.where(sin_el[ok] > 0, 1, -1)
    if len(q) < n_total:
        raise VisionCalError(
            f"only {len(q)} of {n_candidates} sampled poses put the pen on the sheet "
            f"{clearance:.1f} mm clear of its edges and markers (nominal model): the sheet "
            f"is out of reach or the nominal base/zeros are wrong", field="sheet")
    return q, xy, elbow


def _max_min_design(q, xy, elbow, lo, hi, n_total: int, min_separation_mm: float) -> np.ndarray:
    """Indices of ``n_total`` candidates picked greedily max-min in normalised joint space,
    starting at the most extreme pose, alternating the elbows, each at least
    ``min_separation_mm`` from the others on the sheet; refuses when they do not fit."""
    u = (q - lo) / (hi - lo)
    d_min = np.full(len(q), np.inf)
    alive = np.ones(len(q), dtype=bool)
    chosen: list[int] = []
    # start at the candidate farthest from the centre of joint space (an extreme pose)
    first = int(np.argmax(np.linalg.norm(u - 0.5, axis=1)))
    while len(chosen) < n_total:
        if chosen:
            counts = {e: sum(elbow[c] == e for c in chosen) for e in (1, -1)}
            want = min(counts, key=lambda e: counts[e])
            pool = alive & (elbow == want)
            if not pool.any():
                pool = alive
            if not pool.any():
                raise VisionCalError(
                    f"only {len(chosen)} poses fit {min_separation_mm} mm apart on the reachable "
                    f"part of the sheet, {n_total} were asked for", field="sheet")
            pick = int(np.flatnonzero(pool)[np.argmax(d_min[pool])])
        else:
            pick = first
        chosen.append(pick)
        d_min = np.minimum(d_min, np.linalg.norm(u - u[pick], axis=1))
        alive &= np.linalg.norm(xy - xy[pick], axis=1) >= min_separation_mm
    return np.array(chosen)


def _validation_roles(els, n_total: int, n_validation: int, rng) -> np.ndarray:
    """Each design pose's role: validation for a random subset of ``n_validation`` (both
    elbows ``els``, skipping the first extreme picks), calibration for the rest."""
    role = np.array(["calibration"] * n_total, dtype=object)
    if n_validation:
        skip = min(4, max(0, n_total - n_validation))
        cand = np.arange(skip, n_total)
        pos = cand[els[cand] > 0]
        neg = cand[els[cand] < 0]
        n_pos = min(len(pos), (n_validation + 1) // 2)
        n_neg = min(len(neg), n_validation - n_pos)
        n_pos = min(len(pos), n_validation - n_neg)
        val = np.concatenate([rng.choice(pos, n_pos, replace=False),
                              rng.choice(neg, n_neg, replace=False)]).astype(int)
        if len(val) < n_validation:
            rest = np.setdiff1d(np.arange(n_total), val)
            val = np.concatenate([val, rng.choice(rest, n_validation - len(val), replace=False)])
        role[val] = "validation"
    return role


def _drawing_order(qs, home_deg, speed_deg_s) -> list[int]:
    """The poses' drawing order: nearest neighbour in joint travel time from home."""
    speed = np.asarray(speed_deg_s, dtype=float)
    order, cur = [], np.asarray(home_deg, dtype=float)
    left = list(range(len(qs)))
    while left:
        cost = np.max(np.abs(qs[left] - cur) / speed, axis=1)
        k = left.pop(int(np.argmin(cost)))
        order.append(k)
        cur = qs[k]
    return order


def _planned_marks(qs, role, signs, order, overshoot_deg: float) -> list[PlannedMark]:
    """The marks in drawing order, ids ``c00..`` / ``v00..`` per role, each with its one
    overshoot via point ``q - approach * overshoot_deg``."""
    out: list[PlannedMark] = []
    counter = {"calibration": 0, "validation": 0}
    for k in order:
        r = str(role[k])
        mid = f"{'c' if r == 'calibration' else 'v'}{counter[r]:02d}"
        counter[r] += 1
        qk = (float(qs[k, 0]), float(qs[k, 1]))
        s = (int(signs[k, 0]), int(signs[k, 1]))
        via = (float(qk[0] - s[0] * overshoot_deg), float(qk[1] - s[1] * overshoot_deg))
        out.append(PlannedMark(mid, qk, r, s, (via,)))
    return out
