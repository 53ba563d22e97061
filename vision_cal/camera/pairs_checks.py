"""Whether pose pairs are what their file says (``vision-cal handeye --poses``, issue 40).

A hand-eye fitted to pairs whose units, conventions or motion are not what the file
says can sit on its own scatter and look "ready" (the pairs' residual is its own floor).
These checks read the pairs against each other, never against an assumed noise:

- **repeats**: pairs at the same flange pose are one pose (:func:`distinct_poses`): a
  file of 20 poses written 100 times holds 20 poses' evidence, not 2,000;
- **outliers by consensus** (:func:`consensus`): the closed form of random triples of
  pairs, scored by the pairs that agree best with it (the ``share`` quantile of their
  spread, so up to ``1 - share`` of the pairs may be wrong), the pairs far beyond the
  best triple's agreement left out before the weighted fit (which then tests the rest
  one by one);
- **conventions** (:func:`convention_finding`): the pairs read as another tool may have
  meant them (the other mount, a transform inverted, the target's rotation transposed,
  the flange's yaw of the other sign, a rotation vector in degrees, a yaw in radians);
  one that fits many times better than the reading given names its likely cause;
- **units** (:func:`scale_finding`, :func:`reach_finding`): the target's translations
  against the flange's motion (one scale when both are in one unit: the closed form's
  free scale), and the flange's reach against what a SCARA reaches;
- **degenerate motion** (:func:`null_directions`): a direction of the parameters that no
  pair sees (the Jacobian's singular value at round-off), named with the motion that
  left it free;
- **sizes** (:func:`size_findings`): a camera or a target further from the frame that
  carries it than any mount or robot is.

Each finding is ``(status, sentence)`` for the verdict (the status rule of
:mod:`vision_cal.estimate.verdict`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from scipy.spatial.transform import Rotation

from vision_cal.camera.pairs_geometry import (ClosedForm, closed_form, closed_form_many,
                                              spread_mm, target_points, yaw_deg,
                                              yaw_spread_deg)

#: a length ratio near one of these is a unit written as another (name: the larger unit
#: in mm)
UNIT_FACTORS = {"metres": 1000.0, "inches": 25.4, "centimetres": 10.0}
#: a singular value of the scaled Jacobian below this share of the largest: the direction
#: is not seen at all (round-off of the finite differences sits near 1e-8)
NULL_TOL = 1e-6


@dataclass(frozen=True)
class Distinct:
    """The distinct flange poses of a set of pairs: ``first`` (M,) the index of each
    pose's first pair, ``group`` (N,) which pose each pair is, ``A`` and ``B`` (M, 4, 4)
    one pair a pose (a repeated pose's target averaged over its pairs)."""

    first: np.ndarray
    group: np.ndarray
    A: np.ndarray
    B: np.ndarray


def distinct_poses(A: np.ndarray, B: np.ndarray, tol_mm: float, tol_deg: float) -> Distinct:
    """Pairs whose flange poses agree within ``tol_mm`` and ``tol_deg`` are one pose; its
    target is the mean of theirs (rotations averaged and projected back onto a rotation).
    Without repeats, ``A`` and ``B`` are returned as they are."""
    yaw = yaw_deg(A)
    key = np.column_stack([np.round(A[:, :3, 3] / tol_mm), np.round(((yaw + 180.0) % 360.0)
                                                                     / tol_deg)])
    _, first, group = np.unique(key, axis=0, return_index=True, return_inverse=True)
    group = group.reshape(-1)
    order = np.argsort(first, kind="stable")        # poses in the order the file has them
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    group, first = rank[group], first[order]
    if len(first) == len(A):
        return Distinct(np.arange(len(A)), np.arange(len(A)), A, B)
    m = len(first)
    count = np.bincount(group, minlength=m).astype(float)
    R = np.zeros((m, 3, 3))
    t = np.zeros((m, 3))
    np.add.at(R, group, B[:, :3, :3])
    np.add.at(t, group, B[:, :3, 3])
    U, _, Vt = np.linalg.svd(R)
    D = np.ones((m, 3))
    D[:, 2] = np.sign(np.linalg.det(U @ Vt))
    Bm = np.tile(np.eye(4), (m, 1, 1))
    Bm[:, :3, :3] = (U * D[:, None, :]) @ Vt
    Bm[:, :3, 3] = t / count[:, None]
    return Distinct(first, group, A[first], Bm)


@dataclass(frozen=True)
class Consensus:
    """The pairs the best-agreeing triple's closed form leaves within ``cut`` times its
    agreement level (``inlier`` (N,) bool), each pair's spread from it (``spread_mm``,
    (N,)) and that level (mm)."""

    inlier: np.ndarray
    spread_mm: np.ndarray
    level_mm: float


def _triples(n: int, A: np.ndarray, trials: int, min_yaw_deg: float, seed: int) -> np.ndarray:
    """(T, 3) triples of pairs whose flange turns by ``min_yaw_deg`` at least: every one
    when there are at most ``trials`` of them, else ``trials`` drawn at random."""
    if math.comb(n, 3) <= trials:
        idx = np.array(list(combinations(range(n), 3)))
    else:
        rng = np.random.default_rng(seed)
        idx = np.sort(rng.random((trials, n)).argsort(axis=1)[:, :3], axis=1) if n < 64 \
            else rng.integers(0, n, (trials, 3))
        idx = idx[(idx[:, 0] != idx[:, 1]) & (idx[:, 1] != idx[:, 2]) & (idx[:, 0] != idx[:, 2])]
    y = np.radians(yaw_deg(A))[idx]
    turn = np.degrees(np.abs(np.angle(np.exp(1j * (y - y[:, :1]))))).max(axis=1)
    return idx[turn >= min_yaw_deg]


def consensus(A: np.ndarray, B: np.ndarray, z_mm: float, *, trials: int, min_yaw_deg: float,
              share: float, cut: float, seed: int = 0) -> Consensus:
    """Outliers by consensus (module docstring): triples of pairs whose flange turns by
    ``min_yaw_deg`` at least (``trials`` random ones, or every one where there are fewer),
    each scored by the ``share`` quantile of every pair's spread from its closed form; the
    best one's closed form is fitted again to the pairs within ``cut`` times that level
    (twice). ``trials`` triples leave a clean one unfound with probability
    ``(1 - share^3)^trials`` where only ``share`` of the pairs are right. Linear in the
    pairs (the triples' closed forms in one batch, their spreads a block at a time)."""
    n = len(A)
    h = max(4, int(math.ceil(share * n))) - 1
    idx = _triples(n, A, trials, min_yaw_deg, seed) if n >= 7 else np.zeros((0, 3), int)
    if not len(idx):
        return Consensus(np.ones(n, bool), np.zeros(n), 0.0)
    pts = target_points(B)
    Xs, Ys = closed_form_many(A[idx], B[idx], z_mm)
    best = None
    for a in range(0, len(idx), max(1, 200_000 // n)):      # a block at a time: memory
        r = spread_mm(A, B, Xs[a:a + max(1, 200_000 // n)], Ys[a:a + max(1, 200_000 // n)],
                      pts)
        r[~np.all(np.isfinite(r), axis=1)] = np.inf
        score = np.partition(r, h, axis=1)[:, h]
        k = int(np.argmin(score))
        if best is None or score[k] < best[0]:
            best = (float(score[k]), r[k])
    level, r = best
    if not np.isfinite(level):
        return Consensus(np.ones(n, bool), np.zeros(n), 0.0)
    inl = r <= cut * level
    for _ in range(2):
        if inl.sum() < 4 or yaw_spread_deg(A[inl]) < min_yaw_deg:
            break
        X, Y = closed_form(A[inl], B[inl], z_mm)
        r = spread_mm(A, B, X, Y, pts)
        k = min(h, int(inl.sum()) - 1)
        level = float(np.partition(r[inl], k)[k])
        inl = r <= cut * max(level, 1e-12)
    return Consensus(inl, r, level)


@dataclass(frozen=True)
class Reading:
    """One way of reading the pairs: its moving transforms ``A`` and targets ``B`` (as
    the fit takes them), what it is (``name``) and what a file read so would have meant
    (``cause``)."""

    name: str
    cause: str
    A: np.ndarray
    B: np.ndarray


def _transposed(T: np.ndarray) -> np.ndarray:
    out = T.copy()
    out[:, :3, :3] = np.transpose(T[:, :3, :3], (0, 2, 1))
    return out


def readings(T_robot_flange: np.ndarray, B: np.ndarray, mount: str, *, rvec=None,
             yaw=None) -> list[Reading]:
    """The other ways a tool may have meant the pairs (module docstring), with their
    causes; ``rvec`` (N, 3) the target's rotation vectors and ``yaw`` (N,) the flange's
    yaw as the file wrote them (None: given as matrices)."""
    other = "fixed" if mount == "arm" else "arm"
    inv = np.linalg.inv
    moving = (lambda A: A) if mount == "arm" else inv
    A = moving(T_robot_flange)
    out = [Reading(f"--mount {other}", f"a camera {'standing still' if other == 'fixed' else 'on the flange'} "
                   f"(--mount {other}), or T_robot_flange given inverted (T_flange_robot)",
                   inv(A), B),
           Reading("T_camera_target inverted", "T_camera_target given inverted (the camera's "
                   "pose in the target's frame, T_target_camera)", A, inv(B)),
           Reading("both inverted", "both transforms given inverted (T_flange_robot and "
                   f"T_target_camera), or --mount {other} with T_camera_target inverted",
                   inv(A), inv(B)),
           Reading("target rotation transposed", "the target's rotation transposed (R^T "
                   "given for R: rows and columns swapped)", A, _transposed(B)),
           Reading("flange yaw negated", "the flange's yaw of the opposite sign (its rotation "
                   "transposed)", moving(_transposed(T_robot_flange)), B)]
    if rvec is not None:
        Bd = B.copy()
        Bd[:, :3, :3] = Rotation.from_rotvec(np.radians(np.asarray(rvec, float))).as_matrix()
        out.append(Reading("rvec in degrees", "the target's rotation vector in degrees "
                           "(OpenCV's rvec is in radians)", A, Bd))
    if yaw is not None:
        Ad = T_robot_flange.copy()
        a = np.asarray(yaw, float)          # the numbers written, read as radians
        Ad[:, :2, :2] = np.stack([np.stack([np.cos(a), -np.sin(a)], -1),
                                  np.stack([np.sin(a), np.cos(a)], -1)], 1)
        out.append(Reading("yaw in radians", "the flange's yaw in radians (yaw_deg is in "
                           "degrees)", moving(Ad), B))
    return out


def _agreement(A: np.ndarray, B: np.ndarray, z_mm: float, pts: np.ndarray) -> float:
    """The median spread (mm) of the pairs from their own closed form."""
    if yaw_spread_deg(A) < 1e-6:
        return float("inf")
    X, Y = closed_form(A, B, z_mm)
    r = spread_mm(A, B, X, Y, pts)
    return float(np.median(r)) if np.all(np.isfinite(r)) else float("inf")


def convention_finding(T_robot_flange: np.ndarray, B: np.ndarray, mount: str, z_mm: float,
                       *, ratio: float, sample: int, rvec=None, yaw=None
                       ) -> tuple[str, str] | None:
    """``not reliable`` with the likely cause when another reading of the pairs
    (:func:`readings`) agrees ``ratio`` times better than the one given (median spread of
    the pairs from their closed form; on ``sample`` pairs spread over the file at most);
    None when the given reading is the best or none is clearly better."""
    n = len(B)
    idx = np.unique(np.linspace(0, n - 1, min(n, sample)).round().astype(int))
    T, Bs = T_robot_flange[idx], B[idx]
    rv = None if rvec is None else np.asarray(rvec)[idx]
    yw = None if yaw is None else np.asarray(yaw)[idx]
    pts = target_points(Bs)
    A = T if mount == "arm" else np.linalg.inv(T)
    given = _agreement(A, Bs, z_mm, pts)
    scored = [(_agreement(r.A, r.B, z_mm, pts), r) for r in readings(T, Bs, mount, rvec=rv,
                                                                     yaw=yw)]
    best, r = min(scored, key=lambda s: s[0])
    if not (np.isfinite(best) and best * ratio < given):
        return None
    return ("not reliable",
            f"the pairs do not agree as given (median {given:.3g} mm from one another's "
            f"target) but agree {given / max(best, 1e-12):.0f} times better read as "
            f"{r.name} ({best:.3g} mm): {r.cause}? Correct the file or the options and run "
            "again")


def scale_finding(cf: ClosedForm, *, unit_ratio: float, min_rel: float, n_std: float
                  ) -> tuple[str, str] | None:
    """The target's translations against the flange's motion (the closed form's free
    scale ``cf.scale``): a ratio near a unit factor (``not reliable``, the units named), or
    one off 1 by more than ``min_rel`` and ``n_std`` std (``check``: the board's size
    given to its detector?). None when it is 1 within those, or the motion does not fix
    it."""
    s, sd = cf.scale, cf.scale_std
    if not (np.isfinite(s) and s > 0 and np.isfinite(sd)) or sd > 0.1 * s:
        return None
    if abs(math.log(s)) > math.log(unit_ratio):
        # s > 1: the target's numbers are too small for the flange's, it is in the larger unit
        big = s > 1.0
        f = s if big else 1.0 / s
        name, factor = min(UNIT_FACTORS.items(), key=lambda kv: abs(math.log(f / kv[1])))
        guess = (f" T_robot_flange in {'mm' if big else name} and T_camera_target in "
                 f"{name if big else 'mm'}?" if abs(math.log(f / factor)) < math.log(1.15)
                 else " the two transforms in different units?")
        return ("not reliable",
                f"the flange's motion asks for the target's translations times {s:.4g} (1 "
                f"when both transforms are in one unit):{guess} Give both in one unit "
                "(--units)")
    if abs(s - 1.0) > max(min_rel, n_std * sd):
        return ("check",
                f"the target's translations are {100 * (s - 1):+.2f} % off what the flange's "
                f"motion asks for ({abs(s - 1) / sd:.0f} std): the board's square size given "
                "to its detector off by that much?")
    return None


def reach_finding(T_robot_flange: np.ndarray, *, min_reach_mm: float) -> tuple[str, str] | None:
    """``check`` when the flange never reaches ``min_reach_mm`` from the robot's axis:
    smaller than a SCARA, lengths in centimetres or inches read as mm?"""
    reach = float(np.max(np.hypot(T_robot_flange[:, 0, 3], T_robot_flange[:, 1, 3])))
    if reach >= min_reach_mm:
        return None
    return ("check",
            f"the flange reaches at most {reach:.3g} mm from the robot's axis in these pairs, "
            f"less than any SCARA ({min_reach_mm:g} mm): lengths in centimetres or inches "
            "read as mm? (--units cm or in)")


def null_directions(J: np.ndarray, labels, length_mm: float) -> list[np.ndarray]:
    """The parameter directions (unit vectors in ``labels``' own units) no pair sees: the
    right singular vectors of ``J`` (rows: residuals; columns: ``labels``, deg or mm),
    its rotation columns taken as mm at ``length_mm`` from their axis, whose singular value
    is below :data:`NULL_TOL` of the largest."""
    c = np.array([length_mm * math.pi / 180.0 if lab.endswith("_deg") else 1.0
                  for lab in labels])
    Js = J / c
    _, s, Vt = np.linalg.svd(Js, full_matrices=False)
    out = []
    for k in np.flatnonzero(s < NULL_TOL * s[0]):
        v = Vt[k] / c                  # back to the labels' units
        out.append(v / np.linalg.norm(v))
    return out


def null_sentence(v: np.ndarray, labels, T_robot_flange: np.ndarray, scale_mm: float
                  ) -> tuple[list[str], str]:
    """The labels a null direction ``v`` moves (its components above a tenth of the
    largest, in mm at ``scale_mm``) and the sentence naming it with the motion that left
    it free."""
    c = np.array([scale_mm * math.pi / 180.0 if lab.endswith("_deg") else 1.0
                  for lab in labels])
    w = np.abs(v * c)
    moved = [lab for lab, x in zip(labels, w) if x > 0.1 * w.max()]
    xy = T_robot_flange[:, :2, 3]
    stay = float(np.max(np.linalg.norm(xy - xy.mean(axis=0), axis=1)))
    why = (f"the flange stood at one place (every pair within {stay:.3f} mm of it) while "
           "only joint 4 turned: a turn of the camera about the flange's axis and of the "
           "target about the same axis change no pair; move the arm (joints 1 and 2) "
           "between pairs" if stay < 1.0 else
           "the pairs' motion leaves it free: turn joint 4 at several places of the arm")
    return moved, (f"the pairs do not fix {', '.join(moved)} (they move together without "
                   f"changing any pair): {why}")


def size_findings(X: np.ndarray, Y: np.ndarray, B: np.ndarray, mount: str, *,
                  max_mount_mm: float, max_robot_mm: float, z_given: bool
                  ) -> list[tuple[str, str]]:
    """``not reliable`` where the fit puts the camera or the target further from the frame
    carrying it than a mount (``max_mount_mm``: on the flange) or a workcell
    (``max_robot_mm``: from the robot's base) can be, or the camera further from its
    target than that."""
    if mount == "arm":
        parts = [("the camera", "the flange", X, max_mount_mm),
                 ("the target", "the robot's base", Y, max_robot_mm)]
    else:
        parts = [("the camera", "the robot's base", X, max_robot_mm),
                 ("the target", "the flange", Y, max_mount_mm)]
    out = []
    hint = ("the target's height (--z-mm, target_z_mm) or the units wrong?" if z_given
            else "the units wrong?")
    for what, frame, T, limit in parts:
        d = float(np.linalg.norm(T[:3, 3]))
        if not d <= limit:
            out.append(("not reliable", f"{what} would sit {d:.4g} mm from {frame}, beyond "
                                        f"what any {'mount' if limit == max_mount_mm else 'workcell'}"
                                        f" holds ({limit:g} mm): {hint}"))
    dist = float(np.median(np.linalg.norm(B[:, :3, 3], axis=1)))
    if not dist <= max_robot_mm:
        out.append(("not reliable", f"the camera stands {dist:.4g} mm from the target "
                                    f"(median over the pairs), beyond {max_robot_mm:g} mm: "
                                    "the units wrong?"))
    return out
