"""Measuring the sheet: ArUco grid to sheet millimetres, pen marks to sub-pixel centres.

Frames and units: sheet frame S (x right, y up, mm) as in the dataset format; image pixels
(u, v) = (column, row), integer at pixel centres (OpenCV). Covariances in mm^2.

Public API (imports are lazy so that ``import vision_cal.measure`` stays light)::

    measure_folder(session, *, out_dir, jobs=None, cache_dir=None, progress=None, config=None)
        -> Measurement(marks={id: MarkMeasurement}, images=[ImageResult], lens, ...)
    measure_image(path, session, *, lens=None, config=None) -> ImageResult

Modules: ``aruco`` (markers, sub-pixel edges), ``mapping`` (lens + homography, lens
estimate), ``dots`` (ink dots and their centres on the sheet), ``associate`` (dots to
plan mark ids), ``types`` (the measurement's types and their JSON), ``cache`` (per-photo
cache), ``batch`` (the pipeline).
"""

from __future__ import annotations

__all__ = ["measure_folder", "measure_image", "Measurement", "MarkMeasurement", "ImageResult",
           "LensEstimate"]


def __getattr__(name):
    # local imports: ``import vision_cal.measure`` stays light (no OpenCV) until one is used
    if name in ("measure_folder", "measure_image"):
        from vision_cal.measure import batch
        return getattr(batch, name)
    if name in ("Measurement", "MarkMeasurement", "ImageResult"):
        from vision_cal.measure import types
        return getattr(types, name)
    if name == "LensEstimate":
        from vision_cal.measure.mapping import LensEstimate
        return LensEstimate
    raise AttributeError(name)
