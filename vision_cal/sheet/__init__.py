"""The printable calibration sheet: layout (pure geometry, the one owner of what is
printed) and its writers (PDF, SVG, PNG, sheet.json)."""

from __future__ import annotations

from pathlib import Path

from vision_cal.dataset.io import atomic_write_bytes, atomic_write_json, atomic_write_text
from vision_cal.errors import VisionCalError
from vision_cal.sheet.layout import ISO_SIZES_MM, SheetLayout, make_layout, page_size_mm
from vision_cal.sheet.pdf import pdf_bytes
from vision_cal.sheet.png import png_bytes
from vision_cal.sheet.svg import svg_text

__all__ = ["ISO_SIZES_MM", "SheetLayout", "make_layout", "page_size_mm", "write_sheet"]


def write_sheet(layout: SheetLayout, out_dir, *, png_dpi: float | None = None) -> dict:
    """Write ``sheet.pdf``, ``sheet.svg``, ``sheet.json`` (and ``sheet.png`` at ``png_dpi``)
    into ``out_dir``, each atomically; every file is produced in memory before any is
    written. Returns {kind: path}."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise VisionCalError("exists and is not a folder", file=str(out), field="--out")
    doc = layout.to_sheet_json()
    pdf = pdf_bytes(layout)
    svg = svg_text(layout)
    png = None
    if png_dpi is not None:
        png = png_bytes(layout, png_dpi)
        doc["printed"]["png_dpi"] = float(png_dpi)
    paths = {"pdf": atomic_write_bytes(out / "sheet.pdf", pdf),
             "svg": atomic_write_text(out / "sheet.svg", svg)}
    if png is not None:
        paths["png"] = atomic_write_bytes(out / "sheet.png", png)
    paths["json"] = atomic_write_json(out / "sheet.json", doc)
    return paths
