"""The sheet as printed: where the printed markers' corners really are on the paper.

A printer does not put the ink where the layout says (a wave along the paper feed, a bow,
a skew, toner that grows the black squares: tenths of a millimetre). Where several views of
the sheet exist (a series from several places, a survey before the robot draws), the
markers' corners are estimated jointly with the lens and each photo's pose: a bundle
adjustment with the target's points released, as OpenCV's ``calibrateCameraRO`` (Strobl and
Hirzinger 2011) and mrcal's board deformation do.

The gauge. Moving the whole layout by a similarity (shift, turn, scale) and every camera
with it leaves every photo the same, so the views cannot see it. It is fixed as the
contract's frame is: the as-printed layout's best-fitting similarity to the declared one,
each marker's growth (toner) fitted beside it, is the identity (the sheet frame stays the
declared one on average, the overall scale the declared one; the printer's overall scale
is the bars' business, ``printed_scale``; a marker's growth is no scale of the sheet).

What the layout's uncertainty does to the marks is not independent from mark to mark:
every photo's mapping is fitted to the corners, so the marks share it. ``field`` is the
corners' joint covariance projected on the displacement fields a mapping can take
(:func:`field_basis`); the calibration carries it into the parameters' covariance
(``vision_cal.model.lsq.Fit.with_shared_error``).

Model. Marker corner ``c`` of the declared layout (``P_c``, sheet mm, z = 0) is printed at
``P_c + delta_c``; photo ``v`` sees it at ``project(K, dist, R_v, t_v, P_c + delta_c)``
(OpenCV's pinhole with k1 k2 p1 p2 k3). Free: every pose, every ``delta_c`` of a corner seen
in at least ``min_views`` photos, and the lens when it was not declared (f, principal point,
k1, k2, p1, p2; and each photo's focal length within ``focal_scatter`` of it: a phone
refocuses). A weak prior (``prior_mm``) holds the deltas the views do not fix at zero
(the gauge, and any mode the lens can take over); the similarity is then removed. Solved by
the one solver (:func:`vision_cal.model.solve.solve`: trf, Huber loss), with OpenCV's
derivatives of its projection for the poses and the lens; the covariance under its one
policy (a direction the views do not fix in the lens or the corners leaves their std
unknown, never small).

What the views cannot separate from the lens is stated with its size: ``unresolved_mm``,
the RMS over the released corners of their standard deviation (from the Jacobian at the
solution, the residual's own scale, times sqrt(photos / places): repeated photos from one
place repeat its detection errors), the lens free. ``interior_mm`` is what the shared lens
and corners leave on marks between the markers, each photo's pose refitted to the corners as
its mapping is (:func:`_interior_cov`); the print's limit on the marks is the larger of the
two (``limit_mm``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from vision_cal.config import DEFAULT, AsPrintedConfig
from vision_cal.model.rms import rms_2d
from vision_cal.model.solve import Covariance, Solution, covariance, solve

#: lens parameters freed when the lens was not declared, in this order
LENS_FREE = ("f", "cx", "cy", "k1", "k2", "p1", "p2")


@dataclass(frozen=True)
class AsPrinted:
    """The as-printed layout (see the module docstring).

    ``ids`` (M,), ``declared_mm`` / ``printed_mm`` / ``std_mm`` (M, 4, 2): each marker's
    corners (TL, TR, BR, BL) as declared, as printed (gauge fixed), and the per-axis std of
    the printed ones (0 for corners not released). ``released`` (M, 4) bool. ``K``, ``dist``,
    ``size_px``: the lens the views were solved with (``lens_free``: refined here).
    ``files``, ``rms_px_before`` / ``rms_px_after``: per photo, the marker corners' RMS
    reprojection residual against the declared layout and against the printed one (same
    lens, each photo's own pose). ``n_places``: distinct camera places among the photos.
    ``heights_mm`` / ``height_std_mm`` (M, 4): each corner's height off the paper's plane
    (less the heights' best-fitting plane) and its std, when they were released
    (``config.as_printed.release_heights``; else None): paper that is not flat.
    """

    ids: np.ndarray
    declared_mm: np.ndarray
    printed_mm: np.ndarray
    std_mm: np.ndarray
    released: np.ndarray
    K: np.ndarray
    dist: np.ndarray
    size_px: tuple[int, int]
    lens_free: bool
    files: tuple[str, ...]
    rms_px_before: tuple[float, ...]
    rms_px_after: tuple[float, ...]
    n_places: int
    source: str = "views"
    notes: tuple[str, ...] = field(default=())
    heights_mm: np.ndarray | None = None
    height_std_mm: np.ndarray | None = None
    #: (2 M 4, 2 M 4) the corners' joint covariance in the gauge (x, y of each corner, in
    #: ``printed_mm``'s order; zero where not released); not written (``field`` is)
    corner_cov_mm2: np.ndarray | None = None
    #: a ``field`` block read from a file (used when ``corner_cov_mm2`` is None)
    field_read: dict | None = None
    #: why the bundle adjustment stopped before it converged (its evaluation limit), None
    #: when it converged: a solve that stopped is a failure, never a result (issue 37)
    stopped: str | None = None
    #: each photo's camera place (``files``' order; :func:`place_labels`), () when unknown
    places: tuple[int, ...] = ()
    #: the halves' agreement (:mod:`vision_cal.measure.replicate`), None when not run
    replication: dict | None = None
    #: the field against its own covariance (``chi2_dof``, ``dof``, ``p_value``,
    #: :mod:`vision_cal.measure.replicate`), None when not computed
    significance: dict | None = None
    #: (P, 2) sheet points between the markers and (2 P, 2 P) the joint covariance of marks
    #: measured there (:func:`_interior_cov`); not written (``interior_mm`` and ``field``
    #: are)
    interior_xy_mm: np.ndarray | None = None
    interior_cov_mm2: np.ndarray | None = None
    #: ``interior_mm`` read from a file (used when ``interior_cov_mm2`` is None)
    interior_read: float | None = None

    # ------------------------------------------------------------------ figures
    @property
    def deviation_mm(self) -> np.ndarray:
        """printed - declared (M, 4, 2)."""
        return self.printed_mm - self.declared_mm

    @property
    def rms_mm(self) -> float:
        d = self.deviation_mm[self.released]
        return rms_2d(d) if len(d) else 0.0

    @property
    def max_mm(self) -> float:
        d = self.deviation_mm[self.released]
        return float(np.linalg.norm(d, axis=1).max()) if len(d) else 0.0

    @property
    def growth_mm(self) -> float:
        """The markers' mean growth per side (toner; negative: printed thinner)."""
        s = np.sign(self.declared_mm - self.declared_mm.mean(axis=1, keepdims=True))
        g = (self.deviation_mm * s).sum(axis=2) / 2.0
        return float(g[self.released].mean()) if self.released.any() else 0.0

    @property
    def field_rms_mm(self) -> float:
        """The deviation's RMS without the markers' growth: where the print moved."""
        s = np.sign(self.declared_mm - self.declared_mm.mean(axis=1, keepdims=True))
        d = (self.deviation_mm - self.growth_mm * s)[self.released]
        return rms_2d(d) if len(d) else 0.0

    @property
    def height_rms_mm(self) -> float | None:
        """RMS of the released corners' heights off the paper's plane (None: not released)."""
        if self.heights_mm is None:
            return None
        h = np.asarray(self.heights_mm)[self.released]
        return float(np.sqrt(np.mean(h**2))) if len(h) else 0.0

    @property
    def height_unresolved_mm(self) -> float | None:
        """RMS of the released corners' height std (None: not released)."""
        if self.height_std_mm is None:
            return None
        s = np.asarray(self.height_std_mm)[self.released]
        return float(np.sqrt(np.mean(s**2))) if len(s) else float("nan")

    @property
    def unresolved_mm(self) -> float:
        """RMS (2-D) of the released corners' std: what the views leave uncertain, the part
        of the print the lens could take over included."""
        s = self.std_mm[self.released]
        return float(np.sqrt(np.mean(np.sum(s**2, axis=1)))) if len(s) else float("nan")

    @property
    def interior_mm(self) -> float | None:
        """RMS (2-D) of the std of marks measured between the markers (the print's and the
        lens's trade included): what the layout leaves on the marks. None without the
        interior covariance."""
        if self.interior_cov_mm2 is None:
            return self.interior_read
        d = np.clip(np.diag(np.asarray(self.interior_cov_mm2, float)), 0, None)
        return float(np.sqrt(2.0 * np.mean(d)))

    @property
    def limit_mm(self) -> float:
        """The print's limit on the marks (2-D RMS): the interior's when known, never below
        the corners' own (``unresolved_mm``)."""
        inner = self.interior_mm
        return max(self.unresolved_mm, inner) if inner is not None and np.isfinite(inner) \
            else self.unresolved_mm

    @property
    def field(self) -> dict | None:
        """What the layout's uncertainty does to every photo's mapping, hence to the marks:
        the corners' joint covariance (``corner_cov_mm2``, in the gauge) projected on the
        displacement fields a mapping takes (:func:`field_basis`, a homography's 8): a mark
        at ``p`` is off by ``B(p) c`` with ``c`` of covariance ``cov_mm2``, the same ``c``
        for every mark (the marks near each other share it: it does not average down over
        marks as their own noise does). None without the joint covariance (a layout read
        from a file written before it was kept)."""
        if self.corner_cov_mm2 is None or not self.released.any():
            return self.field_read
        rel = self.released.ravel()
        P = self.declared_mm.reshape(-1, 2)
        centre = P[rel].mean(axis=0)
        scale = float(np.abs(P[rel] - centre).max())
        rc = np.column_stack([2 * np.flatnonzero(rel), 2 * np.flatnonzero(rel) + 1]).ravel()
        L = np.linalg.pinv(field_basis(P[rel], centre, scale))
        C = L @ np.asarray(self.corner_cov_mm2, float)[np.ix_(rc, rc)] @ L.T
        if self.interior_cov_mm2 is not None:   # the marks' own, where they are drawn
            Li = np.linalg.pinv(field_basis(self.interior_xy_mm, centre, scale))
            Ci = Li @ np.asarray(self.interior_cov_mm2, float) @ Li.T
            if np.trace(Ci) > np.trace(C):
                C = Ci
        return {"basis": "homography", "centre_mm": centre.tolist(), "scale_mm": scale,
                "cov_mm2": C.tolist()}

    def corners_for(self, ids, declared_mm) -> np.ndarray:
        """The printed corners of markers ``ids`` (their declared ``declared_mm`` where this
        layout does not know them)."""
        pos = {int(i): k for k, i in enumerate(self.ids)}
        out = np.array(declared_mm, float, copy=True).reshape(-1, 4, 2)
        for j, i in enumerate(np.asarray(ids).ravel()):
            k = pos.get(int(i))
            if k is not None:
                out[j] = self.printed_mm[k]
        return out

    # ------------------------------------------------------------------ JSON
    def to_json(self) -> dict:
        """measurement.json / survey.json ``as_printed`` (docs/format.md)."""
        return {
            "source": self.source,
            "gauge": "best-fitting similarity to the declared layout, each marker's growth "
                     "aside, = identity",
            "rms_mm": self.rms_mm, "max_mm": self.max_mm, "growth_mm": self.growth_mm,
            "field_rms_mm": self.field_rms_mm, "unresolved_mm": self.unresolved_mm,
            "interior_mm": self.interior_mm, "height_rms_mm": self.height_rms_mm,
            "height_unresolved_mm": self.height_unresolved_mm,
            "n_places": int(self.n_places), "lens_free": bool(self.lens_free),
            "K": np.asarray(self.K).tolist(), "dist": np.asarray(self.dist).tolist(),
            "size_px": list(self.size_px),
            "photos": [{"file": f, "corner_rms_px_before": b, "corner_rms_px_after": a,
                        **({"place": int(self.places[k])} if self.places else {})}
                       for k, (f, b, a) in enumerate(zip(self.files, self.rms_px_before,
                                                        self.rms_px_after))],
            "markers": [{"id": int(i), "corners_mm": p.tolist(), "declared_mm": d.tolist(),
                         "std_mm": s.tolist(), "released": [bool(r) for r in rel],
                         **({} if self.heights_mm is None else
                            {"height_mm": np.asarray(self.heights_mm)[k].tolist(),
                             "height_std_mm": np.asarray(self.height_std_mm)[k].tolist()})}
                        for k, (i, p, d, s, rel) in enumerate(zip(
                            self.ids, self.printed_mm, self.declared_mm, self.std_mm,
                            self.released))],
            "notes": list(self.notes),
            "field": self.field,
            "stopped": self.stopped,
            "replication": self.replication,
            "significance": self.significance,
        }

    @classmethod
    def from_json(cls, d: dict) -> "AsPrinted":
        ms = d["markers"]
        ph = d.get("photos") or []
        return cls(np.array([int(m["id"]) for m in ms]),
                   np.array([m["declared_mm"] for m in ms], float).reshape(-1, 4, 2),
                   np.array([m["corners_mm"] for m in ms], float).reshape(-1, 4, 2),
                   np.array([m["std_mm"] for m in ms], float).reshape(-1, 4, 2),
                   np.array([m["released"] for m in ms], bool).reshape(-1, 4),
                   np.asarray(d["K"], float), np.asarray(d["dist"], float),
                   tuple(int(v) for v in d["size_px"]), bool(d["lens_free"]),
                   tuple(p["file"] for p in ph),
                   tuple(float(p["corner_rms_px_before"]) for p in ph),
                   tuple(float(p["corner_rms_px_after"]) for p in ph),
                   int(d["n_places"]), str(d.get("source", "views")),
                   tuple(d.get("notes") or ()),
                   *((np.array([m["height_mm"] for m in ms], float).reshape(-1, 4),
                      np.array([m["height_std_mm"] for m in ms], float).reshape(-1, 4))
                     if ms and all("height_mm" in m for m in ms) else (None, None)),
                   None, d.get("field"),
                   stopped=None if d.get("stopped") is None else str(d["stopped"]),
                   places=(tuple(int(p["place"]) for p in ph)
                           if ph and all("place" in p for p in ph) else ()),
                   replication=d.get("replication"), significance=d.get("significance"),
                   interior_read=(None if d.get("interior_mm") is None
                                  else float(d["interior_mm"])))


# ---------------------------------------------------------------------- projection

def _lens_vector(K, dist) -> np.ndarray:
    d = np.zeros(5)
    dd = np.asarray(dist, float).ravel()[:5]
    d[:len(dd)] = dd
    K = np.asarray(K, float)
    return np.array([0.5 * (K[0, 0] + K[1, 1]), K[0, 2], K[1, 2], d[0], d[1], d[2], d[3], d[4]])


def _lens_matrices(lens):
    f, cx, cy, k1, k2, p1, p2, k3 = lens
    return (np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]]),
            np.array([k1, k2, p1, p2, k3]))


def _similarity_design(p: np.ndarray) -> np.ndarray:
    """(2N, 4): the displacements at points ``p`` (N, 2) of a small similarity
    (tx, ty, a, b), d = t + [[a, -b], [b, a]] p; rows x0, y0, x1, y1, ..."""
    A = np.zeros((2 * len(p), 4))
    A[0::2, 0] = A[1::2, 1] = 1.0
    A[0::2, 2], A[0::2, 3] = p[:, 0], -p[:, 1]
    A[1::2, 2], A[1::2, 3] = p[:, 1], p[:, 0]
    return A


def _gauge_matrix(p: np.ndarray, marker: np.ndarray, growth_sign: np.ndarray) -> np.ndarray:
    """(4, 2N): the small similarity (tx, ty, a, b) of displacements at corners ``p`` (N, 2),
    each marker's growth aside (``marker`` (N,) its index, ``growth_sign`` (N, 2) the
    corner's direction from its marker's centre): toner grows every black square, which
    is no shift, turn or scale of the layout (fitted on the corners alone, a 0.06 mm growth
    of 30 mm markers read as a 3.5e-5 scale of the whole sheet: the links 0.012 mm short)."""
    A = _similarity_design(p)
    _, m = np.unique(marker, return_inverse=True)
    G = np.zeros((2 * len(p), m.max() + 1 if len(m) else 0))
    G[0::2][np.arange(len(p)), m] = growth_sign[:, 0]
    G[1::2][np.arange(len(p)), m] = growth_sign[:, 1]
    return np.linalg.pinv(np.hstack([A, G]))[:4]


def field_basis(p: np.ndarray, centre, scale: float) -> np.ndarray:
    """(2N, 8): the displacement fields a sheet mapping (a homography) can take, at points
    ``p`` (N, 2): shift (2), the linear part (4), the perspective terms (2), in
    ``(p - centre) / scale``; rows x0, y0, x1, y1, ... (mm per unit coefficient)."""
    u = (np.asarray(p, float).reshape(-1, 2) - np.asarray(centre, float)) / float(scale)
    B = np.zeros((2 * len(u), 8))
    B[0::2, 0] = B[1::2, 1] = 1.0
    B[0::2, 2], B[0::2, 3] = u[:, 0], u[:, 1]
    B[1::2, 4], B[1::2, 5] = u[:, 0], u[:, 1]
    B[0::2, 6], B[0::2, 7] = u[:, 0] ** 2, u[:, 0] * u[:, 1]
    B[1::2, 6], B[1::2, 7] = u[:, 0] * u[:, 1], u[:, 1] ** 2
    return B


def _apply_similarity(s, p):
    tx, ty, a, b = s
    return np.column_stack([tx + a * p[:, 0] - b * p[:, 1], ty + b * p[:, 0] + a * p[:, 1]])


def place_labels(rvecs, tvecs, *, min_move_mm: float, min_turn_deg: float) -> np.ndarray:
    """Each pose's camera place (V,) int, numbered in order of first appearance: the first
    earlier place whose camera centre is within ``min_move_mm`` and whose view direction is
    within ``min_turn_deg``, else a new one."""
    places, labels = [], []
    for r, t in zip(rvecs, tvecs):
        R = cv2.Rodrigues(np.asarray(r, float))[0]
        C = -R.T @ np.asarray(t, float).ravel()
        z = R[2]
        k = next((k for k, (c, zz) in enumerate(places)
                  if np.linalg.norm(C - c) < min_move_mm and
                  np.degrees(np.arccos(np.clip(z @ zz, -1, 1))) < min_turn_deg), None)
        if k is None:
            places.append((C, z))
            k = len(places) - 1
        labels.append(k)
    return np.array(labels, int)


# ---------------------------------------------------------------------- the solve

@dataclass(frozen=True)
class _Observations:
    """Every photo's marker corners, gathered for the joint solve.

    ``ids`` (M,) and ``declared`` (M, 4, 2): the markers seen (sorted) and their declared
    corners; ``view`` / ``point`` (n,) and ``px`` (n, 2): each observed corner's photo, its
    corner's index (4 * marker + corner) and its raw pixel; ``rvecs`` / ``tvecs`` (V, 3):
    each photo's start pose (sheet -> camera) against the declared layout."""

    ids: np.ndarray
    declared: np.ndarray
    view: np.ndarray
    point: np.ndarray
    px: np.ndarray
    rvecs: np.ndarray
    tvecs: np.ndarray

    @property
    def P0(self) -> np.ndarray:
        """The declared corners, one row each (4 M, 2)."""
        return self.declared.reshape(-1, 2)


def _observe(views, K, dist0) -> _Observations:
    """The corners of ``views`` as one unknown each over all photos, every photo's
    observations of them, and each photo's start pose (IPPE, else OpenCV's iterative PnP)
    against the declared layout with the lens ``K``, ``dist0``."""
    layout: dict[int, np.ndarray] = {}
    for _, ids, mm, _ in views:
        for i, c in zip(ids, mm):
            layout.setdefault(int(i), np.asarray(c, float))
    ids = np.array(sorted(layout))
    pos = {int(i): k for k, i in enumerate(ids)}
    declared = np.array([layout[int(i)] for i in ids])                      # (M, 4, 2)
    obs_view, obs_pt, obs_px = [], [], []
    rvecs, tvecs = [], []
    for v, (_, mids, mm, px) in enumerate(views):
        ok, r, t = cv2.solvePnP(np.column_stack([mm.reshape(-1, 2), np.zeros(mm.size // 2)]),
                                np.asarray(px, float).reshape(-1, 1, 2), K, dist0,
                                flags=cv2.SOLVEPNP_IPPE)
        if not ok:
            ok, r, t = cv2.solvePnP(np.column_stack([mm.reshape(-1, 2), np.zeros(mm.size // 2)]),
                                    np.asarray(px, float).reshape(-1, 1, 2), K, dist0)
        rvecs.append(np.asarray(r, float).ravel())
        tvecs.append(np.asarray(t, float).ravel())
        for i, c in zip(mids, np.asarray(px, float).reshape(-1, 4, 2)):
            for k in range(4):
                obs_view.append(v)
                obs_pt.append(4 * pos[int(i)] + k)
                obs_px.append(c[k])
    return _Observations(ids, declared, np.array(obs_view), np.array(obs_pt),
                         np.array(obs_px), np.array(rvecs), np.array(tvecs))


def _released(obs: _Observations, min_views: int) -> np.ndarray:
    """Which corners are released (4 M,) bool: seen at least ``min_views`` times, in at
    least ``min_views`` photos."""
    n_points = len(obs.P0)
    n_seen = np.bincount(obs.point, minlength=n_points)
    view_sets = [set(obs.view[obs.point == p]) for p in range(n_points)]
    return np.array([n_seen[p] >= min_views and len(view_sets[p]) >= min_views
                     for p in range(n_points)])


@dataclass(frozen=True)
class _Problem:
    """The bundle adjustment's layout of unknowns and its residuals (module docstring).

    The unknowns ``x``: the lens (``n_lens``: ``LENS_FREE``, when ``lens_free``), then per
    photo ``npv`` values (rvec, tvec, and its focal length's factor when the lens is free),
    then ``nd`` per released corner (its shift in the paper's plane and, with
    ``release_heights``, its height off it). The residuals: every observed pixel (x, y),
    the focal factors' prior (``w_foc``), the corners' prior (``w_delta``)."""

    obs: _Observations
    lens0: np.ndarray
    lens_free: bool
    rel_idx: np.ndarray         # the released corners' indices
    col_of: np.ndarray          # corner index -> its column among the released, -1: fixed
    nd: int
    w_delta: np.ndarray
    w_foc: float
    view_rows: tuple            # per photo, its observations' rows

    @property
    def V(self) -> int:
        """The photos."""
        return len(self.obs.rvecs)

    @property
    def n_lens(self) -> int:
        """The lens's unknowns (0: the lens fixed)."""
        return len(LENS_FREE) if self.lens_free else 0

    @property
    def npv(self) -> int:
        """Unknowns per photo: rvec, tvec (and its focal length's factor)."""
        return 7 if self.lens_free else 6

    @property
    def n_pose(self) -> int:
        """Every photo's unknowns."""
        return self.npv * self.V

    @property
    def n_fixed(self) -> int:
        """The unknowns before the corners' (the lens, the poses)."""
        return self.n_lens + self.n_pose

    @property
    def n_delta(self) -> int:
        """The released corners' unknowns."""
        return self.nd * len(self.rel_idx)

    @property
    def n_foc(self) -> int:
        """The focal factors' prior rows: a phone refocuses, each photo's f = f (1 + e)."""
        return self.V if self.lens_free else 0

    @property
    def m_obs(self) -> int:
        """The pixel residuals (x and y of every observed corner)."""
        return 2 * len(self.obs.px)

    @property
    def foc_cols(self) -> np.ndarray:
        """Each photo's focal factor's column in ``x`` (V,; used only with the lens free)."""
        return self.n_lens + self.npv * np.arange(self.V) + 6

    def labels(self) -> tuple[str, ...]:
        """Each unknown's name, for what the covariance reports: the lens's (``f``, ...),
        each photo's pose (``rx@2``, ``tz@2``, ``df@2``: photo 2) and each released corner's
        (``x@7.1``: marker 7's corner 1)."""
        pose = ("rx", "ry", "rz", "tx", "ty", "tz", "df")[:self.npv]
        corner = ("x", "y", "z")[:self.nd]
        ids = self.obs.ids
        return (LENS_FREE[:self.n_lens]
                + tuple(f"{p}@{v}" for v in range(self.V) for p in pose)
                + tuple(f"{c}@{ids[i // 4]}.{i % 4}" for i in self.rel_idx for c in corner))

    def unpack(self, x):
        """The lens vector (8,), the poses (V, npv) and every corner's delta (4 M, 3) of
        ``x``."""
        lens = self.lens0.copy()
        if self.lens_free:
            lens[:7] = x[:7]
        poses = x[self.n_lens:self.n_lens + self.n_pose].reshape(self.V, self.npv)
        delta = np.zeros((len(self.obs.P0), 3))
        delta[self.rel_idx, :self.nd] = x[self.n_fixed:].reshape(-1, self.nd)
        return lens, poses, delta

    def model(self, x, with_jac: bool):
        """Predicted pixels (n_obs, 2) and, with ``with_jac``, the dense Jacobian of the
        observation rows (OpenCV's own derivatives of its projection)."""
        lens_free, n_lens, npv, n_pose, nd = (self.lens_free, self.n_lens, self.npv,
                                              self.n_pose, self.nd)
        P0, obs_pt, obs_px, col_of = self.obs.P0, self.obs.point, self.obs.px, self.col_of
        lens, poses, delta = self.unpack(x)
        Kx, dx = _lens_matrices(lens)
        P = np.column_stack([P0, np.zeros(len(P0))]) + delta
        pred = np.empty_like(obs_px)
        J = np.zeros((self.m_obs, len(x))) if with_jac else None
        eps = 1e-3
        for v, rows in enumerate(self.view_rows):
            Kv = Kx.copy()
            if lens_free:
                Kv[0, 0] = Kv[1, 1] = Kx[0, 0] * (1.0 + poses[v, 6])
            Pv = P[obs_pt[rows]]
            pv, jv = cv2.projectPoints(Pv, poses[v, :3], poses[v, 3:6], Kv, dx)
            pred[rows] = pv.reshape(-1, 2)
            if not with_jac:
                continue
            r2 = np.column_stack([2 * rows, 2 * rows + 1]).ravel()
            jv = jv.reshape(-1, 2, jv.shape[1]).reshape(2 * len(rows), -1)
            J[r2, n_lens + npv * v:n_lens + npv * v + 6] = jv[:, :6]
            if lens_free:   # f (fx = fy), cx, cy, k1, k2, p1, p2; the photo's focal factor
                J[r2, 0] = (jv[:, 6] + jv[:, 7]) * (1.0 + poses[v, 6])
                J[r2, n_lens + npv * v + 6] = (jv[:, 6] + jv[:, 7]) * Kx[0, 0]
                J[r2, 1], J[r2, 2] = jv[:, 8], jv[:, 9]
                J[r2, 3:7] = jv[:, 10:14]
            cols = col_of[obs_pt[rows]]
            rel = cols >= 0
            if rel.any():   # each corner moves only its own pixel: two shifted projections
                for j in range(nd):
                    Ps = Pv.copy()
                    Ps[:, j] += eps
                    ps, _ = cv2.projectPoints(Ps, poses[v, :3], poses[v, 3:6], Kv, dx)
                    dp = (ps.reshape(-1, 2) - pv.reshape(-1, 2)) / eps
                    rr = rows[rel]
                    cc = self.n_fixed + nd * cols[rel] + j
                    J[2 * rr, cc] = dp[rel, 0]
                    J[2 * rr + 1, cc] = dp[rel, 1]
        return pred, J

    def residuals(self, x) -> np.ndarray:
        """The weighted residuals: pixels, focal factors' prior, corners' prior."""
        pred, _ = self.model(x, False)
        return np.concatenate([(pred - self.obs.px).ravel(),
                               self.w_foc * x[self.foc_cols[:self.n_foc]],
                               self.w_delta * x[self.n_fixed:]])

    def jacobian(self, x) -> np.ndarray:
        """The residuals' dense Jacobian at ``x``."""
        _, J = self.model(x, True)
        n_foc, n_fixed = self.n_foc, self.n_fixed
        F = np.zeros((n_foc, len(x)))
        F[np.arange(n_foc), self.foc_cols[:n_foc]] = self.w_foc
        D = np.hstack([np.zeros((self.n_delta, n_fixed)), np.diag(self.w_delta)])
        return np.vstack([J, F, D])

    def start(self) -> np.ndarray:
        """The start ``x``: the lens as given, the start poses, no focal change, no delta."""
        obs = self.obs
        poses0 = np.column_stack([obs.rvecs, obs.tvecs]
                                 + ([np.zeros(self.V)] if self.lens_free else []))
        return np.concatenate([self.lens0[:7] if self.lens_free else [], poses0.ravel(),
                               np.zeros(self.n_delta)])

    def per_view_rms(self, res) -> tuple[float, ...]:
        """Each photo's RMS pixel residual (2-D) in residual vector ``res``."""
        r = res[:self.m_obs].reshape(-1, 2)
        return tuple(rms_2d(r[self.obs.view == v]) for v in range(self.V))

    def heights_plane(self) -> np.ndarray:
        """The heights' gauge: the released corners' plane design matrix (n, 3)."""
        return np.column_stack([np.ones(len(self.rel_idx)), self.obs.P0[self.rel_idx]])

    def gauge(self) -> np.ndarray:
        """The in-plane gauge: (4, 2 n) the released corners' displacements' best-fitting
        small similarity, each marker's growth fitted beside it (:func:`_gauge_matrix`)."""
        rel_idx, P0 = self.rel_idx, self.obs.P0
        marker = rel_idx // 4
        centres = self.obs.declared.mean(axis=1)
        return _gauge_matrix(P0[rel_idx], marker, np.sign(P0[rel_idx] - centres[marker]))


def _problem(obs: _Observations, released: np.ndarray, lens0: np.ndarray, lens_free: bool,
             cfg: AsPrintedConfig) -> _Problem:
    """The bundle adjustment over ``obs`` with the corners ``released`` free, its priors'
    weights from ``cfg`` (the noise over each prior's size)."""
    rel_idx = np.flatnonzero(released)
    col_of = -np.ones(len(obs.P0), int)
    col_of[rel_idx] = np.arange(len(rel_idx))
    # each released corner: its shift in the paper's plane, and (``release_heights``) its
    # height off it: paper that is not flat shows parallax between places, which a shift
    # alone would take for print
    nd = 3 if cfg.release_heights else 2
    w_prior = cfg.noise_px / cfg.prior_mm
    w_delta = np.tile([w_prior] * 2 + ([cfg.noise_px / cfg.height_prior_mm] if nd == 3 else []),
                      len(rel_idx))
    view_rows = tuple(np.flatnonzero(obs.view == v) for v in range(len(obs.rvecs)))
    return _Problem(obs, lens0, lens_free, rel_idx, col_of, nd, w_delta,
                    cfg.noise_px / cfg.focal_scatter, view_rows)


def _solve(pb: _Problem, huber_px: float, max_nfev: int):
    """The two solves (the one solver, :func:`vision_cal.model.solve.solve`: trf, a Huber
    loss of ``huber_px``, the Jacobian's scale, scipy's default tolerances), each a
    ``Solution``, or a ``StoppedSolve`` after ``max_nfev`` evaluations: ``before`` (the
    declared layout, the lens and the poses free) and the solution from where it reached
    (the released corners free too)."""
    nb, mb, no_delta = pb.n_fixed, pb.m_obs + pb.n_foc, np.zeros(pb.n_delta)
    kw = dict(method="trf", loss="huber", f_scale=huber_px, x_scale="jac", max_nfev=max_nfev,
              xtol=1e-8, ftol=1e-8, gtol=1e-8)
    # posed on the lens and poses alone (a slice of the Jacobian: a free mask's column copy
    # is stored in another order, and its rounding moved the solution by 1e-9)
    before = solve(lambda x: pb.residuals(np.concatenate([x, no_delta]))[:mb], pb.start()[:nb],
                   jac=lambda x: pb.jacobian(np.concatenate([x, no_delta]))[:mb, :nb], **kw)
    sol = solve(pb.residuals, np.concatenate([reached(before).x, no_delta]), jac=pb.jacobian,
                **kw)
    return before, sol


def reached(sol) -> Solution:
    """Where a solve ended: the ``Solution``, or where a ``StoppedSolve`` stopped."""
    return sol if sol else sol.last


def _solution_cov(pb: _Problem, sol: Solution, n_places: int) -> Covariance:
    """The covariance of every unknown at the solution ``sol``, under the one policy
    (:func:`vision_cal.model.solve.covariance`), from the plain Jacobian (not the one the
    Huber loss weighs) and the residual's own scale."""
    r_obs = sol.residuals[:pb.m_obs]
    dof = max(pb.m_obs - (len(sol.x) - 4), 1)
    # photos from one place see the corners with the same detection errors (the same
    # pixels): they carry one view's information, not one each; the variance counts
    # places (38 photos from 4 places: the std was 3 times too small, and a bumped sheet's
    # model error passed for 0.012 mm of print at 5 times it)
    s2 = float(np.sum(r_obs**2)) / dof * pb.V / max(n_places, 1)
    return covariance(pb.jacobian(sol.x), labels=pb.labels(), s2=s2)


def _shared_fixed(pb: _Problem, cov: Covariance) -> bool:
    """Whether the data fix every unknown the photos share (the lens, the corners): a
    direction the views do not fix that moves one leaves the corners' covariance unknown
    (the poses' own aside)."""
    shared = np.concatenate([np.arange(pb.n_lens), pb.n_fixed + np.arange(pb.n_delta)])
    return bool(cov.fixed[shared].all())


def _sheet_point(pb: _Problem, x, v: int, px: np.ndarray) -> np.ndarray:
    """Where pixels ``px`` (N, 2) of photo ``v`` meet the paper's plane (N, 2) mm, through
    the lens and the pose of ``x``."""
    lens, poses, _ = pb.unpack(x)
    K, dist = _lens_matrices(lens)
    if pb.lens_free:
        K[0, 0] = K[1, 1] = K[0, 0] * (1.0 + poses[v, 6])
    R = cv2.Rodrigues(np.asarray(poses[v, :3], float))[0]
    n = cv2.undistortPoints(np.asarray(px, float).reshape(-1, 1, 2), K, dist).reshape(-1, 2)
    ray = np.column_stack([n, np.ones(len(n))]) @ R          # in the sheet frame
    C = -R.T @ poses[v, 3:6]
    return C[:2] + (-C[2] / ray[:, 2])[:, None] * ray[:, :2]


def interior_points(pb: _Problem, n=(6, 4)) -> np.ndarray:
    """(P, 2): a grid over the inner part of the released corners' extent (where marks
    are drawn: between the markers)."""
    P = pb.obs.P0[pb.rel_idx]
    lo, hi = P.min(axis=0), P.max(axis=0)
    lo, hi = lo + 0.15 * (hi - lo), hi - 0.15 * (hi - lo)
    X, Y = np.meshgrid(np.linspace(lo[0], hi[0], n[0]), np.linspace(lo[1], hi[1], n[1]))
    return np.column_stack([X.ravel(), Y.ravel()])


def _map_derivatives(pb: _Problem, x0: np.ndarray, v: int, px: np.ndarray,
                     cols) -> np.ndarray:
    """(2 P, len(cols)): how photo ``v``'s pixel-to-sheet map moves pixels ``px`` (P, 2)
    per unit of the unknowns ``cols`` (central differences)."""
    out = np.zeros((2 * len(px), len(cols)))
    for k, j in enumerate(cols):
        h = 1e-6 * max(abs(x0[j]), 1.0)
        xp, xm = x0.copy(), x0.copy()
        xp[j] += h
        xm[j] -= h
        out[:, k] = (_sheet_point(pb, xp, v, px) - _sheet_point(pb, xm, v, px)).ravel() / (2 * h)
    return out


def _interior_cov(pb: _Problem, sol, cov_x: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(2 P, 2 P): the joint covariance of marks at sheet points ``P`` (P, 2) measured
    through every photo (averaged over the photos), in the gauge, from what every photo
    shares: the lens and the printed corners. Each photo's map is fitted to the corners
    again, so its pose follows them (the pose's own noise is each photo's, in the marks'
    scatter already): a shared change ``ds`` moves the pose by ``-(A'A)^-1 A' B ds`` (``A``,
    ``B`` the photo's rows of the Jacobian in its pose and in the shared unknowns) and the
    mark by the map's derivatives in the lens and the pose; the corners' in-plane part also
    through the gauge (the similarity of their deltas moves every mark), their heights less
    their plane. What the solve leaves between the markers, where the print and an
    undeclared lens trade against each other (its radial terms against a print that grows
    outward, the paper's heights)."""
    x0 = np.asarray(sol.x, float)
    J = pb.jacobian(x0)[:pb.m_obs]
    lens_cols = list(range(pb.n_lens))
    shared = np.concatenate([np.arange(pb.n_lens), pb.n_fixed + np.arange(pb.n_delta)])
    G = np.zeros((2 * len(P), len(shared)))
    lens, poses, _ = pb.unpack(x0)
    for v, rows in enumerate(pb.view_rows):
        K, dist = _lens_matrices(lens)
        if pb.lens_free:
            K[0, 0] = K[1, 1] = K[0, 0] * (1.0 + poses[v, 6])
        px = cv2.projectPoints(np.column_stack([P, np.zeros(len(P))]), poses[v, :3],
                               poses[v, 3:6], K, dist)[0].reshape(-1, 2)
        pose_cols = list(pb.n_lens + pb.npv * v + np.arange(pb.npv))
        r2 = np.column_stack([2 * rows, 2 * rows + 1]).ravel()
        follow = -np.linalg.lstsq(J[np.ix_(r2, pose_cols)], J[np.ix_(r2, shared)],
                                  rcond=None)[0]                     # (npv, shared)
        Gv = _map_derivatives(pb, x0, v, px, pose_cols) @ follow
        if lens_cols:
            Gv[:, :pb.n_lens] += _map_derivatives(pb, x0, v, px, lens_cols)
        G += Gv / pb.V
    if len(pb.rel_idx) >= 3:
        sim = _similarity_design(P) @ pb.gauge()               # (2 P, 2 n_rel)
        cols = pb.n_lens + pb.nd * np.arange(len(pb.rel_idx))
        G[:, cols] -= sim[:, 0::2]
        G[:, cols + 1] -= sim[:, 1::2]
    C = cov_x[np.ix_(shared, shared)]
    if pb.nd == 3 and len(pb.rel_idx) >= 3:
        # the heights in their gauge (less their best-fitting plane): a plane of the corners
        # is the paper's, which the marks lie on too
        plane = pb.heights_plane()
        T = np.eye(len(shared))
        hc = pb.n_lens + pb.nd * np.arange(len(pb.rel_idx)) + 2
        T[np.ix_(hc, hc)] = np.eye(len(hc)) - plane @ np.linalg.pinv(plane)
        C = T @ C @ T.T
    return G @ C @ G.T


def _corner_std(pb: _Problem, cov: Covariance | None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The released corners' std from the solution's covariance ``cov``
    (:func:`_solution_cov`): in-plane (4 M, 2), in the gauge (less the best-fitting
    similarity, each marker's growth aside), and the heights' (4 M,), less their
    best-fitting plane; and the in-plane joint covariance in the gauge (2 M 4, 2 M 4),
    zero where not released (``AsPrinted.corner_cov_mm2``). NaN std and no covariance
    (None) when ``cov`` is None (the views do not fix the lens or the corners); 0 for the
    corners not released."""
    P0, rel_idx, nd, n_delta = pb.obs.P0, pb.rel_idx, pb.nd, pb.n_delta
    std = np.zeros_like(P0)
    hstd = np.zeros(len(P0))
    if cov is None:
        std[rel_idx] = np.nan
        hstd[rel_idx] = np.nan
        return std, hstd, None
    plane = pb.heights_plane()
    gauge = pb.gauge()
    cov3 = cov.matrix[pb.n_fixed:, pb.n_fixed:]
    inplane = (np.arange(n_delta) % nd) < 2
    c2 = cov3[np.ix_(inplane, inplane)]
    if nd == 3 and len(rel_idx) >= 3:   # heights less their best-fitting plane
        Qh = np.eye(len(plane)) - plane @ np.linalg.pinv(plane)
        ch = cov3[np.ix_(~inplane, ~inplane)]
        hstd[rel_idx] = np.sqrt(np.clip(np.diag(Qh @ ch @ Qh.T), 0, None))
    # in the gauge: the deviations less their best-fitting similarity (growth aside)
    A = _similarity_design(P0[rel_idx])
    Q = np.eye(len(A)) - A @ gauge
    c2 = Q @ c2 @ Q.T
    std[rel_idx] = np.sqrt(np.clip(np.diag(c2), 0, None)).reshape(-1, 2)
    full = np.zeros((2 * len(P0), 2 * len(P0)))
    rc = np.column_stack([2 * rel_idx, 2 * rel_idx + 1]).ravel()
    full[np.ix_(rc, rc)] = c2
    return std, hstd, full


def _in_gauge(pb: _Problem, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The solved deltas (4 M, 3) in the gauge: the in-plane shifts (4 M, 2) less their
    best-fitting similarity to the declared layout (each marker's growth aside,
    :meth:`_Problem.gauge`), and the heights (4 M,) less their best-fitting plane (zeros
    when heights are not released)."""
    P0, rel_idx = pb.obs.P0, pb.rel_idx
    heights = np.zeros(len(P0))
    if pb.nd == 3 and len(rel_idx) >= 3:
        plane = pb.heights_plane()
        h = delta[rel_idx, 2]
        heights[rel_idx] = h - plane @ np.linalg.lstsq(plane, h, rcond=None)[0]
    delta = delta[:, :2]
    sim = pb.gauge() @ delta[rel_idx].ravel() if len(rel_idx) >= 3 else np.zeros(4)
    delta[rel_idx] -= _apply_similarity(sim, P0[rel_idx])
    return delta, heights


def estimate_as_printed(views, K, dist, size_px, *, lens_free: bool,
                        config: AsPrintedConfig | None = None, source: str = "views"
                        ) -> AsPrinted | None:
    """The as-printed layout from ``views``: list of (file, marker_ids (M,), declared
    corners_mm (M, 4, 2), raw corners_px (M, 4, 2)). ``K``, ``dist``: the lens (start, or
    fixed when ``lens_free`` is False). None when fewer than ``config.min_places`` camera
    places (``config``: default ``vision_cal.config.DEFAULT.as_printed``)."""
    cfg = config or DEFAULT.as_printed
    views = [v for v in views if len(v[1]) >= 4]
    if len(views) < 2:
        return None
    K = np.asarray(K, float)
    dist0 = np.zeros(5)
    dd = np.asarray(dist if dist is not None else np.zeros(5), float).ravel()[:5]
    dist0[:len(dd)] = dd
    if lens_free:   # the solve frees k1 k2 p1 p2, not k3: held at zero, never at a start's
        # (stage 2's k3 of -0.42, fitted on the layout as declared, held in the solve: k1 and
        # k2 bent around it and the marks between the markers were 0.155 mm off, 0.050 with
        # it at zero; issue 37, world2)
        dist0[4] = 0.0
    obs = _observe(views, K, dist0)
    scale = float(np.median(np.abs(obs.tvecs[:, 2])))
    places = place_labels(obs.rvecs, obs.tvecs, min_move_mm=cfg.place_move * scale,
                          min_turn_deg=cfg.place_turn_deg)
    n_places = int(places.max()) + 1
    if n_places < cfg.min_places:
        return None
    released = _released(obs, cfg.min_views)
    pb = _problem(obs, released, _lens_vector(K, dist0), lens_free, cfg)
    before, sol = _solve(pb, cfg.huber_px, cfg.max_evaluations)
    end = reached(sol)
    lens, _, delta = pb.unpack(end.x)
    cov = _solution_cov(pb, end, n_places)
    notes = [] if sol else [f"the bundle adjustment stopped: {end.status}"]
    if not _shared_fixed(pb, cov):
        notes.append(f"the views do not fix {cov.reason()}: the corners' std is unknown")
        cov = None
    std, hstd, full = _corner_std(pb, cov)
    inner_xy = interior_points(pb) if len(pb.rel_idx) >= 3 else None
    inner = None if inner_xy is None or cov is None else _interior_cov(
        pb, end, cov.matrix, inner_xy)
    delta, heights = _in_gauge(pb, delta)
    Kf, df = _lens_matrices(lens)
    nd = pb.nd
    return AsPrinted(obs.ids, obs.declared, (obs.P0 + delta).reshape(-1, 4, 2),
                     std.reshape(-1, 4, 2), released.reshape(-1, 4), Kf, df,
                     (int(size_px[0]), int(size_px[1])), bool(lens_free),
                     tuple(v[0] for v in views), pb.per_view_rms(reached(before).residuals),
                     pb.per_view_rms(end.residuals), n_places, source, tuple(notes),
                     heights.reshape(-1, 4) if nd == 3 else None,
                     hstd.reshape(-1, 4) if nd == 3 else None, full,
                     stopped=stopped_reason(sol, cfg.max_evaluations),
                     places=tuple(int(p) for p in places),
                     interior_xy_mm=None if inner is None else inner_xy,
                     interior_cov_mm2=inner)


def stopped_reason(sol, max_nfev: int) -> str | None:
    """Why a solve (:func:`vision_cal.model.solve.solve`) stopped before converging (its
    evaluation limit, or a failure), None when it converged."""
    if sol:
        return None
    if sol.on_limit:
        return (f"the bundle adjustment stopped at its evaluation limit ({max_nfev}) before "
                f"converging ({sol.last.nfev} evaluations)")
    return f"the bundle adjustment failed: {sol.last.status}"


def _released_design(declared_mm, released):
    """The released corners of ``declared_mm`` (M, 4, 2) (``released`` (M, 4)): their
    similarity design (:func:`_similarity_design`) and the gauge's fit of a small
    similarity with each marker's growth beside it (:func:`_gauge_matrix`)."""
    dec = np.asarray(declared_mm, float).reshape(-1, 4, 2)
    rel = np.asarray(released, bool).reshape(-1, 4).ravel()
    p = dec.reshape(-1, 2)[rel]
    marker = np.repeat(np.arange(len(dec)), 4)[rel]
    sign = np.sign(dec - dec.mean(axis=1, keepdims=True)).reshape(-1, 2)[rel]
    return _similarity_design(p), _gauge_matrix(p, marker, sign)


def layout_similarity(declared_mm, released, deviation_mm):
    """The small similarity of ``deviation_mm`` (M, 4, 2) over the ``released`` (M, 4)
    corners of ``declared_mm``, each marker's growth aside (what the gauge sets to zero):
    (shift (2,) mm, scale - 1, turn rad, the largest displacement it makes at those
    corners, mm)."""
    A, G = _released_design(declared_mm, released)
    rel = np.asarray(released, bool).reshape(-1, 4).ravel()
    s = G @ np.asarray(deviation_mm, float).reshape(-1, 2)[rel].ravel()
    worst = float(np.linalg.norm((A @ s).reshape(-1, 2), axis=1).max()) if len(A) else 0.0
    return s[:2], float(s[2]), float(s[3]), worst


def gauge_projector(declared_mm, released) -> np.ndarray:
    """(2 n, 2 n) over the ``released`` (M, 4) corners of ``declared_mm`` (M, 4, 2), rows x0,
    y0, x1, y1, ... in their order: displacements less their best-fitting small similarity,
    each marker's growth fitted beside it (the layout's gauge, :func:`_gauge_matrix`). Two
    layouts fixed in the gauge over different corners agree on the corners both know only
    once both are taken into the gauge over those (:mod:`vision_cal.measure.replicate`)."""
    A, G = _released_design(declared_mm, released)
    return np.eye(len(A)) - A @ G
