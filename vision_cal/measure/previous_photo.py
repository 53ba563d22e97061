"""The photo before: what is printed under a new pen mark, seen without it.

A series that adds marks photo by photo (each photo lists the marks of the one before and
more, ``images[].marks`` in docs/format.md) shows every new mark's place in the photo
before, without the mark. Mapped through both photos' sheet mappings, that photo is the
print under the mark as this camera sees it (blur, ink, paper), whatever generator drew the
sheet. :func:`vision_cal.measure.dots.refine_dot` fits it to the photo around the mark
(``S = a + b S_before``: exposure and white balance change between photos) and measures the
pen's ink against it, for a sheet whose print is not described (``sheet.printed``), where
otherwise only the paper-and-grid model is left.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision_cal.dataset import photos
from vision_cal.measure.mapping import SheetMapping


@dataclass(frozen=True)
class PreviousPhoto:
    """The photo before ``file``: ``S`` (H, W) float32 the sum of its three channels in its
    measured pixel frame, ``mapping`` its sheet mapping."""

    file: str
    S: np.ndarray
    mapping: SheetMapping

    def sample(self, X_mm: np.ndarray, Y_mm: np.ndarray) -> np.ndarray:
        """``S`` at sheet points (same shape as ``X_mm``); -1 outside the photo."""
        X_mm = np.asarray(X_mm, float)
        uv = self.mapping.sheet_to_image(np.column_stack([X_mm.ravel(),
                                                          np.asarray(Y_mm, float).ravel()]))
        mx = uv[:, 0].reshape(X_mm.shape).astype(np.float32)
        my = uv[:, 1].reshape(X_mm.shape).astype(np.float32)
        return cv2.remap(self.S, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                         borderValue=-1.0)


def previous_photos(session, root, files, listed_marks, results,
                    only=None) -> dict[int, PreviousPhoto]:
    """{k: the photo before photo ``k``} for a series adding marks photo by photo: photo
    ``k - 1`` (in the listed order) was measured, and its listed marks are fewer than and all
    among photo ``k``'s. ``files`` and ``listed_marks`` per photo (None: not listed),
    ``results`` their :class:`vision_cal.measure.types.ImageResult`. A photo that cannot be
    read again is no reference (nothing else changes). ``only``: the photos to look at
    (default all)."""
    out = {}
    cam = session.camera
    for k in range(1, len(files)):
        if only is not None and k not in only:
            continue
        before, now = listed_marks[k - 1], listed_marks[k]
        prev = results[k - 1]
        if before is None or now is None or prev.status != "ok" or prev.mapping is None:
            continue
        if not (set(before) < set(now)) or results[k].status != "ok":
            continue
        try:
            data = photos.read_photo(root, files[k - 1])
            turned = photos.check_header(photos.read_header(data),
                                         None if cam is None else cam.size_px)
        except photos.PhotoRefused:
            continue
        img = photos.decode_photo(data, turned=turned)
        if img is None or tuple(img.shape[1::-1]) != tuple(prev.size_px or ()):
            continue
        out[k] = PreviousPhoto(files[k - 1], photos.channel_sum(img), prev.mapping)
    return out
