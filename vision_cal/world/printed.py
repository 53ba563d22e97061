"""The renderer's paper texture from a printed sheet's own raster.

``vision-cal sheet --png-dpi N`` writes ``sheet.png`` next to ``sheet.json``; this module
lets the synthetic world photograph exactly that print instead of the analytic sheet of
:mod:`vision_cal.world.sheet`: the raster is the ink on the paper, the paper colour and
grain are added here, the pen dots by :func:`vision_cal.world.sheet.ink_marks` (the
analytic sheet's dot model).

Texture convention: the same as :mod:`vision_cal.world.sheet` (row 0 at the top,
``px_per_mm`` = dpi / 25.4, the paper a whole number of pixels).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from vision_cal.dataset.session import Sheet, load_sheet_file
from vision_cal.errors import VisionCalError
from vision_cal.world.sheet import (PAPER_RGB, displacement_maps, ink_marks, paper_field,
                                     texture_shape)


@dataclass(frozen=True)
class PrintedSheet:
    """A printed sheet: its description ``sheet`` (from sheet.json), its raster ``rgb``
    (H, W, 3) uint8 (white paper = 255) and the raster's ``px_per_mm``."""

    sheet: Sheet
    rgb: np.ndarray
    px_per_mm: float


def load_printed_sheet(sheet_json, png=None) -> PrintedSheet:
    """Read ``sheet.json`` and its raster (``png``, default ``sheet.png`` beside it).

    The scale comes from ``sheet.printed.png_dpi`` (else the PNG's own dpi); the raster must
    cover the paper with a whole number of pixels (e.g. 254 dpi = 10 px/mm).
    """
    sheet_json = Path(sheet_json)
    sheet = load_sheet_file(sheet_json)
    png = Path(png) if png is not None else sheet_json.with_name("sheet.png")
    try:
        with Image.open(png) as im:
            dpi_meta = im.info.get("dpi", (None,))[0]
            rgb = np.asarray(im.convert("RGB"))
    except FileNotFoundError as e:
        raise VisionCalError("not found (write it with vision-cal sheet --png-dpi N)",
                             file=str(png)) from e
    except OSError as e:
        raise VisionCalError(f"unreadable image: {e}", file=str(png)) from e
    dpi = (sheet.printed or {}).get("png_dpi") or dpi_meta
    if not dpi:
        raise VisionCalError("no dpi: neither sheet.printed.png_dpi nor the PNG says it",
                             file=str(sheet_json), field="printed.png_dpi")
    ppm = float(dpi) / 25.4
    try:
        shape = texture_shape(sheet.extent_mm, ppm)
    except VisionCalError as e:
        raise VisionCalError(f"{e.reason} (write the PNG at a dpi that is a multiple of "
                             "25.4 / mm, e.g. 254)", file=str(png)) from e
    if rgb.shape[:2] != shape:
        raise VisionCalError(f"expected {shape[1]} x {shape[0]} px for the paper at {dpi:g} "
                             f"dpi, got {rgb.shape[1]} x {rgb.shape[0]}", file=str(png))
    return PrintedSheet(sheet, rgb, ppm)


def printed_texture(printed: PrintedSheet, *, marks_xy_mm, mark_diameters_mm=1.2,
                    px_per_mm: float | None = None, rng=None,
                    paper_grain: bool = True, print_field=None) -> np.ndarray:
    """The printed sheet with its pen marks: (H, W, 3) uint8 RGB, like ``sheet_texture``.

    ``print_field`` (:class:`vision_cal.world.print_deviation.PrintField`): the raster's
    ink displaced by its field (its toner growth is not applied to a raster).

    ``px_per_mm``, when given, must be the raster's own (the print is not resampled).
    """
    return printed_textures(printed, marks_xy_mm=marks_xy_mm,
                            mark_diameters_mm=mark_diameters_mm, px_per_mm=px_per_mm, rng=rng,
                            paper_grain=paper_grain, print_field=print_field)[0]


def printed_textures(printed: PrintedSheet, *, marks_xy_mm, mark_diameters_mm=1.2,
                     px_per_mm: float | None = None, rng=None, paper_grain: bool = True,
                     print_field=None):
    """``(with the marks, without them)`` from one build, like ``sheet_textures``."""
    ppm = printed.px_per_mm
    if px_per_mm is not None and abs(float(px_per_mm) - ppm) > 1e-9:
        raise VisionCalError(f"the printed raster is {ppm:g} px/mm, not {px_per_mm:g}",
                             field="px_per_mm")
    rng = np.random.default_rng(rng)
    H, W = printed.rgb.shape[:2]
    paper = paper_field((H, W), rng) if paper_grain else np.ones((H, W), np.float32)
    # printed ink filters the paper's colour and grain (as in sheet_texture)
    ink = printed.rgb.astype(np.float32)
    if print_field is not None and print_field.moves:
        maps = displacement_maps(print_field, printed.sheet.extent_mm, ppm, (H, W))
        ink = np.clip(cv2.remap(ink, *maps, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE),
                      0.0, 255.0)
    # in place: the same float32 operations in the same order, without three temporaries
    # of the raster's size (an A2 sheet at 10 px/mm: 300 MB each; 1.4 -> 0.4 s)
    tex = ink
    tex *= np.asarray(PAPER_RGB, np.float32) / 255.0
    tex *= paper[:, :, None]
    np.rint(tex, out=tex)
    tex = np.clip(tex, 0, 255, out=tex).astype(np.uint8)
    return ink_marks(tex, extent_mm=printed.sheet.extent_mm, px_per_mm=ppm,
                     marks_xy_mm=marks_xy_mm, mark_diameters_mm=mark_diameters_mm,
                     rng=rng), tex
