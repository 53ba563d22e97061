"""The paper's scale, a stated uncertainty of every length (issue 37, calibration.json
``paper_scale``).

Marks on a paper are measured in the paper's own millimetres. Paper grows and shrinks 0.1-0.3 %
with humidity and a printer's scale is off by about 0.1 %, and a uniform scale of the
paper is exactly a uniform scale of the link lengths and the base: the marks cannot tell
them apart (a sheet that shrank 0.15 % left L1 and L2 0.56 and 0.42 mm off with stds of
0.018 and 0.015 mm). Targets on the paper are hit all the same (the robot and the targets
share the paper's millimetres); a length in physical millimetres, and a target off the
paper measured from it, carry the scale times their length (a target ``d`` mm beyond the
paper's edge: ``kappa d``).

``kappa`` (one std, relative): ``uncertainty.paper_scale_std`` (0.2 %) unless the printed
100 mm bars were measured with a caliper (``sheet.printed.measured_bar_mm``, or
``vision-cal calibrate --bars-mm X,Y``); then the physical lengths are
``printer_scale.physical_mm`` and ``kappa`` is the caliper reading's
(``uncertainty.bar_reading_mm`` over the bar's length, over sqrt 2 for the two bars'
mean). calibration.json ``std`` stays the marks' std; ``paper_scale.std_with_paper_scale``
is it with the scale added in quadrature.
"""

from __future__ import annotations

import math

import numpy as np

from vision_cal.config import DEFAULT, EstimatorConfig
from vision_cal.errors import VisionCalError

#: how far a measured bar may be from its printed length before it is a misreading
#: (paper and printers move tenths of a percent; 2 % is a wrong number, not a scale)
BAR_TOLERANCE = 0.02


def outside_mm(xy_mm, extent) -> np.ndarray:
    """(N, 2) how far each point ``xy_mm`` (N, 2) lies outside the box ``extent`` (x0, y0,
    x1, y1) along x and y (0 inside): the length a target off the paper is measured over."""
    p = np.asarray(xy_mm, float).reshape(-1, 2)
    x0, y0, x1, y1 = (float(v) for v in extent)
    lo, hi = np.array([x0, y0]), np.array([x1, y1])
    return np.abs(p - np.clip(p, lo, hi))


def check_bars(bars_mm, bar_mm: float = 100.0, *, field: str = "--bars-mm") -> tuple[float, float]:
    """The two printed bars as measured (x then y, mm), refused (one line naming ``field``)
    unless finite and within :data:`BAR_TOLERANCE` of ``bar_mm``."""
    try:
        x, y = (float(v) for v in bars_mm)
    except (TypeError, ValueError) as e:
        raise VisionCalError(f"expected two lengths X,Y in mm, got {bars_mm!r}",
                             field=field) from e
    for name, v in (("X", x), ("Y", y)):
        if not (math.isfinite(v) and abs(v / bar_mm - 1.0) <= BAR_TOLERANCE):
            raise VisionCalError(f"the {name} bar measured {v:g} mm: a printed {bar_mm:g} mm bar "
                                 f"is within {100 * BAR_TOLERANCE:g} % of it (paper and printers "
                                 "move tenths of a percent); measure it again", field=field)
    return x, y


def paper_scale_block(sheet, params: dict | None, std: dict | None, printer: dict | None,
                      config: EstimatorConfig | None = None) -> dict | None:
    """calibration.json ``paper_scale`` (module docstring): ``source`` (``prior`` or
    ``measured bars``), ``scale_std`` (kappa), ``reason``, ``sheet_extent_mm`` (the paper,
    x0 y0 x1 y1: targets inside carry no scale), ``lengths_of`` (``params`` or
    ``printer_scale.physical_mm``), ``std_with_paper_scale`` (``L1_mm``, ``L2_mm``,
    ``base_mm``: the marks' std and ``kappa`` times the length, the base's over its
    distance outside the paper) and ``text``. None without a sheet (marks measured by an
    instrument in physical millimetres) or without the fit's parameters and std."""
    if sheet is None or not params or not std:
        return None
    uc = (config or DEFAULT).uncertainty
    ext = [float(v) for v in sheet.extent_mm]
    if printer is not None:
        bar = float(printer.get("bar_mm", 100.0))
        kappa = uc.bar_reading_mm / bar / math.sqrt(2.0)
        source, of = "measured bars", "printer_scale.physical_mm"
        reason = (f"the printed {bar:g} mm bars measured ({printer['measured_bar_mm'][0]:g}, "
                  f"{printer['measured_bar_mm'][1]:g} mm), each read to "
                  f"{uc.bar_reading_mm:g} mm (config uncertainty.bar_reading_mm)")
        lengths = {**params, **(printer.get("physical_mm") or {})}
    else:
        kappa = uc.paper_scale_std
        source, of = "prior", "params"
        reason = ("the printed bars not measured: paper grows and shrinks 0.1-0.3 % with "
                  "humidity and a printer's scale is within about 0.1 % (config "
                  "uncertainty.paper_scale_std); marks on the paper cannot tell its scale from "
                  "the link lengths: measure the two 100 mm bars with a caliper (vision-cal "
                  "calibrate --bars-mm X,Y)")
        lengths = params
    d_base = outside_mm([params["base_mm"]], ext)[0]
    out = {"source": source, "scale_std": kappa, "reason": reason, "sheet_extent_mm": ext,
           "lengths_of": of,
           "std_with_paper_scale": {
               "L1_mm": math.hypot(std["L1_mm"], kappa * lengths["L1_mm"]),
               "L2_mm": math.hypot(std["L2_mm"], kappa * lengths["L2_mm"]),
               "base_mm": [math.hypot(std["base_mm"][k], kappa * d_base[k]) for k in (0, 1)]}}
    w = out["std_with_paper_scale"]
    out["text"] = (f"paper scale ({source}, {100 * kappa:.2g} % one std): L1 +- "
                   f"{w['L1_mm']:.3f} mm, L2 +- {w['L2_mm']:.3f} mm in physical mm (the marks "
                   f"alone: {std['L1_mm']:.3f}, {std['L2_mm']:.3f}); targets off the paper "
                   f"+- {kappa * 100:.3f} mm per 100 mm beyond its edge")
    return out
