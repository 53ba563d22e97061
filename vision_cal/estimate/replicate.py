"""The robot fit replicated by two halves of its marks (issue 37, calibration.json
``replication``): each half fitted alone with the model the selection chose, and what the
run reports - the parameters and where planned targets land - compared between the halves
against the covariance each half states (:func:`vision_cal.model.replication.compare`).

The halves see the robot in two configurations, so they replicate the model and not
only the noise: the two elbows (the sign of ``sin(q2 + z2)``), else joint 1 below and
above its median, else marks taken alternately along joint 1 within each approach side.
Each half must keep ``uncertainty.min_half_dof`` degrees of freedom and identify every
parameter (both approach sides of a joint with backlash, joint 4 turned with a tool);
the first split that does is used. On kinematic worlds (``bench/coverage.py --halves``,
seeds 6100-6119) the elbows read a 0.3 % joint-1 gear scale or a 0.05 deg cyclic error the
model lacks 20/20 (chi2/dof median 5.1 / 5.3) where marks taken alternately read 0/20
(0.9 / 0.7: both halves carry the same bias), and a right model disagrees 0/20 (0.90).

Each half's covariance is the one the run states, the half's own design scaled by the
full fit's residual variance (``s^2 (J_h' W J_h)^-1``: the full fit's ``s^2`` is what
calibration.json's ``std`` carries, with ``2N - P`` degrees of freedom, where a half's own
would have half as many). An error the halves share (the print's measured field,
measurement.json ``print.field``) moves both and is carried into their difference's
covariance with its cross terms. The positions compared: the validation marks' commands
(three or more), else the fitted marks' own (the workspace the marks cover).

The halves agree unless ``p < verdict.floor_alpha`` and ``chi2/dof >
verdict.floor_ratio_tol^2`` for the parameters or the positions (the noise floor's
rule); the verdict is not ``ready`` otherwise (:func:`vision_cal.estimate.verdict.judge`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.model.lsq import Fit
from vision_cal.model.replication import Comparison, compare
from vision_cal.model.solve import covariance
from vision_cal.model.robot import RobotModel


@dataclass(frozen=True)
class Halves:
    """Two disjoint sets of mark indices and how they were chosen (``split``: a phrase)."""

    a: np.ndarray
    b: np.ndarray
    split: str


def candidate_splits(q_deg, approach, z2_deg: float) -> list[Halves]:
    """The splits to try, in order (module docstring): the elbows, joint 1's halves, marks
    taken alternately along joint 1 within each pair of approach signs. ``q_deg`` (N, 2+),
    ``approach`` (N, 2+)."""
    q = np.asarray(q_deg, float).reshape(len(q_deg), -1)
    s = np.asarray(approach, float).reshape(len(q), -1)
    idx = np.arange(len(q))
    up = np.sin(np.radians(q[:, 1] + z2_deg)) > 0
    med = float(np.median(q[:, 0]))
    low = q[:, 0] <= med
    a, b = [], []
    key = (s[:, 0] > 0) * 2 + (s[:, 1] > 0)
    for k in range(4):
        m = idx[key == k]
        m = m[np.argsort(q[m, 0], kind="stable")]
        for j, i in enumerate(m):
            (a if (j + j // 2) % 2 == 0 else b).append(i)
    return [Halves(idx[up], idx[~up], "elbow +1 | elbow -1"),
            Halves(idx[low], idx[~low], f"joint 1 at or below | above {med:.1f} deg"),
            Halves(np.sort(np.array(a, int)), np.sort(np.array(b, int)),
                   "alternate marks along joint 1, each approach side")]


@dataclass(frozen=True)
class _Half:
    fit: Fit
    cov: np.ndarray            # the stated covariance (P, P)
    G: np.ndarray              # (P, 2 n_h) the parameters' linear response to its marks


def _fit_half(model: RobotModel, q, xy, s, sigma, s2: float, config) -> "_Half | str":
    """One half fitted with ``model``'s structure; its covariance scaled by ``s2``; or why
    it cannot be."""
    f = Fit.from_estimate(q, xy, approach=s, model=model, sigma_mm=sigma, robust=False,
                          config=config)
    if not f:
        return f.reason
    if not (np.isfinite(f.residual_scale) and f.residual_scale > 0):
        return "a half fits its marks exactly"
    P = len(f.model.vector)
    w = np.ones(len(q)) if sigma is None else 1.0 / np.asarray(sigma, float)
    J = f.model.jacobian(q, s).reshape(-1, P)
    W = np.repeat(w**2, 2)
    unit = covariance(J * np.sqrt(W)[:, None]).matrix   # the one policy, unit noise
    return _Half(f, unit * s2, unit @ (J.T * W))


def replicate(model: RobotModel, q_deg, xy_mm, approach, sigma_mm, *, residual_scale: float,
              check_q=None, check_approach=None, check_label: str = "",
              shared_cov_mm2=None, config: EstimatorConfig | None = None) -> dict:
    """calibration.json ``replication`` for a fit of ``model``'s structure to the marks
    ``q_deg`` (N, 2|3), ``xy_mm`` (N, 2), ``approach``, ``sigma_mm`` (N,) or None, whose
    full fit's residual scale is ``residual_scale``; the positions compared at
    ``check_q`` / ``check_approach`` (default the marks' own; ``check_label`` says what
    they are); ``shared_cov_mm2`` (2N, 2N) an error the marks share (the print's field),
    or None. Keys: ``split``, ``halves`` ([n_a, n_b]), ``params`` and ``positions``
    (:class:`~vision_cal.model.replication.Comparison` as JSON, ``positions.at``), ``agree``, ``text``; when no split
    can be fitted, ``agree`` None and the ``reason``."""
    cfg = config or DEFAULT
    q = np.asarray(q_deg, float)
    q = q.reshape(len(q), -1)
    xy = np.asarray(xy_mm, float).reshape(-1, 2)
    s = np.asarray(approach, float).reshape(len(q), -1)
    sig = None if sigma_mm is None else np.asarray(sigma_mm, float).reshape(-1)
    P = len(model.vector)
    s2 = float(residual_scale) ** 2
    if not (np.isfinite(s2) and s2 > 0):
        return {"agree": None, "reason": "the full fit states no residual variance",
                "text": "not replicated: the full fit states no residual variance"}
    why = []
    for h in candidate_splits(q, s, model.params.z2_deg):
        small = min(len(h.a), len(h.b))
        if 2 * small - P < cfg.uncertainty.min_half_dof:
            why.append(f"{h.split}: {small} marks in a half, {P} parameters")
            continue
        halves = [_fit_half(model, q[i], xy[i], s[i], None if sig is None else sig[i], s2, cfg)
                  for i in (h.a, h.b)]
        bad = [x for x in halves if isinstance(x, str)]
        if bad:
            why.append(f"{h.split}: {bad[0]}")
            continue
        out = _compared(h, halves, q, s, check_q, check_approach, check_label,
                        shared_cov_mm2, cfg)
        if out["params"]["dof"] > 0:
            return out
        why.append(f"{h.split}: no degree of freedom to compare")
    return {"agree": None, "reason": "; ".join(why) or "no marks",
            "text": "not replicated: " + ("; ".join(why) or "no marks")}


def _compared(h: Halves, halves: list, q, s, check_q, check_approach, check_label: str,
              shared, cfg: EstimatorConfig) -> dict:
    """The block for two fitted halves (see :func:`replicate`)."""
    ha, hb = halves
    if check_q is None or not len(check_q):
        cq, cs, label = q, s, f"the {len(q)} fitted marks' commands"
    else:
        cq = np.asarray(check_q, float).reshape(len(check_q), -1)
        cs = np.asarray(check_approach, float).reshape(len(cq), -1)
        label = check_label or f"{len(cq)} commands"
    P = ha.cov.shape[0]
    Ja = ha.fit.model.jacobian(cq, cs).reshape(-1, P)
    Jb = hb.fit.model.jacobian(cq, cs).reshape(-1, P)
    extra_p = extra_x = 0.0
    if shared is not None:   # the difference of two responses to one shared error
        C = np.asarray(shared, float)
        rows = [np.column_stack([2 * i, 2 * i + 1]).ravel() for i in (h.a, h.b)]
        L = np.hstack([ha.G, -hb.G])
        order = np.concatenate(rows)
        Cab = C[np.ix_(order, order)]
        extra_p = L @ Cab @ L.T
        Lx = np.hstack([Ja @ ha.G, -(Jb @ hb.G)])
        extra_x = Lx @ Cab @ Lx.T
    par = compare(ha.fit.model.vector, ha.cov + extra_p, hb.fit.model.vector, hb.cov)
    pos = compare(ha.fit.model.predict(cq, cs).ravel(), Ja @ ha.cov @ Ja.T + extra_x,
                  hb.fit.model.predict(cq, cs).ravel(), Jb @ hb.cov @ Jb.T)
    vc = cfg.verdict
    agree = all(r.agrees(vc.floor_alpha, vc.floor_ratio_tol) for r in (par, pos))
    return {"split": h.split, "halves": [int(len(h.a)), int(len(h.b))],
            "params": par.to_json(), "positions": {**pos.to_json(), "at": label},
            "agree": bool(agree), "text": _text(h, par, pos, agree)}


def _text(h: Halves, par: Comparison, pos: Comparison, agree: bool) -> str:
    """One line for the console and the report."""
    return (f"replication ({h.split}, {len(h.a)} | {len(h.b)} marks): parameters chi2/dof "
            f"{par.chi2_dof:.2f} on {par.dof} dof (p = {par.p_value:.2g}), target positions "
            f"{pos.chi2_dof:.2f} on {pos.dof} dof (p = {pos.p_value:.2g}): "
            + ("the halves agree within their stated std" if agree else
               "the halves disagree beyond their stated std"))
