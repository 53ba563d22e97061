"""Bench: photographs per second at 2000 x 1500 on the CPU, and where the time goes.

A full A2 sheet (8 px/mm texture, 4752 x 3360) with 40 dots, tilted views, lens distortion,
vignetting, noise. Every photo gets a texture with one more dot (as a series does), so the
texture is uploaded again each time. Baseline in the same process: cv2.warpPerspective of
the same texture to the same view (no supersampling, no mipmaps, no lens).

    .venv/bin/python bench/render.py [--n 5]
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np

from vision_cal.render.camera import camera_matrix, default_views, project
from vision_cal.render.photo import Photographer
from vision_cal.render.sheet import make_sheet, sheet_texture


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=5, help="photos to time (default 5)")
    ap.add_argument("--px-per-mm", type=float, default=8.0)
    args = ap.parse_args(argv)

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

    tex_s, parts, totals = [], [], []
    for i in range(args.n):
        t0 = time.perf_counter()
        tex = sheet_texture(sheet, marks_xy_mm=marks[: 36 + i], px_per_mm=args.px_per_mm, rng=2)
        tex_s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        ph.photograph(tex, extent_mm=sheet.extent_mm, T_cam_sheet=views[i], dist=dist,
                      vignetting=0.25, noise_sigma=1.5, rng=i)
        totals.append(time.perf_counter() - t0)
        parts.append(dict(ph.last_timing))

    # baseline: one homography warp of the same texture to the same (ideal) view
    x0, y0, x1, y1 = sheet.extent_mm
    H_tex, W_tex = tex.shape[:2]
    src = np.array([[-0.5, -0.5], [W_tex - 0.5, -0.5], [W_tex - 0.5, H_tex - 0.5],
                    [-0.5, H_tex - 0.5]], np.float32)           # texture pixel corners
    base_s = []
    for i in range(args.n):
        dst = project([[x0, y1], [x1, y1], [x1, y0], [x0, y0]], K=K,
                      T_cam_sheet=views[i]).astype(np.float32)
        Hm = cv2.getPerspectiveTransform(src, dst)
        t0 = time.perf_counter()
        cv2.warpPerspective(tex, Hm, size, flags=cv2.INTER_LINEAR)
        base_s.append(time.perf_counter() - t0)

    def med(key):
        return float(np.median([p[key] for p in parts]))

    photo = float(np.median(totals))
    texture = float(np.median(tex_s))
    baseline = float(np.median(base_s))
    per_image = photo + texture
    print(f"image 2000x1500, A2 texture {W_tex}x{H_tex} at {args.px_per_mm:g} px/mm, "
          f"{len(marks[:36 + args.n - 1])} dots, {args.n} tilted views, supersample "
          f"{ph.supersample}")
    print(f"Photographer init (OpenGL context)   {t_init:7.3f} s (once)")
    print(f"sheet_texture                        {texture:7.3f} s")
    print(f"  texture upload + mipmaps           {med('texture_upload_s'):7.3f} s")
    print(f"  pyrender render + read-back        {med('render_s'):7.3f} s")
    print(f"  downsample (+ shadows)             {med('downsample_s'):7.3f} s")
    print(f"  post: lens, vignetting, noise      {med('post_s'):7.3f} s  (first photo builds "
          f"the lens maps: {parts[0]['post_s']:.3f} s)")
    print(f"photograph total                     {photo:7.3f} s  = {1 / photo:.2f} images/s "
          "(texture patched per photo, as render_dataset does)")
    print(f"per image incl. a new texture        {per_image:7.3f} s  = {1 / per_image:.2f} images/s")
    share = {"texture": texture, "upload": med("texture_upload_s"), "pyrender": med("render_s"),
             "downsample": med("downsample_s"), "post": med("post_s")}
    tot = sum(share.values())
    print("share: " + ", ".join(f"{k} {100 * v / tot:.0f} %" for k, v in share.items()))
    print(f"baseline cv2.warpPerspective         {baseline:7.4f} s  -> photograph is "
          f"{photo / baseline:.0f}x the baseline, pyrender alone {med('render_s') / baseline:.0f}x")
    ph.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
