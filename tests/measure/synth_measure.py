"""Test helper: synthetic photographs of a sheet with known truth (fast, no pyrender).

A texture from ``vision_cal.world.sheet.sheet_texture`` is looked up, through the lens
(accurate inverse map via ``cv2.undistortPoints``) and a pinhole camera at ``T_cam_sheet``,
for every photo pixel in one ``cv2.remap``; then blur (in the texture) and noise.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from vision_cal.dataset.session import load_session
from vision_cal.measure.detect import detect_image
from vision_cal.measure.finish import finish_image
from vision_cal.world.camera import camera_matrix, look_at
from vision_cal.world.sheet import make_sheet, sheet_texture, sheet_to_texture_pixel

SIZE = (1000, 750)


def small_sheet(dictionary="DICT_5X5_100"):
    # 240 x 180 mm, 4 x 3 markers of 20 mm; seen at ~0.25 mm per pixel in 1000 x 750
    return make_sheet(size_mm=(240.0, 180.0), bottom_left_mm=(-120.0, -90.0),
                      dictionary=dictionary, marker_mm=20.0, grid=(4, 3), margin_mm=8.0)


def view(*, tilt_deg=0.0, azimuth_deg=30.0, dist_mm=None, f_px=1400.0, target=(0.0, 0.0),
         size=SIZE, roll_up=(0.0, 1.0, 0.0)):
    K = camera_matrix(size_px=size, f_px=f_px)
    if dist_mm is None:
        dist_mm = f_px * 0.25  # ~0.25 mm per pixel
    t = np.radians(tilt_deg)
    a = np.radians(azimuth_deg)
    eye = np.array([target[0] + dist_mm * np.sin(t) * np.cos(a),
                    target[1] + dist_mm * np.sin(t) * np.sin(a), dist_mm * np.cos(t)])
    T = look_at(eye_mm=eye, target_mm=target, up_hint=roll_up)
    return K, T


def texture(sheet, marks_xy, *, ppm=8.0, rng=0, diameters=1.2, **kw):
    return sheet_texture(sheet, marks_xy_mm=np.asarray(marks_xy, float).reshape(-1, 2),
                         mark_diameters_mm=diameters, px_per_mm=ppm, rng=rng, **kw)


def photo(sheet, tex, *, K, T, dist=None, size=SIZE, ppm=8.0, noise=2.0, blur_mm=0.12,
          rng=0, shade=0.0):
    """RGB uint8 (h, w, 3) photo of ``tex`` (texture of ``sheet`` at ``ppm``)."""
    rng = np.random.default_rng(rng)
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    uv = np.stack([u.ravel(), v.ravel()], axis=-1)
    if dist is not None and np.any(dist):
        uv = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, np.asarray(dist, float), P=K,
                                 criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
                                           100, 1e-12)).reshape(-1, 2)
    H = K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]])
    G = np.linalg.inv(H)
    q = uv @ G[:, :2].T + G[:, 2]
    xy = q[:, :2] / q[:, 2:3]
    tp = sheet_to_texture_pixel(xy, extent_mm=sheet.extent_mm, px_per_mm=ppm)
    mx = tp[:, 0].reshape(h, w).astype(np.float32)
    my = tp[:, 1].reshape(h, w).astype(np.float32)
    src = cv2.GaussianBlur(tex.astype(np.float32), (0, 0), blur_mm * ppm) if blur_mm else \
        tex.astype(np.float32)
    img = cv2.remap(src, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=(60, 60, 60))
    if shade:
        g = (1.0 - shade * (u / w)).astype(np.float32)
        img *= g[:, :, None]
    img += rng.normal(0.0, noise, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def write_png(path, rgb):
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    assert ok
    Path(path).write_bytes(buf.tobytes())


def session_json(sheet, *, marks, images, robot=None, camera=None, dia=1.2):
    """A session.json dict. ``marks``: list of (id, (q1, q2)); ``images``: (file, [ids])."""
    robot = robot or {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
                      "base_mm": [-250.0, 210.0]}
    d = {"format": "vision-cal/1", "sheet": sheet.to_json(), "robot": robot,
         "pen": {"mark_diameter_mm": dia},
         "marks": [{"id": i, "joints_deg": [float(q[0]), float(q[1])]} for i, q in marks],
         "images": [{"file": f, "marks": list(ids)} for f, ids in images]}
    if camera is not None:
        K, dist = camera
        d["camera"] = {"size_px": list(SIZE), "K": np.asarray(K).tolist(),
                       "dist": list(map(float, dist))}
    return d


def write_session(folder, d):
    Path(folder, "session.json").write_text(json.dumps(d, indent=1))


# --------------------------------------------------------------------------- datasets

from vision_cal.model.kinematics import ScaraParams, inverse  # noqa: E402

TRUTH = ScaraParams(350.0, 260.0, 3.0, -4.0, -250.0, 210.0)
#: the user's nominal model: 8 / -7 deg off in the zeros and ~92 mm off in the base
NOMINAL = {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [3.0 + 8.0, -4.0 - 7.0],
           "base_mm": [-250.0 + 65.0, 210.0 - 65.0]}


def free_targets(sheet, n, *, rng=0, min_sep=8.0, box=(100.0, 75.0)):
    """``n`` sheet points away from markers and their quiet zones, ``min_sep`` apart."""
    rng = np.random.default_rng(rng)
    cen = np.array([np.asarray(m.corners_mm).mean(axis=0) for m in sheet.markers])
    out = []
    while len(out) < n:
        p = rng.uniform([-box[0], -box[1]], box)
        if np.any(np.all(np.abs(cen - p) < 19.0, axis=1)):
            continue
        if out and np.min(np.hypot(*(np.array(out) - p).T)) < min_sep:
            continue
        out.append(p)
    return np.array(out)


def plan_for(targets, truth=TRUTH):
    """Commanded joints (N, 2) that put the true robot's pen on ``targets``."""
    return inverse(truth, targets, elbow=-1)


# --------------------------------------------------------------------------- phone series

def jpeg_bytes(rgb, orientation: int = 1, quality: int = 90) -> bytes:
    """JPEG of ``rgb`` tagged with EXIF ``orientation``."""
    import io

    from PIL import Image

    im = Image.fromarray(rgb)
    ex = im.getexif()
    ex[0x0112] = orientation
    b = io.BytesIO()
    im.save(b, "JPEG", quality=quality, exif=ex.tobytes())
    return b.getvalue()


def phone_series(folder, seed: int, n_photos: int = 12, n_turned: int = 3, n_marks: int = 16):
    """A hand-held phone series of :func:`small_sheet` (issue 18 section 4): ``n_photos``
    JPEGs 1008x756 from random views (tilt 3-22 deg, any azimuth and roll), the focal length
    breathing 1.5 % (std) from photo to photo, a mild lens nobody declares (k1 -0.04..-0.08),
    ``n_turned`` files stored turned a quarter and tagged EXIF orientation 6. Writes
    session.json; returns the mark ids and their true sheet positions (n_marks, 2)."""
    rng = np.random.default_rng(seed)
    size = (1008, 756)
    sheet = small_sheet()
    targets = free_targets(sheet, n_marks, rng=seed, box=(85.0, 62.0))
    tex = texture(sheet, targets, rng=seed)
    ids = [f"c{i:02d}" for i in range(n_marks)]
    k1 = -rng.uniform(0.04, 0.08)
    dist = [k1, 0.3 * abs(k1), 0.0, 0.0, 0.0]
    f0 = 820.0
    turned = set(rng.choice(n_photos, n_turned, replace=False).tolist())
    folder = Path(folder)
    folder.mkdir(parents=True)
    images = []
    for n in range(n_photos):
        f = f0 * (1.0 + 0.015 * rng.standard_normal())        # focus breathing
        roll = rng.uniform(0, 2 * np.pi)
        K, T = view(tilt_deg=rng.uniform(3, 22), azimuth_deg=rng.uniform(0, 360), f_px=f,
                    dist_mm=f * rng.uniform(0.27, 0.31), size=size,
                    target=rng.uniform([-8, -6], [8, 6]),
                    roll_up=(np.cos(roll), np.sin(roll), 0.0))
        img = photo(sheet, tex, K=K, T=T, dist=dist, size=size, ppm=8.0, noise=2.5,
                    blur_mm=0.15, rng=1000 * seed + n)
        name = f"IMG_{n:04d}.jpg"
        if n in turned:    # held upright: the sensor's pixels stored turned, tagged 6
            (folder / name).write_bytes(jpeg_bytes(np.ascontiguousarray(np.rot90(img, 1)), 6))
        else:
            (folder / name).write_bytes(jpeg_bytes(img, 1))
        images.append((name, ids))
    write_session(folder, session_json(sheet, marks=list(zip(ids, plan_for(targets))),
                                       images=images, robot=NOMINAL))
    return ids, targets


#: four views around the sheet, tilted 8-18 deg (the measure tests' small series)
SERIES_VIEWS = [dict(tilt_deg=12.0, azimuth_deg=20.0), dict(tilt_deg=18.0, azimuth_deg=150.0),
                dict(tilt_deg=8.0, azimuth_deg=-100.0), dict(tilt_deg=15.0, azimuth_deg=70.0)]


def shifted_series(src, *, moved_photo: int, shift_mm, n_marks: int = 10):
    """Write into ``src`` a session of the four :data:`SERIES_VIEWS` photos of the same
    ``n_marks`` marks, photo ``moved_photo`` seeing every dot moved together by ``shift_mm``
    (what a bad mapping of it would give). Returns (ids, true targets (n, 2) mm)."""
    sheet = small_sheet()
    targets = free_targets(sheet, n_marks, rng=88, box=(85.0, 62.0))
    ids = [f"c{i:02d}" for i in range(len(targets))]
    src.mkdir()
    images = []
    for n, v in enumerate(SERIES_VIEWS):
        K, T = view(**v)
        xy = targets + (np.asarray(shift_mm) if n == moved_photo else 0.0)
        write_png(src / f"p{n}.png", photo(sheet, texture(sheet, xy, rng=8), K=K, T=T,
                                           rng=30 + n))
        images.append((f"p{n}.png", ids))
    write_session(src, session_json(sheet, marks=list(zip(ids, plan_for(targets))),
                                    images=images, robot=NOMINAL))
    return ids, targets


def one_mark_session(folder, sheet: dict, photo_file: str):
    """Write into ``folder`` (created) a session.json of ``sheet`` (sheet.json's content)
    with one mark and one photo ``photo_file`` showing it, for measuring a photo's dots
    alone; returns the loaded session."""
    folder.mkdir()
    (folder / "session.json").write_text(json.dumps({
        "format": "vision-cal/1", "sheet": sheet,
        "robot": {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0, 0],
                  "base_mm": [-250, 0]},
        "pen": {"mark_diameter_mm": 1.2}, "marks": [{"id": "c0", "joints_deg": [0, 0]}],
        "images": [{"file": photo_file, "marks": ["c0"]}]}))
    return load_session(folder)


def measure_image(path, session, *, lens=None, config=None):
    """One photo measured as the folder's run measures each (markers, mapping, dots in
    sheet mm): ``detect_image`` then ``finish_image``."""
    return finish_image(detect_image(path, session, config=config), session, lens,
                        config=config)
