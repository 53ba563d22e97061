"""The print field checked by replication, and the rule that applies it (issue 37).

The sheet as printed (:mod:`vision_cal.measure.asprinted`) is a claim about the paper: every
marker corner moved by so much, known to so much. It is checked the way every figure is:
the evidence is split into two independent halves, the same estimate is run on each, and
the two fields are compared on the corners both moved against the covariance each half
states (:func:`vision_cal.model.replication.compare`).

- The halves (:func:`split_halves`): the camera places, alternately in the order they were
  first photographed, when each half then holds ``config.min_places`` places (photos from
  one place repeat its detection errors: they must not be split across the halves); else
  the photos alternately, when each half still sees that many places (the halves then
  share places, and their agreement is optimistic: ``split`` says so); else none.
- The comparison (:func:`replicate`): each half's corners as printed, taken into one gauge
  over the corners both released (:func:`vision_cal.measure.asprinted.gauge_projector`),
  with each half's joint covariance taken into it the same way.
- The rule (:func:`claim_of`): a field is applied only when its solve converged, it is
  significant against its own covariance (:func:`significance`: p below
  ``config.field_alpha``; from the calibration's own photos also off its layout beyond
  ``config.min_deviation_ratio`` times what the views leave unresolved), and its halves
  agree (``chi2/dof`` at most ``config.replication_max_chi2_dof``). Otherwise it moves no
  mark, and the print's size is carried in every mark's variance (``measure/print_stage``),
  with what would resolve it. Halves that agree but scatter more than stated scale the
  applied field's std (:func:`stated_scale`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from vision_cal.config import DEFAULT, AsPrintedConfig
from vision_cal.measure.asprinted import AsPrinted, estimate_as_printed, gauge_projector
from vision_cal.model.replication import Comparison, compare
from vision_cal.model.rms import rms_2d

#: the statuses of a replication
AGREE, DISAGREE, NOT_CHECKED = "agree", "disagree", "not checked"


@dataclass(frozen=True)
class Halves:
    """Two halves of the photos (indices into the views), and how they were split:
    ``places`` (every camera place in one half only) or ``photos`` (places shared)."""

    split: str
    a: tuple[int, ...]
    b: tuple[int, ...]


def split_halves(places, min_places: int) -> Halves | None:
    """Two halves of photos whose camera places are ``places`` (V,) (numbered in order of
    first appearance), each with at least ``min_places`` places (module docstring), or
    None."""
    places = np.asarray(places, int)
    n = int(places.max()) + 1 if len(places) else 0
    if n >= 2 * min_places:
        a = tuple(int(i) for i in np.flatnonzero(places % 2 == 0))
        b = tuple(int(i) for i in np.flatnonzero(places % 2 == 1))
        return Halves("places", a, b)
    idx = np.arange(len(places))
    a, b = idx[0::2], idx[1::2]
    if min(len(set(places[a])), len(set(places[b]))) >= min_places:
        return Halves("photos", tuple(int(i) for i in a), tuple(int(i) for i in b))
    return None


@dataclass(frozen=True)
class Replication:
    """The halves' print fields compared (:func:`replicate`).

    ``status``: ``agree``, ``disagree`` or ``not checked`` (``reason``: why, and what would
    make the check possible); ``split`` and the halves' photos ``files_a`` / ``files_b``;
    ``n_corners`` compared; ``comparison`` (chi2/dof over the corners' x and y, in the
    gauge); ``correlation_xy`` the halves' correlation along x and along y; ``rms_diff_mm``
    the 2-D RMS of their difference; ``rms_a_mm`` / ``rms_b_mm`` each half's field (2-D RMS
    over the corners compared) and ``unresolved_a_mm`` / ``unresolved_b_mm`` what each
    states; ``max_chi2_dof`` the threshold it was judged by."""

    status: str
    reason: str | None = None
    split: str | None = None
    files_a: tuple[str, ...] = ()
    files_b: tuple[str, ...] = ()
    n_corners: int = 0
    comparison: Comparison | None = None
    correlation_xy: tuple[float, float] = (math.nan, math.nan)
    rms_diff_mm: float = math.nan
    rms_a_mm: float = math.nan
    rms_b_mm: float = math.nan
    unresolved_a_mm: float = math.nan
    unresolved_b_mm: float = math.nan
    max_chi2_dof: float = math.nan

    @property
    def chi2_dof(self) -> float:
        return self.comparison.chi2_dof if self.comparison is not None else math.nan

    def to_json(self) -> dict:
        """measurement.json / survey.json ``as_printed.replication`` (docs/format.md)."""
        c = self.comparison
        d = {"status": self.status, "reason": self.reason, "split": self.split,
                "files_a": list(self.files_a), "files_b": list(self.files_b),
                "n_corners": int(self.n_corners),
                "chi2_dof": None if c is None else _num(c.chi2_dof),
                "dof": None if c is None else int(c.dof),
                "p_value": None if c is None else _num(c.p_value),
                "correlation_xy": [_num(v) for v in self.correlation_xy],
                "rms_diff_mm": _num(self.rms_diff_mm),
                "rms_a_mm": _num(self.rms_a_mm), "rms_b_mm": _num(self.rms_b_mm),
                "unresolved_a_mm": _num(self.unresolved_a_mm),
                "unresolved_b_mm": _num(self.unresolved_b_mm),
                "max_chi2_dof": _num(self.max_chi2_dof)}
        return {**d, "text": replication_line(d)}


def _num(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def replication_line(r: dict | None) -> str:
    """The sentence for a replication block (``Replication.to_json``, as read from a file)."""
    if not r:
        return "the print field was not checked by replication (a file written before it was)"
    if r.get("status") == NOT_CHECKED:
        return f"the print field could not be checked by replication: {r.get('reason')}"
    cx, cy = (v if v is not None else math.nan for v in r.get("correlation_xy", [None, None]))
    split = ("camera places" if r.get("split") == "places"
             else "photos (the halves share camera places: optimistic)")
    return (f"two halves ({split}: {len(r.get('files_a', []))} + {len(r.get('files_b', []))} "
            f"photos) {'agree' if r.get('status') == AGREE else 'disagree'} on the print: "
            f"chi2/dof {_f(r.get('chi2_dof'), 2)} over {r.get('n_corners')} corners "
            f"(at most {_f(r.get('max_chi2_dof'), 2)}), correlation {cx:.2f} / {cy:.2f} "
            f"(x / y), difference {_f(r.get('rms_diff_mm'), 3)} mm RMS against fields of "
            f"{_f(r.get('rms_a_mm'), 3)} / {_f(r.get('rms_b_mm'), 3)} mm known to "
            f"{_f(r.get('unresolved_a_mm'), 3)} / {_f(r.get('unresolved_b_mm'), 3)} mm")


def _f(v, digits: int) -> str:
    return "nan" if v is None else f"{float(v):.{digits}f}"


def _not_checked(reason: str, cfg: AsPrintedConfig, **kw) -> Replication:
    return Replication(NOT_CHECKED, reason, max_chi2_dof=cfg.replication_max_chi2_dof, **kw)


def replicate(views, ap: AsPrinted, K, dist, size_px, *, lens_free: bool,
              config: AsPrintedConfig | None = None) -> Replication:
    """The print field ``ap`` (estimated from ``views``, the list
    :func:`vision_cal.measure.asprinted.estimate_as_printed` took, with the start lens
    ``K``, ``dist``) estimated again from each of two halves of the photos and the halves
    compared (module docstring)."""
    cfg = config or DEFAULT.as_printed
    by_file = {v[0]: v for v in views}
    used = [by_file[f] for f in ap.files if f in by_file]
    n_places = len(set(ap.places))
    halves = split_halves(ap.places, cfg.min_places) if len(used) == len(ap.places) else None
    if halves is None:
        need = 2 * cfg.min_places
        return _not_checked(
            f"{n_places} camera places ({len(used)} photos): two independent halves need "
            f"{need} places, {cfg.min_places} each; photograph the sheet from "
            f"{max(need - n_places, 1)} more places (docs/sheet.md)", cfg)
    files = ([used[i][0] for i in halves.a], [used[i][0] for i in halves.b])
    # each half starts from the whole's lens (a free lens is solved again from there; a
    # declared one is the one given): the start moves no converged solution, and spares
    # the iterations that found it
    start = (ap.K, ap.dist) if lens_free else (K, dist)
    half_aps = []
    for name, idx in (("a", halves.a), ("b", halves.b)):
        h = estimate_as_printed([used[i] for i in idx], *start, size_px,
                                lens_free=lens_free, config=cfg)
        if h is None or h.stopped or h.corner_cov_mm2 is None:
            why = ("sees fewer camera places than a field needs" if h is None else
                   h.stopped if h.stopped else "leaves its corners' covariance singular")
            return _not_checked(f"half {name} ({len(idx)} photos) {why}", cfg,
                                split=halves.split, files_a=tuple(files[0]),
                                files_b=tuple(files[1]))
        half_aps.append(h)
    return compare_layouts(half_aps[0], half_aps[1], cfg, split=halves.split, files=files)


def _common(a: AsPrinted, b: AsPrinted):
    """The markers both halves know, and per corner whether both released it: (declared
    (Mc, 4, 2), released (Mc, 4), rows of ``a`` and of ``b``)."""
    pos_b = {int(i): k for k, i in enumerate(b.ids)}
    ka = [k for k, i in enumerate(a.ids) if int(i) in pos_b]
    kb = [pos_b[int(a.ids[k])] for k in ka]
    rel = a.released[ka] & b.released[kb]
    return a.declared_mm[ka], rel, np.array(ka, int), np.array(kb, int)


def _in_common_gauge(h: AsPrinted, rows: np.ndarray, rel: np.ndarray, Q: np.ndarray):
    """Half ``h``'s deviations and joint covariance at the common corners (``rows`` its
    markers, ``rel`` (Mc, 4) the corners), in the gauge ``Q`` over them."""
    corner = (4 * rows[:, None] + np.arange(4)[None, :])[rel]          # corner indices
    rc = np.column_stack([2 * corner, 2 * corner + 1]).ravel()
    d = h.deviation_mm[rows][rel].ravel()
    C = np.asarray(h.corner_cov_mm2, float)[np.ix_(rc, rc)]
    return Q @ d, Q @ C @ Q.T


def compare_layouts(a: AsPrinted, b: AsPrinted, config: AsPrintedConfig | None = None, *,
                    split: str | None = None, files=((), ())) -> Replication:
    """Two layouts of one print (two halves, or two surveys: two cameras) compared on the
    corners both released, in one gauge over those, against the joint covariance each
    states (``corner_cov_mm2``; module docstring)."""
    cfg = config or DEFAULT.as_printed
    declared, rel, ka, kb = _common(a, b)
    n = int(rel.sum())
    common = dict(split=split, files_a=tuple(files[0]), files_b=tuple(files[1]), n_corners=n)
    if a.corner_cov_mm2 is None or b.corner_cov_mm2 is None:
        return _not_checked("a layout without its corners' joint covariance (singular)",
                            cfg, **common)
    if n < cfg.replication_min_corners:
        return _not_checked(f"the halves moved only {n} corners in common, fewer than "
                            f"{cfg.replication_min_corners}: photograph the whole sheet in "
                            "every photo", cfg, **common)
    Q = gauge_projector(declared, rel)
    da, Ca = _in_common_gauge(a, ka, rel, Q)
    db, Cb = _in_common_gauge(b, kb, rel, Q)
    c = compare(da, Ca, db, Cb)
    corr = tuple(float(np.corrcoef(da[k::2], db[k::2])[0, 1])
                 if np.std(da[k::2]) > 0 and np.std(db[k::2]) > 0 else math.nan
                 for k in (0, 1))
    ua = float(np.sqrt(np.trace(Ca) / n))
    ub = float(np.sqrt(np.trace(Cb) / n))
    status = AGREE if c.within(cfg.replication_max_chi2_dof) else DISAGREE
    reason = (None if status == AGREE else
              f"the halves' fields differ by {rms_2d((da - db).reshape(-1, 2)):.3f} mm RMS, "
              f"chi2/dof {c.chi2_dof:.2f} against the {ua:.3f} / {ub:.3f} mm each states "
              f"(at most {cfg.replication_max_chi2_dof:g})")
    return Replication(status, reason, comparison=c, correlation_xy=corr,
                       rms_diff_mm=rms_2d((da - db).reshape(-1, 2)),
                       rms_a_mm=rms_2d(da.reshape(-1, 2)), rms_b_mm=rms_2d(db.reshape(-1, 2)),
                       unresolved_a_mm=ua, unresolved_b_mm=ub,
                       max_chi2_dof=cfg.replication_max_chi2_dof, **common)


def significance(ap: AsPrinted) -> Comparison | None:
    """The field ``ap`` against its own covariance: its released corners' deviations (in the
    gauge) compared with zero (:func:`vision_cal.model.replication.compare`); None without
    the joint covariance."""
    if ap.corner_cov_mm2 is None or not ap.released.any():
        return None
    rel = ap.released.ravel()
    rc = np.column_stack([2 * np.flatnonzero(rel), 2 * np.flatnonzero(rel) + 1]).ravel()
    d = ap.deviation_mm.reshape(-1, 2)[rel].ravel()
    return compare(d, np.asarray(ap.corner_cov_mm2, float)[np.ix_(rc, rc)], np.zeros_like(d), 0.0)


def with_replication(ap: AsPrinted, views, K, dist, size_px, *, lens_free: bool,
                     config: AsPrintedConfig | None = None,
                     only_significant: bool = False) -> AsPrinted:
    """``ap`` with its ``significance`` (:func:`significance`) and ``replication``
    (:func:`replicate`) blocks; a solve that stopped on a limit is neither (it is no
    result). ``only_significant``: a field not significant is not replicated (it is not
    applied whatever its halves say: the calibration's own stage spares the two solves)."""
    if ap.stopped:
        return ap
    cfg = config or DEFAULT.as_printed
    sig = significance(ap)
    ap = replace(ap, significance=None if sig is None else {
        "chi2_dof": _num(sig.chi2_dof), "dof": int(sig.dof), "p_value": _num(sig.p_value)})
    if only_significant and _not_significant(ap, cfg):
        return ap
    rep = replicate(views, ap, K, dist, size_px, lens_free=lens_free, config=cfg)
    return replace(ap, replication=rep.to_json())


def stated_scale(replication: dict | None) -> float:
    """How much larger than stated the halves show the layout's std to be: sqrt(chi2/dof)
    of halves that agree, when above 1 (1 otherwise: halves that scatter less than stated
    do not shrink it, and a field whose halves disagree is not applied). The applied
    field's limit on the marks and its shared covariance are scaled by it."""
    r = replication or {}
    c = r.get("chi2_dof")
    if r.get("status") != AGREE or c is None or not math.isfinite(c):
        return 1.0
    return float(math.sqrt(max(1.0, c)))


# ---------------------------------------------------------------------- the rule

#: the claim's statuses: applied, or why not
APPLIED, FAILED, NOT_SIGNIFICANT, NOT_REPLICATED, NOT_RESOLVED = (
    "applied", "failed", "not significant", "not replicated", "not resolved")


@dataclass(frozen=True)
class Claim:
    """Whether a print field moves the marks: ``status`` (``applied``, ``failed``: its solve
    stopped on a limit, ``not significant``, ``not replicated``, ``not resolved``: the
    views leave its corners unknown) and ``reason`` (None when applied: a sentence with
    what would resolve it)."""

    status: str
    reason: str | None = None

    @property
    def applied(self) -> bool:
        return self.status == APPLIED

    def to_json(self) -> dict:
        return {"status": self.status, "reason": self.reason}


def measures_the_print(claim: Claim) -> bool:
    """A layout that measured the print, applied or found on its layout (``not
    significant``: the print is where the layout says, within what the views leave
    unresolved); a failed, unresolved or unreplicated one tells nothing of it."""
    return claim.status in (APPLIED, NOT_SIGNIFICANT)


def claim_of(ap: AsPrinted, config: AsPrintedConfig | None = None) -> Claim:
    """The rule (module docstring) for the layout ``ap`` with its ``replication``."""
    cfg = config or DEFAULT.as_printed
    if ap.stopped:
        return Claim(FAILED, f"{ap.stopped}: a failed solve, no print field claimed; "
                             "photograph the sheet again from further places (docs/sheet.md)")
    u = ap.unresolved_mm
    if not math.isfinite(u) or u > cfg.prior_mm:
        return Claim(NOT_RESOLVED, f"the views leave the corners known only to {u:.3g} mm, "
                                   f"more than the {cfg.prior_mm:g} mm a printer can be off: "
                                   "photograph the sheet from further places, tilted more")
    why = _not_significant(ap, cfg)
    if why:
        return Claim(NOT_SIGNIFICANT, why)
    r = ap.replication
    if not r or r.get("status") != AGREE:
        why = (r or {}).get("reason") or "not checked by replication"
        return Claim(NOT_REPLICATED, f"the print field ({ap.rms_mm:.3f} mm RMS) does not "
                                     f"replicate: {why}")
    return Claim(APPLIED)


def _not_significant(ap: AsPrinted, cfg: AsPrintedConfig) -> str | None:
    """Why the field ``ap`` is not significant (None: it is): its chi-square against its own
    covariance (``ap.significance``) not beyond ``cfg.field_alpha``; a layout from the
    calibration's own photos (``source`` views) must also be off its layout by more than
    ``cfg.min_deviation_ratio`` times what the views leave unresolved (a file without
    ``significance``: that rule alone)."""
    u = ap.unresolved_mm
    s = ap.significance or {}
    p = s.get("p_value")
    if p is not None and not p < cfg.field_alpha:
        return (f"the print is {ap.rms_mm:.3f} mm RMS off its layout, chi2/dof "
                f"{s.get('chi2_dof') or math.nan:.2f} against the {u:.3f} mm the views leave "
                f"unresolved (p = {p:.2g}, at most {cfg.field_alpha:g} needed): on its layout "
                "as far as they can tell")
    if (p is None or ap.source == "views") and not ap.rms_mm > cfg.min_deviation_ratio * u:
        return (f"the print is {ap.rms_mm:.3f} mm RMS off its layout, within "
                f"{cfg.min_deviation_ratio:g} times the {u:.3f} mm the views leave "
                "unresolved: on its layout as far as they can tell")
    return None
