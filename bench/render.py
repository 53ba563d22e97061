"""Bench: photographs per second at 2000 x 1500 on the CPU, and where the time goes.

A full A2 sheet (8 px/mm texture, 4752 x 3360) with 40 dots, tilted views, lens distortion,
vignetting, noise. Every photo gets a texture with one more dot (as a series does): the
textures are built once and each photo patches its new dot in, as ``render_dataset`` does
(only the changed texels are uploaded, then the mipmaps rebuilt), and is PNG-encoded as a
dataset's photo is. Baseline in the same process: cv2.warpPerspective of the same texture to
the same view (no supersampling, no mipmaps, no lens); the render per photo is printed as a
ratio to it, in wall and in CPU seconds (the CPU figure holds on a loaded machine).

    .venv/bin/python bench/render.py [--n 5] [--accuracy]

``--accuracy`` also prints where the rendered dots land against ``cv2.projectPoints``
(640 x 480, dots ~3 px across, a view straight down, two tilted 20-30 deg, and a barrel
lens): the figures the render docstrings used to quote, measured here each time.
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np

from vision_cal.world.camera import camera_matrix, default_views, project
from vision_cal.world.photo import Photographer
from vision_cal.world.sheet import make_sheet, sheet_texture


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=5, help="photos to time (default 5)")
    ap.add_argument("--px-per-mm", type=float, default=8.0)
    ap.add_argument("--accuracy", action="store_true",
                    help="also print rendered dot centres against cv2.projectPoints")
    args = ap.parse_args(argv)
    if args.accuracy:
        accuracy()

    size = (2000, 1500)
    K = camera_matrix(size_px=size, f_px=1800.0)
    dist = np.array([-0.08, 0.01, 0.0, 0.0, 0.0])
    sheet = make_sheet()
    rng = np.random.default_rng(0)
    marks = rng.uniform([-260.0, -180.0], [260.0, 180.0], (40, 2))
    views = default_views(sheet, n=args.n, size_px=size, K=K, tilt_deg=(15, 25), rng=1)

    t0 = time.perf_counter()
    ph = Photographer(size_px=size, K=K)
    t_init = time.perf_counter() - t0

    # as render_dataset does: both textures built once, each photo patches in its new dot
    from vision_cal.world.dataset import Textures, encode_image

    d = np.full(36 + args.n, 1.2)
    t0 = time.perf_counter()
    textures = Textures(sheet, marks[: 36 + args.n], d, px_per_mm=args.px_per_mm, seed=2)
    t_tex = time.perf_counter() - t0
    tex = textures.add_marks(35)
    tex_s, parts, totals, enc_s, cpu_s = [], [], [], [], []
    for i in range(args.n):
        c0 = time.process_time()
        t0 = time.perf_counter()
        tex = textures.add_marks(36 + i)
        tex_s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        rgb = ph.photograph(tex, extent_mm=sheet.extent_mm, T_cam_sheet=views[i], dist=dist,
                            vignetting=0.25, noise_sigma=1.5, rng=i)
        totals.append(time.perf_counter() - t0)
        parts.append(dict(ph.last_timing))
        t0 = time.perf_counter()
        encode_image(rgb, None)
        enc_s.append(time.perf_counter() - t0)
        cpu_s.append(time.process_time() - c0)

    # a series parks the arm over the sheet in one photo in three (render_dataset): its
    # shadows are drawn too; one such photo, timed on its own
    arm = [((-420.0, -230.0), (-90.0, 40.0), 60.0, 140.0),
           ((-90.0, 40.0), (130.0, -40.0), 45.0, 90.0)]
    c0 = time.process_time()
    rgb = ph.photograph(tex, extent_mm=sheet.extent_mm, T_cam_sheet=views[0], dist=dist,
                        arm=arm, vignetting=0.25, noise_sigma=1.5, rng=99)
    _encode_image(rgb, None)
    arm_cpu = time.process_time() - c0

    # baseline: one homography warp of the same texture to the same (ideal) view
    x0, y0, x1, y1 = sheet.extent_mm
    H_tex, W_tex = tex.shape[:2]
    src = np.array([[-0.5, -0.5], [W_tex - 0.5, -0.5], [W_tex - 0.5, H_tex - 0.5],
                    [-0.5, H_tex - 0.5]], np.float32)           # texture pixel corners
    base_s, base_cpu = [], []
    for i in range(args.n):
        dst = project([[x0, y1], [x1, y1], [x1, y0], [x0, y0]], K=K,
                      T_cam_sheet=views[i]).astype(np.float32)
        Hm = cv2.getPerspectiveTransform(src, dst)
        c0 = time.process_time()
        t0 = time.perf_counter()
        cv2.warpPerspective(tex, Hm, size, flags=cv2.INTER_LINEAR)
        base_s.append(time.perf_counter() - t0)
        base_cpu.append(time.process_time() - c0)

    def med(key):
        return float(np.median([p[key] for p in parts]))

    photo = float(np.median(totals))
    texture = float(np.median(tex_s))
    encode = float(np.median(enc_s))
    baseline = float(np.median(base_s))
    per_image = photo + texture + encode
    print(f"image 2000x1500, A2 texture {W_tex}x{H_tex} at {args.px_per_mm:g} px/mm, "
          f"{36 + args.n - 1} dots, {args.n} tilted views, supersample {ph.supersample}")
    print(f"Photographer init (OpenGL context)   {t_init:7.3f} s (once)")
    print(f"both sheet textures (one build)      {t_tex:7.3f} s (once per dataset)")
    print(f"new dot patched into the texture     {texture:7.3f} s")
    print(f"  texture upload + mipmaps           {med('texture_upload_s'):7.3f} s")
    print(f"  pyrender render + read-back        {med('render_s'):7.3f} s")
    print(f"  downsample (+ shadows)             {med('downsample_s'):7.3f} s")
    print(f"  post: lens, vignetting, noise      {med('post_s'):7.3f} s  (first photo builds "
          f"the lens maps: {parts[0]['post_s']:.3f} s)")
    print(f"photograph total                     {photo:7.3f} s")
    print(f"PNG encode                           {encode:7.3f} s")
    share = {"patch": texture, "upload": med("texture_upload_s"), "pyrender": med("render_s"),
             "downsample": med("downsample_s"), "post": med("post_s"), "png": encode}
    tot = sum(share.values())
    print("share: " + ", ".join(f"{k} {100 * v / tot:.0f} %" for k, v in share.items()))
    print(f"baseline cv2.warpPerspective         {baseline:7.4f} s")
    print(f"render per photo {per_image:.3f} s = {1 / per_image:.2f} photos/s = "
          f"{per_image / baseline:.0f}x cv2.warpPerspective of the same texture (pyrender "
          f"alone {med('render_s') / baseline:.0f}x); the textures once: "
          f"{t_tex / baseline:.0f}x")
    cpu, cpu_base = float(np.median(cpu_s)), float(np.median(base_cpu))
    print(f"render per photo in CPU seconds {cpu:.3f} s (all threads) = "
          f"{cpu / max(cpu_base, 1e-9):.0f}x cv2.warpPerspective's {cpu_base:.4f} s")
    series = (2 * cpu + arm_cpu) / 3
    print(f"with the arm parked over the sheet (and its shadows) {arm_cpu:.3f} s CPU; a "
          f"series' photo (one in three parked) {series:.3f} s CPU = "
          f"{series / max(cpu_base, 1e-9):.0f}x")
    ph.close()
    return 0


def _dot_centres(img, bare, guesses_px, *, r=6):
    """Ink-coverage centroids near ``guesses_px`` (photo with and without the dots)."""
    from vision_cal.world.sheet import DOT_RGB

    img = img[..., 0].astype(float)
    bare = bare[..., 0].astype(float)
    alpha = (bare - img) / np.maximum(bare - DOT_RGB[0], 1.0)
    out = []
    for u, v in guesses_px:
        u0, v0 = int(round(u)), int(round(v))
        a = alpha[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
        vv, uu = np.mgrid[v0 - r:v0 + r + 1, u0 - r:u0 + r + 1]
        out.append([np.sum(a * uu) / a.sum(), np.sum(a * vv) / a.sum()])
    return np.array(out)


def accuracy() -> None:
    """Rendered dot centres minus cv2.projectPoints (px), as tests/world/test_photo.py
    checks them, printed as figures."""
    size = (640, 480)
    K = camera_matrix(size_px=size, f_px=800.0)
    sheet = make_sheet(size_mm=(200.0, 150.0), bottom_left_mm=(-100.0, -60.0), marker_mm=20.0,
                       grid=(3, 2), margin_mm=10.0)
    xy = np.array([[x, y] for x in np.arange(-80.0, 81.0, 12.3)
                   for y in np.arange(-30.0, 71.0, 11.7)])
    centres = np.stack([m.corners_mm.mean(axis=0) for m in sheet.markers])
    xy = xy[np.min(np.linalg.norm(xy[:, None] - centres[None], axis=2), axis=1) > 20.0]
    views = (default_views(sheet, n=1, size_px=size, K=K, tilt_deg=(0, 0), rng=1)
             + default_views(sheet, n=2, size_px=size, K=K, tilt_deg=(20, 30), rng=2))
    ph = Photographer(size_px=size, K=K)
    print(f"dot centres vs cv2.projectPoints, {size[0]}x{size[1]}, {len(xy)} dots ~3 px across:")
    for paper in ("plain", "grid"):
        kw = (dict(grid=False, paper_grain=False, rng=7) if paper == "plain" else dict(rng=8))
        tex = sheet_texture(sheet, marks_xy_mm=xy, px_per_mm=8.0, **kw)
        bare = sheet_texture(sheet, marks_xy_mm=np.zeros((0, 2)), px_per_mm=8.0, **kw)
        for name, T, dist in (("straight down", views[0], None), ("tilted 1", views[1], None),
                              ("tilted 2", views[2], None),
                              ("tilted 2, k1 -0.1", views[2],
                               np.array([-0.1, 0.0, 0.0, 0.0, 0.0]))):
            img = ph.photograph(tex, extent_mm=sheet.extent_mm, T_cam_sheet=T, dist=dist)
            img0 = ph.photograph(bare, extent_mm=sheet.extent_mm, T_cam_sheet=T, dist=dist)
            uv = project(xy, K=K, dist=dist, T_cam_sheet=T)
            err = _dot_centres(img, img0, uv) - uv
            print(f"  {paper:5s} paper, {name:18s} max {np.abs(err).max():.3f} px, "
                  f"rms {np.sqrt(np.mean(err ** 2)):.3f} px, mean "
                  f"({err[:, 0].mean():+.4f}, {err[:, 1].mean():+.4f}) px")
    ph.close()


if __name__ == "__main__":
    raise SystemExit(main())
