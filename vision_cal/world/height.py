"""A sheet that is not flat: the height field under the paper (the renderer's world only).

The paper lies on the table with smooth bumps, a curled edge and a sag. Its height above
the plane of the markers' nominal positions (z = 0, z up towards the camera, mm) is

    h(x, y) = sum_bumps  height_mm * exp(-|p - centre|^2 / (2 sigma^2))
            + sum_curls  height_mm * max(0, 1 - d_edge(p) / width_mm)^2
            - sag_mm * (1 - u^2) (1 - v^2)

with ``d_edge`` the distance of p from the named paper edge and (u, v) in [-1, 1] the
position across the paper. Random bumps (``random``) are drawn from the scene seed.

The paper is displaced vertically: the printed point with sheet coordinates (x, y) (its
texture position) sits at (x, y, h(x, y)). The pen, which moves in the robot plane,
leaves its ink at its own (x, y) on the raised paper, so a mark's sheet coordinates are
the pen's xy and its height is h there. Seen from a camera at C (height H above the
paper), a point raised by z appears where its ray meets z = 0, moved by
``z (p - C_xy) / (H - z)``: about ``z r / H`` outward from the nadir.

This is the world's own implementation; the estimator never imports it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


EDGES = ("left", "right", "bottom", "top")
MESH_STEP_MM = 2.0   # paper mesh spacing (h is smooth over tens of mm: < 1e-3 mm error)


@dataclass(frozen=True)
class Bump:
    centre_mm: tuple[float, float]
    sigma_mm: float
    height_mm: float

    def to_json(self) -> dict:
        return {"centre_mm": list(self.centre_mm), "sigma_mm": self.sigma_mm,
                "height_mm": self.height_mm}


@dataclass(frozen=True)
class Curl:
    edge: str
    height_mm: float
    width_mm: float

    def to_json(self) -> dict:
        return {"edge": self.edge, "height_mm": self.height_mm, "width_mm": self.width_mm}


@dataclass(frozen=True)
class RandomBumps:
    """``n`` bumps drawn from the scene seed: heights uniform in ``height_mm`` with a random
    sign when ``signed``, widths uniform in ``sigma_mm``, centres uniform on the paper."""

    n: int
    height_mm: tuple[float, float] = (0.3, 0.65)
    sigma_mm: tuple[float, float] = (25.0, 60.0)
    signed: bool = True

    def to_json(self) -> dict:
        return {"n": self.n, "height_mm": list(self.height_mm),
                "sigma_mm": list(self.sigma_mm), "signed": self.signed}


@dataclass(frozen=True)
class HeightField:
    """The sheet's height field (see the module docstring); ``extent_mm`` the paper."""

    extent_mm: tuple[float, float, float, float]
    bumps: tuple[Bump, ...] = ()
    curls: tuple[Curl, ...] = ()
    sag_mm: float = 0.0

    @property
    def is_flat(self) -> bool:
        return not self.bumps and not self.curls and self.sag_mm == 0.0

    def height_mm(self, xy_mm) -> np.ndarray:
        """h (N,) mm at sheet points (N, 2)."""
        p = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        x0, y0, x1, y1 = self.extent_mm
        h = np.zeros(len(p))
        for b in self.bumps:
            d2 = np.sum((p - np.asarray(b.centre_mm)) ** 2, axis=1)
            h += b.height_mm * np.exp(-d2 / (2.0 * b.sigma_mm**2))
        for c in self.curls:
            d = {"left": p[:, 0] - x0, "right": x1 - p[:, 0], "bottom": p[:, 1] - y0,
                 "top": y1 - p[:, 1]}[c.edge]
            h += c.height_mm * np.clip(1.0 - d / c.width_mm, 0.0, None) ** 2
        if self.sag_mm:
            u = (2.0 * p[:, 0] - x0 - x1) / (x1 - x0)
            v = (2.0 * p[:, 1] - y0 - y1) / (y1 - y0)
            h -= self.sag_mm * (1.0 - u * u) * (1.0 - v * v)
        return h

    def grid(self, step_mm: float = MESH_STEP_MM):
        """(xs (nx,), ys (ny,), Z (ny, nx)) on a regular grid covering the paper exactly."""
        x0, y0, x1, y1 = self.extent_mm
        nx = max(int(np.ceil((x1 - x0) / step_mm)), 1) + 1
        ny = max(int(np.ceil((y1 - y0) / step_mm)), 1) + 1
        xs, ys = np.linspace(x0, x1, nx), np.linspace(y0, y1, ny)
        X, Y = np.meshgrid(xs, ys)
        Z = self.height_mm(np.column_stack([X.ravel(), Y.ravel()])).reshape(X.shape)
        return xs, ys, Z

    def to_json(self, *, sample_step_mm: float = 10.0) -> dict:
        """truth.json ``sheet_height``: the model and the field sampled every 10 mm."""
        xs, ys, Z = self.grid(sample_step_mm)
        return {"bumps": [b.to_json() for b in self.bumps],
                "curls": [c.to_json() for c in self.curls], "sag_mm": self.sag_mm,
                "grid": {"x_mm": xs.tolist(), "y_mm": ys.tolist(),
                         "z_mm": np.round(Z, 5).tolist()},
                "max_abs_mm": float(np.abs(Z).max()) if Z.size else 0.0}

    def effect_json(self) -> dict:
        """truth.json's ``sheet_height`` effect entry (format effect table)."""
        d = self.to_json()
        return {"name": "sheet_height", "grid": d["grid"], "max_abs_mm": d["max_abs_mm"]}


@dataclass(frozen=True)
class HeightScene:
    """The scene's description (``sheet.height``); :meth:`field` makes the field."""

    bumps: tuple[Bump, ...] = ()
    curls: tuple[Curl, ...] = ()
    sag_mm: float = 0.0
    random: RandomBumps | None = None

    def field(self, extent_mm, seed: int) -> HeightField:
        bumps = list(self.bumps)
        if self.random is not None and self.random.n > 0:
            rng = np.random.default_rng(np.random.SeedSequence([int(seed), 13]))
            x0, y0, x1, y1 = (float(v) for v in extent_mm)
            r = self.random
            for _ in range(r.n):
                h = rng.uniform(*r.height_mm)
                if r.signed and rng.random() < 0.5:
                    h = -h
                bumps.append(Bump((float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1))),
                                  float(rng.uniform(*r.sigma_mm)), float(h)))
        return HeightField(tuple(float(v) for v in extent_mm), tuple(bumps), self.curls,
                           self.sag_mm)


def height_scene_from_dict(r, d, where: str = "sheet.height") -> HeightScene | None:
    """Parse ``sheet.height`` with the scene reader ``r`` (errors name the field)."""
    if d is None:
        return None
    d = r.section(d, where, ("bumps", "curls", "sag_mm", "random"))
    bumps = []
    for i, b in enumerate(r.list_(d.get("bumps") or [], f"{where}.bumps")):
        w = f"{where}.bumps[{i}]"
        b = r.section(b, w, ("centre_mm", "sigma_mm", "height_mm"))
        for k in ("centre_mm", "sigma_mm", "height_mm"):
            if k not in b:
                r.fail(f"{w}.{k}", "missing required field")
        bumps.append(Bump(r.vector(b["centre_mm"], f"{w}.centre_mm", 2),
                          r.number(b["sigma_mm"], f"{w}.sigma_mm", lo=1.0),
                          r.number(b["height_mm"], f"{w}.height_mm", lo=-20, hi=20)))
    curls = []
    for i, c in enumerate(r.list_(d.get("curls") or [], f"{where}.curls")):
        w = f"{where}.curls[{i}]"
        c = r.section(c, w, ("edge", "height_mm", "width_mm"))
        curls.append(Curl(r.choice(c.get("edge"), f"{w}.edge", EDGES),
                          r.number(c.get("height_mm", 1.0), f"{w}.height_mm", lo=-20, hi=20),
                          r.number(c.get("width_mm", 40.0), f"{w}.width_mm", lo=1.0)))
    sag = r.number(d.get("sag_mm", 0.0), f"{where}.sag_mm", lo=-20, hi=20)
    rnd = None
    if d.get("random") is not None:
        w = f"{where}.random"
        q = r.section(d["random"], w, ("n", "height_mm", "sigma_mm", "signed"))
        dflt = RandomBumps(0)
        hr = r.vector(q.get("height_mm", list(dflt.height_mm)), f"{w}.height_mm", 2, lo=0,
                      hi=20)
        sr = r.vector(q.get("sigma_mm", list(dflt.sigma_mm)), f"{w}.sigma_mm", 2, lo=1.0)
        if hr[0] > hr[1] or sr[0] > sr[1]:
            r.fail(w, "expected [min, max] ranges")
        rnd = RandomBumps(r.integer(q.get("n", 4), f"{w}.n", lo=0, hi=100), hr, sr,
                          r.boolean(q.get("signed", True), f"{w}.signed"))
    return HeightScene(tuple(bumps), tuple(curls), sag, rnd)

