"""Which dot is which planned mark.

1. Dots of all photos are grouped into physical dots by their sheet position (a dot seen in
   several photos is one dot). Each group knows in which photos it was seen.
2. Series: a mark can only be a dot never seen in a photo taken before the mark was drawn
   (``images[k].marks`` lists what is on the sheet). When exactly one new mark and one new
   dot appear in a photo, they are each other.
3. Otherwise (a single photo of the finished sheet, several marks added between photos) the
   dots are matched to the plan through the robot model. The nominal model may be off by
   ~10 deg in the joint zeros and ~100 mm in the base: a vote over joint-zero offsets
   (0.5 deg grid) and base translations (5 mm bins) proposes hypotheses, each refined by
   Hungarian assignment (``scipy.optimize.linear_sum_assignment``) and the closed-form base
   fit ``vision_cal.model.linear.linear_init``. Already identified marks (anchors) are
   kept. The result is accepted only when one assignment explains the dots clearly better
   than any other; a mark with two dots inside the gate is left out, with a reason.

Positions are sheet mm; joint angles degrees.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from vision_cal.model.linear import explain_degeneracy, linear_init
from vision_cal.config import DEFAULT
from vision_cal.errors import CalibrationError, Failure
from vision_cal.model.kinematics import ScaraParams, forward
from vision_cal.model.rms import rms as rms_of
from vision_cal.model.rms import rms_2d


@dataclass(frozen=True)
class DotGroup:
    """One physical dot: per-photo estimates ``xy_mm`` (n, 2), ``cov_mm2`` (n, 2, 2), the
    session image index of each, and the per-photo dot index."""

    xy_mm: np.ndarray
    cov_mm2: np.ndarray
    images: tuple[int, ...]
    dot_index: tuple[int, ...]

    @property
    def mean_mm(self) -> np.ndarray:
        return self.xy_mm.mean(axis=0)


@dataclass(frozen=True)
class Match:
    """:func:`match_to_plan`'s assignment: ``pairs`` (mark index, dot index), the base
    parameters it fits (``params``) and the residual RMS (mm) under them."""

    pairs: tuple[tuple[int, int], ...]
    params: ScaraParams
    rms_mm: float


@dataclass(frozen=True)
class NoMatch(Failure):
    """No assignment of the dots to the plan could be told, and why (falsy; reading a
    :class:`Match`'s attribute from it raises with the reason)."""

    reason: str


def group_dots(per_image, *, tol_mm: float) -> list[DotGroup]:
    """Group dots across photos. ``per_image``: list of (image_index, xy (K, 2), cov (K, 2, 2))."""
    groups: list[dict] = []
    for k, xy, cov in per_image:
        xy = np.asarray(xy, float).reshape(-1, 2)
        means = np.array([np.mean(g["xy"], axis=0) for g in groups]).reshape(-1, 2)
        used = set()
        for j in range(len(xy)):
            best = -1
            if len(means):
                d = np.hypot(*(means - xy[j]).T)
                order = np.argsort(d)
                for gi in order[:3]:
                    if d[gi] > tol_mm:
                        break
                    if k not in groups[gi]["img"] and gi not in used:
                        best = int(gi)
                        break
            if best < 0:
                groups.append({"xy": [], "cov": [], "img": [], "idx": []})
                best = len(groups) - 1
            used.add(best)
            g = groups[best]
            g["xy"].append(xy[j])
            g["cov"].append(np.asarray(cov[j], float))
            g["img"].append(k)
            g["idx"].append(j)
    return [DotGroup(np.array(g["xy"]), np.array(g["cov"]), tuple(g["img"]), tuple(g["idx"]))
            for g in groups]


def combine(group: DotGroup, *, common_fraction: float | None = None
            ) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted mean (2,), its covariance (2, 2) and the spread (RMS distance of the
    photos' estimates to the mean, mm).

    The covariance of the mean of n photos is ``inv(sum C_i^-1) * (1 + rho (n - 1))``
    (errors correlated by ``rho = common_fraction`` between photos), inflated further when
    the photos disagree more than their covariances say. ``common_fraction`` None: config
    ``association.common_fraction`` (the share of a photo's error variance that repeats in
    every photo of the same dot) of ``DEFAULT``.
    """
    if common_fraction is None:
        common_fraction = DEFAULT.association.common_fraction
    W = np.array([np.linalg.inv(c + np.eye(2) * 1e-12) for c in group.cov_mm2])
    Wsum = W.sum(axis=0)
    n = len(group.cov_mm2)
    cov = np.linalg.inv(Wsum)
    xy = cov @ np.einsum("nij,nj->i", W, group.xy_mm)
    cov = cov * (1.0 + common_fraction * (n - 1))
    d = group.xy_mm - xy
    spread = rms_2d(d)
    if n > 1:
        chi2 = float(np.einsum("ni,nij,nj->", d, W, d))
        f = chi2 / (2 * (n - 1))
        if f > 1:
            cov = cov * f
    return xy, cov, spread


@dataclass(frozen=True)
class Assignment:
    """``mark_to_group``: mark id -> group index; ``refused``: mark id -> reason;
    ``how``: mark id -> "series" | "model"; ``params``: the base fit used (or None);
    ``warnings``: one-line notes."""

    mark_to_group: dict
    refused: dict = field(default_factory=dict)
    how: dict = field(default_factory=dict)
    params: ScaraParams | None = None
    warnings: tuple[str, ...] = ()


def _plausible(p: ScaraParams, nominal: ScaraParams, max_zero_deg, max_base_mm) -> bool:
    dz = [((a - b + 180) % 360) - 180 for a, b in zip(p.joint_zero_deg, nominal.joint_zero_deg)]
    db = np.hypot(p.base_x_mm - nominal.base_x_mm, p.base_y_mm - nominal.base_y_mm)
    dl = max(abs(p.L1_mm / nominal.L1_mm - 1), abs(p.L2_mm / nominal.L2_mm - 1))
    return (max(abs(d) for d in dz) <= 1.5 * max_zero_deg and db <= 1.5 * max_base_mm
            and dl <= 0.15)


def _fit(q, xy, pairs):
    mi = np.array([i for i, _ in pairs])
    dj = np.array([j for _, j in pairs])
    if explain_degeneracy(q[mi]) is not None:
        return None
    try:
        return linear_init(q[mi], xy[dj])
    except CalibrationError:
        return None


def _refine(q, dots, allowed, P0, anchors, *, gate0, nominal, max_zero_deg, max_base_mm):
    """Iterate Hungarian assignment and base fit from predictions P0 (N, 2)."""
    P = P0
    gate = gate0
    pairs = None
    params = None
    fixed_m = {i for i, _ in anchors}
    fixed_d = {j for _, j in anchors}
    for it in range(6):
        D = np.hypot(P[:, None, 0] - dots[None, :, 0], P[:, None, 1] - dots[None, :, 1])
        cost = np.where(allowed & (D <= gate), D, 1e6)
        cost[list(fixed_m), :] = 1e6
        cost[:, list(fixed_d)] = 1e6
        r, c = linear_sum_assignment(cost)
        ok = cost[r, c] < 1e6
        new = sorted(set(anchors) | {(int(i), int(j)) for i, j in zip(r[ok], c[ok])})
        if len(new) < 3:
            return None
        p = _fit(q, dots, new)
        if p is None:
            return None
        params = p
        P = forward(p, q)
        res = np.array([np.hypot(*(P[i] - dots[j])) for i, j in new])
        rms = rms_of(res)
        gate_new = max(2.0, 5.0 * rms)
        if new == pairs and gate_new >= gate * 0.99:
            break
        pairs, gate = new, min(gate, gate_new) if it else gate_new
    if params is None or not _plausible(params, nominal, max_zero_deg, max_base_mm):
        return None
    P = forward(params, q)
    res = np.array([np.hypot(*(P[i] - dots[j])) for i, j in pairs])
    return {"pairs": tuple(pairs), "params": params, "rms": rms_of(res),
            "gate": gate, "P": P}


def clean_anchors(q_deg, dots_mm, anchors, *, tol_mm: float = 3.0) -> list:
    """Drop series anchors the robot model contradicts (a dot that first showed up in the
    photo of another mark, because it was missed before): refit the base model without the
    worst one while its residual exceeds ``tol_mm`` and 6 robust sigmas of the others."""
    q = np.asarray(q_deg, float).reshape(-1, 2)
    dots = np.asarray(dots_mm, float).reshape(-1, 2)
    A = list(anchors)
    while len(A) >= 4:
        p = _fit(q, dots, A)
        if p is None:
            break
        P = forward(p, q)
        r = np.array([np.hypot(*(P[i] - dots[j])) for i, j in A])
        worst = int(np.argmax(r))
        others = np.delete(r, worst)
        if r[worst] <= max(tol_mm, 6.0 * 1.4826 * float(np.median(others))):
            break
        A.pop(worst)
    return A


def match_to_plan(q_deg, dots_mm, nominal: ScaraParams, *, allowed=None, anchors=(),
                  max_zero_deg: float | None = None, max_base_mm: float | None = None,
                  zero_step_deg: float = 0.5, bin_mm: float = 5.0) -> Match | NoMatch:
    """Assign dots (M, 2) to planned marks at ``q_deg`` (N, 2) through the robot model.

    ``allowed`` (N, M) bool: pairs permitted by the photo series; ``anchors``: (mark, dot)
    pairs already known. Returns a :class:`Match` (``pairs`` a tuple of (mark index, dot
    index), ``params``, ``rms_mm``) or a falsy :class:`NoMatch` with the ``reason`` it refuses.
    ``max_zero_deg`` / ``max_base_mm`` None: config ``association`` of ``DEFAULT``.
    """
    ac = DEFAULT.association
    max_zero_deg = ac.max_zero_deg if max_zero_deg is None else max_zero_deg
    max_base_mm = ac.max_base_mm if max_base_mm is None else max_base_mm
    q = np.asarray(q_deg, float).reshape(-1, 2)
    dots = np.asarray(dots_mm, float).reshape(-1, 2)
    N, M = len(q), len(dots)
    allowed = np.ones((N, M), bool) if allowed is None else np.asarray(allowed, bool)
    anchors = tuple((int(i), int(j)) for i, j in anchors)
    kw = dict(nominal=nominal, max_zero_deg=max_zero_deg, max_base_mm=max_base_mm)
    if M == 0:
        return NoMatch("no dots to match")
    cands = []
    if len(anchors) >= 3 and _fit(q, dots, anchors) is not None:
        p = _fit(q, dots, anchors)
        r = _refine(q, dots, allowed, forward(p, q), anchors, gate0=10.0, **kw)
        if r:
            cands.append(r)
    if not cands:
        # vote over joint-zero offsets and base translations
        zs = np.arange(-max_zero_deg - 2, max_zero_deg + 2 + 1e-9, zero_step_deg)
        Z1, Z2 = np.meshgrid(zs, zs, indexing="ij")
        Z = np.column_stack([Z1.ravel(), Z2.ravel()])
        mi, dj = np.nonzero(allowed)
        if len(mi) == 0:
            return NoMatch("no dot may be any of the marks")
        P = np.empty((len(Z), N, 2))
        for h, (a, b) in enumerate(Z):
            p = ScaraParams(nominal.L1_mm, nominal.L2_mm, nominal.z1_deg + a,
                            nominal.z2_deg + b, nominal.base_x_mm, nominal.base_y_mm)
            P[h] = forward(p, q)
        # dot minus prediction of every (hypothesis, pair): x and y apart (contiguous)
        dx = dots[dj, 0][None] - P[:, mi, 0]  # (Hn, Np)
        dy = dots[dj, 1][None] - P[:, mi, 1]
        lim = max_base_mm + 60.0
        # only the votes within lim count: binned once found (a fifth of them on a full
        # sheet), in the order of the whole array
        hn, pn = np.nonzero(np.hypot(dx, dy) <= lim)
        T = np.column_stack([dx[hn, pn], dy[hn, pn]])
        del dx, dy
        best = []
        for off in (0.0, 0.5):
            B = np.floor(T / bin_mm + off).astype(np.int64)
            nb = int(2 * lim / bin_mm) + 4
            B = np.clip(B + nb // 2, 0, nb - 1)
            key = (hn * nb + B[:, 0]) * nb + B[:, 1]
            # count distinct marks per bin
            k2 = key * N + mi[pn]
            # distinct keys by sorting (np.unique without counts hashes: 20x slower on the
            # millions of keys of a full sheet's votes, numpy 2.4)
            k2 = np.sort(k2)
            k2 = k2[np.concatenate(([True], k2[1:] != k2[:-1]))]
            kk, cnt = np.unique(k2 // N, return_counts=True)
            top = np.argsort(-cnt)[:12]
            for t_ in top:
                h = int(kk[t_] // (nb * nb))
                bx = int((kk[t_] // nb) % nb) - nb // 2
                by = int(kk[t_] % nb) - nb // 2
                t = (np.array([bx, by]) + 0.5 - off) * bin_mm
                best.append((int(cnt[t_]), h, t))
        best.sort(key=lambda b: -b[0])
        for cnt, h, t in best[:16]:
            if cnt < 3:
                continue
            r = _refine(q, dots, allowed, P[h] + t, anchors, gate0=2.0 * bin_mm, **kw)
            if r:
                cands.append(r)
    if not cands:
        return NoMatch("no assignment of dots to marks is consistent with the nominal robot "
                       "model")
    uniq = {}
    for c in cands:
        if c["pairs"] not in uniq or c["rms"] < uniq[c["pairs"]]["rms"]:
            uniq[c["pairs"]] = c
    ranked = sorted(uniq.values(), key=lambda c: (-len(c["pairs"]), c["rms"]))
    b = ranked[0]
    n = len(b["pairs"])
    if n <= 3:
        return NoMatch(f"only {n} marks matched: 3 marks fit any assignment exactly, so "
                       "which dot is which cannot be told")
    for o in ranked[1:]:
        if len(o["pairs"]) >= n and o["rms"] < 3.0 * b["rms"] + 0.05:
            return NoMatch(
                f"ambiguous: two assignments of {n} marks explain the dots about equally well "
                f"(residual RMS {b['rms']:.3f} and {o['rms']:.3f} mm)")
    return Match(b["pairs"], b["params"], b["rms"])


def associate(q_deg, mark_ids, mark_images, groups: list[DotGroup], nominal: ScaraParams,
              *, max_zero_deg: float | None = None,
              max_base_mm: float | None = None) -> Assignment:
    """Assign dot groups to marks.

    ``q_deg`` (N, 2) commanded joints, ``mark_ids`` (N,), ``mark_images``: for each mark the
    set of usable image indices whose ``marks`` list it (empty: never photographed);
    ``max_zero_deg`` / ``max_base_mm`` None: config ``association`` of ``DEFAULT``.
    """
    q = np.asarray(q_deg, float).reshape(-1, 2)
    N, G = len(q), len(groups)
    if G == 0:
        return Assignment({}, {}, {}, None, ("no pen marks found in any photo",))
    seen = [set(g.images) for g in groups]
    allowed = np.array([[bool(mark_images[i]) and seen[c] <= mark_images[i]
                         for c in range(G)] for i in range(N)], bool).reshape(N, G)
    first_mark = [min(s) if s else None for s in mark_images]
    first_grp = [min(s) for s in seen]
    warnings = []
    m2g, how, refused = {}, {}, {}
    anchors = []
    # series rule: one new mark and one new dot in a photo
    for k in sorted({f for f in first_mark if f is not None}):
        nm = [i for i in range(N) if first_mark[i] == k]
        ng = [c for c in range(G) if first_grp[c] == k]
        if len(nm) == 1 and len(ng) == 1 and allowed[nm[0], ng[0]]:
            anchors.append((nm[0], ng[0]))
    dots = np.array([g.mean_mm for g in groups])
    n_series = len(anchors)
    anchors = clean_anchors(q, dots, anchors)
    if len(anchors) < n_series:
        warnings.append(f"{n_series - len(anchors)} dot(s) that first appeared with a new "
                        "mark disagree with the robot model: matched through the model")
    rest_m = [i for i in range(N) if mark_images[i] and i not in {a for a, _ in anchors}]
    pairs, params = list(anchors), None
    if rest_m or len(anchors) >= 3:
        match = match_to_plan(q, dots, nominal, allowed=allowed, anchors=anchors,
                              max_zero_deg=max_zero_deg, max_base_mm=max_base_mm)
        if not match:
            for i in rest_m:
                refused[str(mark_ids[i])] = match.reason
            warnings.append(f"{len(rest_m)} marks not identified: {match.reason}")
        else:
            params = match.params
            # anchors that the model contradicts are dropped (cannot both be right)
            pairs = list(match.pairs)
            P = forward(params, q)
            gate = max(2.0, 5.0 * match.rms_mm)
            keep = []
            for i, c in pairs:
                near = np.hypot(*(dots - P[i]).T) <= gate
                if near.sum() > 1:
                    refused[str(mark_ids[i])] = (f"two candidate dots within {gate:.1f} mm of "
                                                 "where the model puts the mark")
                    continue
                keep.append((i, c))
            pairs = keep
    anchor_set = set(anchors)
    for i, c in pairs:
        m2g[str(mark_ids[i])] = int(c)
        how[str(mark_ids[i])] = "series" if (i, c) in anchor_set else "model"
    for i in range(N):
        mid = str(mark_ids[i])
        if mid not in m2g and mid not in refused:
            refused[mid] = ("not in any usable photo" if not mark_images[i]
                            else "no dot found for it")
    return Assignment(m2g, refused, how, params, tuple(warnings))
