"""Benchmark of the printed sheet (``vision-cal sheet``): is the print where sheet.json says?

For each page, writes the sheet, rasterises sheet.pdf with two rasterisers that are not
the writer (pdfium via pypdfium2, and poppler's ``pdftoppm`` when installed) and reads
back every ArUco corner (``cv2.aruco.ArucoDetector`` + ``cornerSubPix``) and the two
100 mm scale bars (exact ink area along their middle rows). Prints the corner error
against sheet.json (max and RMS, mm) and each bar's length error (mm); the issue's bound
is 0.02 mm. Also the time ``vision-cal sheet`` takes per page.

Usage::

    .venv/bin/python bench/sheet.py [--ppm 20] [--pages A4 A3 custom]
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.sheet.raster import (detect_corners_mm, find_bars_mm,  # noqa: E402
                                rasterise_pdf, rasterise_pdftoppm)
from vision_cal.commands.main import main  # noqa: E402

PAGES = {"A4": ["--size", "A4", "--portrait"], "A3": ["--size", "A3"],
         "custom": ["--custom", "300", "250", "--dictionary", "DICT_4X4_50",
                    "--marker-mm", "18"]}


def figures(doc, rgb, ppm) -> str:
    x0, y0 = doc["bottom_left_mm"]
    ext = (x0, y0, x0 + doc["size_mm"][0], y0 + doc["size_mm"][1])
    found = detect_corners_mm(rgb, doc["aruco_dictionary"], ext, ppm)
    want = {m["id"]: np.array(m["corners_mm"]) for m in doc["markers"]}
    err = np.array([np.hypot(*(found[i] - want[i]).T) for i in want if i in found])
    bars = find_bars_mm(rgb, ext, ppm)
    bx = bars["x"][1][0] - bars["x"][0][0] - 100.0 if "x" in bars else float("nan")
    by = bars["y"][1][1] - bars["y"][0][1] - 100.0 if "y" in bars else float("nan")
    return (f"{len(found)}/{len(want)} markers, corner error max {err.max():.4f} RMS "
            f"{np.sqrt(np.mean(err ** 2)):.4f} mm; bars {bx:+.4f} / {by:+.4f} mm")


def run(args) -> None:
    tools = [("pdfium", rasterise_pdf)]
    if shutil.which("pdftoppm"):
        tools.append(("pdftoppm", rasterise_pdftoppm))
    else:
        print("pdftoppm not installed: poppler rows skipped")
    for page in args.pages:
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            assert main(["sheet", *PAGES[page], "--out", d, "-q"]) == 0
            dt = time.perf_counter() - t0
            doc = json.loads(Path(d, "sheet.json").read_text())
            print(f"{page}: vision-cal sheet {dt:.2f} s")
            for name, fn in tools:
                rgb, ppm = fn(Path(d, "sheet.pdf"), args.ppm)
                print(f"  {name:9s} at {args.ppm:g} px/mm: {figures(doc, rgb, ppm)}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ppm", type=float, default=20.0, help="raster pixels per mm (20 = 508 dpi)")
    ap.add_argument("--pages", nargs="+", default=["A4", "A3", "custom"], choices=list(PAGES))
    run(ap.parse_args())
