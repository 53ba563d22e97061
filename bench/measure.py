"""Benchmark of the measuring stage (vision_cal.measure).

Prints, for photos of the project's renderer (or of a fast warp of the sheet texture when
``--warp`` is given or pyrender is unavailable):

- time per photo of ``detect_image`` (decode + markers + edge points + dot candidates)
  against plain OpenCV on the same photos in the same run (``cv2.imdecode`` +
  ``ArucoDetector.detectMarkers`` with default parameters), as a ratio (goal <= 1.5);
- photos per second of ``measure_folder`` on a 40-photo folder with jobs=1 and jobs=2
  (cold cache), and of a re-run with a warm cache;
- the mark error against truth.json (RMS mm) and normalised errors (RMS, ideally ~1).

``--reference [SCENE ...] [--seed N]``: instead, one table of the mark error against truth
for flat and bumped scenes (renders/flat_tilted, bumped_tilted, bumped_moving by default),
measured through the marker mapping only (global: sheet.grid left out) and against the
printed grid (local), with the time per photo of each and whether sheet_height is claimed.

``--whole [--folder DIR]``: instead, the whole calibration (``vision-cal DIR --jobs 1``, no
cache: measure, fit, diagnosis, calibration.json) of the demo's 38 photos
(renders/default.yaml, rendered once into DIR, default /tmp/vision-cal-bench-whole) against
plain OpenCV decode + detectMarkers of the same photos, timed before and after it in the
same process: the ratio (goal <= 1.5), where the rest goes (measuring, fit + diagnosis),
and the fit + diagnosis per mark, also as a ratio to plain decode + detect per photo, and
the dots refined per mark (issue 33: linear in photos and marks).

``--printed [--seeds N]``: instead, marks on every kind of printed content of the sheet's
own raster (A4, 254 dpi; the photos of ``tests/measure/test_printed_ink.py`` at views and
noise of seeds 100..100+N, not the tests' seeds): per kind, the largest error of the marks
not flagged, how many were flagged unreliable, and the same with the sheet's ``printed``
block removed (a sheet nobody describes). ``--raster pdfium|poppler|toner``: the photos show
the PDF as another rasteriser draws it, or the raster with its ink grown 0.03 mm, while the
reference stays the sheet's own raster; ``--described-only``: the first table only.

Usage::

    .venv/bin/python bench/measure.py [--folder DIR] [--photos 40] [--warp]

The folder is rendered once into ``DIR`` (default /tmp/vision-cal-bench-measure) and
reused by later runs.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def render_folder(folder: Path, n_photos: int) -> None:
    from vision_cal.estimate.paper import pilot_params
    from vision_cal.world.dataset import render_dataset
    from vision_cal.world.scene import scene_from_dict

    n_val = max(n_photos // 6, 1)
    scene = scene_from_dict({"seed": 11, "plan": {"n_calibration": n_photos - n_val,
                                                   "n_validation": n_val},
                             "camera": {"n_views": 4, "moving": True}})
    render_dataset(scene, folder, progress=True, pilot=pilot_params)


def warp_folder(folder: Path, n_photos: int) -> None:
    """Fallback: the test helper's warp of the sheet texture (no pyrender)."""
    from tests.measure import synth_measure as sm
    from vision_cal.world.camera import camera_matrix, look_at
    from vision_cal.world.sheet import make_sheet

    folder.mkdir(parents=True, exist_ok=True)
    sheet = make_sheet()
    rng = np.random.default_rng(0)
    targets = []
    cen = np.array([np.asarray(m.corners_mm).mean(axis=0) for m in sheet.markers])
    while len(targets) < n_photos:
        p = rng.uniform([-270, -190], [270, 190])
        if np.all(np.any(np.abs(cen - p) > 16, axis=1)):
            targets.append(p)
    targets = np.array(targets)
    q = sm.plan_for(targets)
    size = (2400, 1800)
    K = camera_matrix(size_px=size, f_px=2600.0)
    T = look_at(eye_mm=(20.0, -60.0, 700.0), target_mm=(0.0, 0.0))
    ids = [f"c{i:02d}" for i in range(n_photos)]
    images = []
    for k in range(n_photos):
        tex = sm.texture(sheet, targets[:k + 1], rng=1)
        sm.write_png(folder / f"img_{k:03d}.png",
                     sm.photo(sheet, tex, K=K, T=T, size=size, rng=k))
        images.append((f"img_{k:03d}.png", ids[:k + 1]))
    d = sm.session_json(sheet, marks=list(zip(ids, q)), images=images, robot=sm.NOMINAL)
    d["camera"] = {"size_px": list(size), "K": K.tolist(), "dist": [0.0] * 5}
    sm.write_session(folder, d)
    (folder / "truth.json").write_text(json.dumps(
        {"marks": {i: t.tolist() for i, t in zip(ids, targets)}}))


def plain_opencv(path: Path, dictionary: str) -> int:
    img = cv2.imdecode(np.frombuffer(path.read_bytes(), np.uint8), cv2.IMREAD_COLOR)
    gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(
        getattr(cv2.aruco, dictionary)), cv2.aruco.DetectorParameters())
    _, ids, _ = det.detectMarkers(gray)
    return 0 if ids is None else len(ids)


def _without_grid(folder: Path, tmp: Path) -> Path:
    """The same dataset with ``sheet.grid`` left out (photos copied): the marker mapping only."""
    out = tmp / (folder.name + "-nogrid")
    out.mkdir(parents=True, exist_ok=True)
    for p in folder.iterdir():
        if p.suffix.lower() in (".png", ".jpg", ".jpeg") and not (out / p.name).exists():
            shutil.copyfile(p, out / p.name)   # a copy: photos behind links are refused
    d = json.loads((folder / "session.json").read_text())
    d["sheet"].pop("grid", None)
    (out / "session.json").write_text(json.dumps(d))
    return out


def reference_table(scenes: list[str], root: Path, seed: int | None) -> None:
    """Mark error against truth.json, marker mapping (global) versus the printed grid
    (local), flat and bumped scenes, in one table; time per photo of both."""
    from vision_cal.estimate.paper import pilot_params
    from vision_cal.dataset.session import load_session
    from vision_cal.actions.measure_folder import measure_folder
    from vision_cal.world.dataset import render_dataset
    from vision_cal.world.scene import load_scene

    rows = []
    for name in scenes:
        sc = load_scene(ROOT / "renders" / f"{name}.yaml").with_overrides(seed=seed)
        folder = root / f"{name}-seed{sc.seed}"
        if not (folder / "session.json").exists():
            t = time.perf_counter()
            render_dataset(sc, folder, progress=True, pilot=pilot_params)
            print(f"rendered {folder} in {time.perf_counter() - t:.0f} s", file=sys.stderr)
        truth = json.loads((folder / "truth.json").read_text())
        tm = truth["marks"]
        tmp = Path(tempfile.mkdtemp(prefix="bench-ref-"))
        try:
            res = {}
            for ref, f in (("global", _without_grid(folder, tmp)), ("local", folder)):
                s = load_session(f)
                t = time.perf_counter()
                meas = measure_folder(s, out_dir=tmp / f"out-{ref}", jobs=1)
                dt = (time.perf_counter() - t) / max(len(s.images), 1)
                keys = [k for k in meas.marks if k in tm]
                e = np.array([meas.marks[k].xy_mm - np.asarray(tm[k]) for k in keys])
                sd = np.array([meas.marks[k].std_mm for k in keys])
                hm = meas.height_map
                res[ref] = (float(np.sqrt(np.mean(np.sum(e**2, axis=1)))),
                            float(np.sqrt(np.mean((e / sd) ** 2))), dt,
                            bool(hm is not None and hm.claimed),
                            sorted({m.reference for m in meas.marks.values()}))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        zmax = truth.get("sheet_height", {}).get("max_abs_mm", 0.0)
        rows.append((folder.name, zmax, res))
    print(f"{'scene':28s} {'max z':>6s} | {'global um':>9s} {'z-rms':>5s} {'s/photo':>7s} "
          f"{'height?':>7s} | {'local um':>8s} {'z-rms':>5s} {'s/photo':>7s} {'height?':>7s} "
          f"reference  time ratio")
    for name, zmax, r in rows:
        g, loc = r["global"], r["local"]
        print(f"{name:28s} {zmax:6.2f} | {1000 * g[0]:9.1f} {g[1]:5.2f} {g[2]:7.2f} "
              f"{str(g[3]):>7s} | {1000 * loc[0]:8.1f} {loc[1]:5.2f} {loc[2]:7.2f} "
              f"{str(loc[3]):>7s} {'+'.join(loc[4]):10s} {loc[2] / g[2]:.2f}")


def plain_all(files: list[Path], dictionary: str) -> tuple[float, float]:
    """(wall, CPU) seconds of plain OpenCV decode + detectMarkers over ``files``."""
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(
        getattr(cv2.aruco, dictionary)), cv2.aruco.DetectorParameters())
    t, c = time.perf_counter(), time.process_time()
    for p in files:
        img = cv2.imdecode(np.frombuffer(p.read_bytes(), np.uint8), cv2.IMREAD_COLOR)
        det.detectMarkers(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))
    return time.perf_counter() - t, time.process_time() - c


def whole_run(folder: Path) -> dict:
    """The whole calibration against plain decode + detect (see the module docstring),
    printed; returns the figures (``bench/speed.py`` writes them to docs/speed.json)."""
    from vision_cal.actions import pipeline
    from vision_cal.estimate.paper import pilot_params
    from vision_cal.dataset.session import load_session
    from vision_cal.world.dataset import render_dataset
    from vision_cal.world.scene import load_scene

    if not (folder / "session.json").exists():
        t = time.perf_counter()
        render_dataset(load_scene(ROOT / "renders" / "default.yaml"), folder, progress=True,
                       pilot=pilot_params, jobs=None)
        print(f"rendered {folder} in {time.perf_counter() - t:.0f} s")
    s = load_session(folder)
    files = [folder / im.file for im in s.images]
    spent = {"measure": 0.0, "fit + diagnosis": 0.0}

    def timed(name, f):
        def run(*a, **k):
            c = time.process_time()
            try:
                return f(*a, **k)
            finally:
                spent[name] += time.process_time() - c
        return run

    plain_all(files[:1], s.sheet.aruco_dictionary)          # warm-up: imports, first call
    before = plain_all(files, s.sheet.aruco_dictionary)
    out = Path(tempfile.mkdtemp(prefix="bench-whole-"))
    orig = pipeline.measure_marks, pipeline.fit_marks
    pipeline.measure_marks = timed("measure", orig[0])
    pipeline.fit_marks = timed("fit + diagnosis", orig[1])
    try:
        t, c = time.perf_counter(), time.process_time()
        run = pipeline.calibrate_dataset(folder, out_dir=out, jobs=1)
        whole, whole_cpu = time.perf_counter() - t, time.process_time() - c
    finally:
        pipeline.measure_marks, pipeline.fit_marks = orig
        shutil.rmtree(out, ignore_errors=True)
    after = plain_all(files, s.sheet.aruco_dictionary)
    plain, plain_cpu = 0.5 * (before[0] + after[0]), 0.5 * (before[1] + after[1])
    n_marks = len(run.document.get("marks", {}))
    rest = whole_cpu - spent["measure"] - spent["fit + diagnosis"]
    print(f"{len(files)} photos, {n_marks} marks; plain OpenCV decode + detectMarkers "
          f"{before[0]:.1f} / {after[0]:.1f} s wall before / after the run, "
          f"{before[1]:.1f} / {after[1]:.1f} s CPU")
    print(f"whole run (--jobs 1, no cache) {whole:.1f} s wall = {whole / plain:.2f}x plain; "
          f"{whole_cpu:.1f} s CPU = {whole_cpu / plain_cpu:.2f}x plain CPU (goal <= 1.5; "
          "CPU time is the figure a shared machine does not move)")
    print(f"  CPU: measure {spent['measure']:.1f} s = {spent['measure'] / plain_cpu:.2f}x "
          f"plain, fit + diagnosis {spent['fit + diagnosis']:.2f} s = "
          f"{spent['fit + diagnosis'] / plain_cpu:.3f}x, the rest {rest:.2f} s")
    views = sum(int(m.get("n_photos", 0)) for m in run.document.get("marks", {}).values())
    print(f"dots refined {views} over {len(files)} photos and {n_marks} marks = "
          f"{views / max(n_marks, 1):.1f} per mark (config dots.views_per_dot: linear in "
          "marks, however many photos show each)")
    per_mark = spent["fit + diagnosis"] / max(n_marks, 1)
    print(f"fit + diagnosis per mark {1e3 * per_mark:.1f} ms CPU = "
          f"{per_mark / (plain_cpu / len(files)):.3f}x plain decode + detect per photo")
    return {"photos": len(files), "marks": n_marks, "plain_cpu_s": plain_cpu,
            "whole_cpu_s": whole_cpu, "ratio_cpu": whole_cpu / plain_cpu,
            "ratio_wall": whole / plain, "measure_ratio_cpu": spent["measure"] / plain_cpu,
            "fit_per_mark_ratio": per_mark / (plain_cpu / len(files)),
            "dots_per_mark": views / max(n_marks, 1)}


def _rerasterised(a4: Path, raster: str) -> Path:
    """A copy of the sheet folder ``a4`` whose sheet.png is the PDF as ``raster`` (pdfium or
    poppler's pdftoppm) draws it, or (``toner``) its own raster with the ink grown about
    0.03 mm (0.3 of a pixel's erosion): the print the photos show, not the reference's."""
    from PIL import Image
    from scipy.ndimage import grey_erosion

    from tests.sheet.raster import rasterise_pdf, rasterise_pdftoppm

    d = a4.parent / f"a4_{raster}"
    d.mkdir()
    for f in ("sheet.json", "sheet.pdf"):
        shutil.copy(a4 / f, d / f)
    own = np.asarray(Image.open(a4 / "sheet.png"))
    if raster == "toner":
        grown = grey_erosion(own, size=(3, 3, 1)).astype(float)
        Image.fromarray(np.round(0.7 * own + 0.3 * grown).astype(np.uint8)).save(
            d / "sheet.png", dpi=(254, 254))
        return d
    rgb, _ = (rasterise_pdftoppm if raster == "poppler" else rasterise_pdf)(d / "sheet.pdf",
                                                                             10.0)
    rgb = rgb[:own.shape[0], :own.shape[1]]
    Image.fromarray(rgb).save(d / "sheet.png", dpi=(254, 254))
    return d


def printed_table(n_seeds: int, first_seed: int = 100, raster: str = "own",
                  describes=None) -> None:
    from tests.measure.test_printed_ink import ON_PRINT, PLAIN, _measure
    from vision_cal.sheet import make_layout, write_sheet

    root = Path(tempfile.mkdtemp(prefix="vision-cal-bench-printed-"))
    try:
        write_sheet(make_layout(size="A4"), root / "a4", png_dpi=254)
        if raster != "own":
            print(("photos of the sheet's own raster with its ink grown 0.03 mm" if raster == "toner"
                   else f"photos of the PDF as {raster} draws it")
                  + " (the reference: the sheet's own raster)")
        sheet_dir = root / "a4" if raster == "own" else _rerasterised(root / "a4", raster)
        for describe in ((True, False) if describes is None else describes):
            per: dict = {k: [] for k in (*ON_PRINT, *PLAIN)}
            t = time.perf_counter()
            for s in range(first_seed, first_seed + n_seeds):
                res = _measure(sheet_dir, root / f"d{s}{int(describe)}", s, describe=describe)
                for k, v in res.items():
                    per[k].append(v)
            dt = (time.perf_counter() - t) / n_seeds
            print(f"sheet.printed {'described' if describe else 'removed'}: {n_seeds} photos (seeds {first_seed}-{first_seed + n_seeds - 1}) "
                  f"2000x1500 (0.15 mm/px), {dt:.2f} s per photo")
            print(f"  {'mark on':14s} {'max err um (not flagged)':>24s} {'flagged':>8s}")
            for k, vals in per.items():
                ok = [e for e, why, _ in vals if not why]
                n_flag = sum(bool(why) for _, why, _ in vals)
                worst = f"{1000 * max(ok):.1f}" if ok else "-"
                print(f"  {k:14s} {worst:>24s} {n_flag:>4d}/{len(vals)}")
    finally:
        shutil.rmtree(root, ignore_errors=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--folder", default="/tmp/vision-cal-bench-measure")
    ap.add_argument("--photos", type=int, default=40)
    ap.add_argument("--warp", action="store_true", help="use the fast texture warp")
    ap.add_argument("--repeat", type=int, default=8, help="photos timed per-photo")
    ap.add_argument("--reference", nargs="*", metavar="SCENE",
                    help="only the global-versus-local table for these renders/ scenes "
                         "(default: flat_tilted bumped_tilted bumped_moving)")
    ap.add_argument("--seed", type=int, default=None, help="scene seed for --reference")
    ap.add_argument("--printed", action="store_true",
                    help="only the marks-on-printed-ink table (see the module docstring)")
    ap.add_argument("--seeds", type=int, default=10, help="photos for --printed")
    ap.add_argument("--first-seed", type=int, default=100, help="first photo seed for --printed")
    ap.add_argument("--raster", choices=("own", "pdfium", "poppler", "toner"), default="own",
                    help="--printed: the photos show the sheet's own raster, its PDF as "
                         "pdfium or poppler (pdftoppm) draws it, or its raster with the ink "
                         "grown 0.03 mm (toner)")
    ap.add_argument("--described-only", action="store_true",
                    help="--printed: only the sheet with its printed block")
    ap.add_argument("--whole", action="store_true",
                    help="only the whole calibration against decode + detect (docstring)")
    a = ap.parse_args()
    if a.whole:
        whole_run(Path(a.folder if a.folder != "/tmp/vision-cal-bench-measure"
                       else "/tmp/vision-cal-bench-whole"))
        return 0
    if a.printed:
        printed_table(a.seeds, a.first_seed, a.raster, (True,) if a.described_only else None)
        return 0
    if a.reference is not None:
        reference_table(a.reference or ["flat_tilted", "bumped_tilted", "bumped_moving"],
                        Path("/tmp/vision-cal-bench-reference"), a.seed)
        return 0

    from vision_cal.dataset.session import load_session
    from vision_cal.measure.detect import detect_image
    from vision_cal.actions.measure_folder import measure_folder

    folder = Path(a.folder)
    if not (folder / "session.json").exists():
        t = time.perf_counter()
        if a.warp:
            warp_folder(folder, a.photos)
        else:
            try:
                render_folder(folder, a.photos)
            except Exception as e:  # pyrender/EGL missing: fall back, say so
                print(f"renderer unavailable ({e}); using the texture warp", file=sys.stderr)
                shutil.rmtree(folder, ignore_errors=True)
                warp_folder(folder, a.photos)
        print(f"made {folder} in {time.perf_counter() - t:.1f} s")
    s = load_session(folder)
    files = [folder / im.file for im in s.images]
    h, w = cv2.imread(str(files[0])).shape[:2]
    print(f"{len(files)} photos of {w}x{h} px, {len(s.marks)} marks")

    # per photo, interleaved so that both see the same machine state
    sample = files[:: max(len(files) // a.repeat, 1)][: a.repeat]
    plain_opencv(sample[0], s.sheet.aruco_dictionary)
    detect_image(sample[0], s)
    t_cv, t_me = [], []
    for p in sample:
        t = time.perf_counter()
        plain_opencv(p, s.sheet.aruco_dictionary)
        t_cv.append(time.perf_counter() - t)
        t = time.perf_counter()
        detect_image(p, s)
        t_me.append(time.perf_counter() - t)
    cv_ms, me_ms = 1e3 * np.median(t_cv), 1e3 * np.median(t_me)
    print(f"per photo: plain OpenCV (decode + detectMarkers) {cv_ms:.0f} ms, "
          f"vision_cal detect_image {me_ms:.0f} ms, ratio {me_ms / cv_ms:.2f} (goal <= 1.5)")

    truth = None
    if (folder / "truth.json").exists():
        truth = json.loads((folder / "truth.json").read_text()).get("marks")
    for jobs in (1, 2):
        out = Path(tempfile.mkdtemp(prefix="bench-measure-"))
        try:
            t = time.perf_counter()
            meas = measure_folder(s, out_dir=out, jobs=jobs)
            dt = time.perf_counter() - t
            t = time.perf_counter()
            measure_folder(s, out_dir=out, jobs=jobs)
            dt_warm = time.perf_counter() - t
        finally:
            shutil.rmtree(out, ignore_errors=True)
        n = len(files)
        print(f"measure_folder jobs={jobs}: {n / dt:.2f} photos/s ({dt:.1f} s cold), "
              f"warm cache {n / dt_warm:.1f} photos/s ({dt_warm:.1f} s)")
    ok = sum(im.status == "ok" for im in meas.images)
    print(f"photos ok {ok}/{len(meas.images)}; marks measured {len(meas.marks)}/{len(s.marks)}"
          f"; lens: {'declared' if s.camera else (meas.lens and meas.lens.kept)}")
    if truth:
        keys = [k for k in meas.marks if k in truth]
        e = np.array([meas.marks[k].xy_mm - np.asarray(truth[k]) for k in keys])
        sd = np.array([meas.marks[k].std_mm for k in keys])
        rms = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
        z = np.sqrt(np.mean((e / sd) ** 2, axis=0))
        print(f"mark error vs truth: RMS {rms * 1000:.1f} um (goal <= 15), max "
              f"{np.abs(e).max() * 1000:.1f} um; normalised error RMS x {z[0]:.2f} y {z[1]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
