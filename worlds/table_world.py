"""A large printed sheet lying on a table with an object on it, photographed by two
different cameras (issue 37: the world learns from real photos).

What real photos of one real print showed (a large ArUco grid on a table, three photos from
a phone and three from a DSLR, two surveys that did not describe one print) and this world
renders:

- the paper lies on the table in waves (:class:`Waves`: two plane waves, about 1 mm high,
  never below the table): the point printed at (x, y) sits at (x, y, h(x, y)), as
  ``world/height.py`` places it;
- an object stands on the paper (:class:`Box`, a mug-sized block), hiding what is behind it
  from each camera and cutting the markers at its edges;
- the print is off its layout (``world/print_deviation``: a smooth field and toner);
- two cameras (:class:`TableCamera`): a phone (wide, 4:3, its lens with the tangential and
  thin-prism terms real phone photos show, ``world/camera.phone_lens``, JPEG) and a DSLR
  (a longer lens, 3:2, radial distortion only, another resolution), each photographing
  from its own places round the sheet (``bench/survey_two_cameras.py`` builds a phone, a
  DSLR and their places).

Rendering (:meth:`TableWorld.photograph`) is ray casting, one ray per (supersampled) pixel:
the pixel undistorted by OpenCV's own model (``cv2.undistortPoints``, iterated to
1e-10: 5, 8, 12 or 14 coefficients), the ray met with the waved paper by a fixed-point iteration on its height
(it converges by the waves' slope times the ray's, below 0.05 a step), the box's faces in
front of it, the table around the paper. The paper's texture (``world/sheet.sheet_texture``
with the print) is looked up where the ray meets the paper; the box and the table are
shaded flat under a light from above. Then the supersampled image is averaged down, blurred
(the optics), vignetted, given signal-dependent noise and, for the phone, a JPEG round trip.

The world's own code: it imports ``world/``, ``dataset/`` (the sheet's description) and
OpenCV, never the estimator (``measure/``, ``model/``, ``identify/``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision_cal.dataset.session import Sheet
from vision_cal.world.print_deviation import PrintField, PrintScene
from vision_cal.world.sheet import make_sheet, sheet_texture, sheet_to_texture_pixel

#: fixed-point steps of the ray against the waved paper (converges by ~0.05 a step: four
#: leave 1e-5 of the waves' height)
RAY_STEPS = 4
CHUNK = 1 << 20   # rays cast at once
TABLE_RGB = (150.0, 112.0, 74.0)   # a wooden table
LIGHT = np.array([-0.3, -0.4, 1.0]) / np.linalg.norm([-0.3, -0.4, 1.0])   # towards the light


@dataclass(frozen=True)
class Waves:
    """The paper's height over the table: ``h = sum a_k (1 + sin(2 pi s_k / lam_k + ph_k)) / 2``
    with ``s_k`` the position along direction ``dir_k``; never below the table (mm)."""

    amplitude_mm: tuple[float, ...]
    wavelength_mm: tuple[float, ...]
    direction_deg: tuple[float, ...]
    phase: tuple[float, ...]

    @classmethod
    def random(cls, rng, *, peak_mm: float = 1.0) -> "Waves":
        """Two waves of 120-300 mm whose heights add up to ``peak_mm`` at most."""
        a = rng.uniform(0.3, 1.0, 2)
        a = peak_mm * a / a.sum()
        return cls(tuple(a), tuple(rng.uniform(120.0, 300.0, 2)),
                   tuple(rng.uniform(0.0, 180.0, 2)), tuple(rng.uniform(0, 2 * np.pi, 2)))

    def height_mm(self, x, y) -> np.ndarray:
        h = np.zeros(np.broadcast(x, y).shape)
        for a, lam, d, ph in zip(self.amplitude_mm, self.wavelength_mm, self.direction_deg,
                                 self.phase):
            s = x * np.cos(np.radians(d)) + y * np.sin(np.radians(d))
            h = h + a * (1.0 + np.sin(2 * np.pi * s / lam + ph)) / 2.0
        return h


@dataclass(frozen=True)
class Box:
    """A block standing on the paper: its footprint's centre (x, y) and size (w along its
    own x, d along y), its height, turned ``yaw_deg`` about z; ``rgb`` its colour."""

    centre_mm: tuple[float, float]
    size_mm: tuple[float, float, float]
    yaw_deg: float
    rgb: tuple[float, float, float] = (40.0, 70.0, 140.0)

    def hit(self, C, d):
        """For rays ``C`` (3,) + t ``d`` (N, 3): the distance ``t`` (N,) to the box (inf where
        missed) and the normal (N, 3) of the face hit (sheet frame)."""
        c, s = np.cos(np.radians(self.yaw_deg)), np.sin(np.radians(self.yaw_deg))
        Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])   # box -> sheet
        o = Rz.T @ (np.asarray(C, float) - [*self.centre_mm, 0.0])
        v = d @ Rz                                                    # (N, 3) in the box
        half = np.array([self.size_mm[0] / 2, self.size_mm[1] / 2])
        lo = np.array([-half[0], -half[1], 0.0])
        hi = np.array([half[0], half[1], self.size_mm[2]])
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (lo - o) / v
            t2 = (hi - o) / v
        tn, tf = np.minimum(t1, t2), np.maximum(t1, t2)
        tn = np.where(np.isnan(tn), -np.inf, tn)
        tf = np.where(np.isnan(tf), np.inf, tf)
        near, far = tn.max(axis=1), tf.min(axis=1)
        hit = (near <= far) & (near > 0)
        axis = tn.argmax(axis=1)
        n_box = np.zeros((len(v), 3))
        n_box[np.arange(len(v)), axis] = -np.sign(v[np.arange(len(v)), axis])
        return np.where(hit, near, np.inf), n_box @ Rz.T


@dataclass(frozen=True)
class TableCamera:
    """A camera of the world: ``K`` (3, 3), OpenCV ``dist`` (5, 8, 12 or 14 terms),
    ``size_px`` (w, h), the sensor's ``noise`` (grey levels at mid grey), its JPEG quality
    (None: PNG), its optics' blur (px, Gaussian sigma)."""

    name: str
    size_px: tuple[int, int]
    K: np.ndarray
    dist: np.ndarray
    noise: float = 1.5
    jpeg_quality: int | None = None
    blur_px: float = 0.6


@dataclass(frozen=True)
class TableWorld:
    """The sheet (its description), its print (``field``), the paper's ``waves``, the
    ``box`` on it (None: none) and the printed texture (``ppm`` texels per mm)."""

    sheet: Sheet
    field: PrintField
    waves: Waves
    box: Box | None
    texture: np.ndarray
    ppm: float

    def printed_corners(self) -> np.ndarray:
        """(M, 4, 2) every marker's corners as printed on the paper (the truth)."""
        return self.field.printed_corners(np.array([m.corners_mm for m in self.sheet.markers]))

    def straight_side_corners(self) -> np.ndarray:
        """(M, 4, 2) where each printed marker's straight-fitted sides meet
        (``PrintField.straight_side_corners``: a corner detector fitting lines to the sides
        reads these, the field's curvature along a side moving them off the corner points
        by about 0.4 h^2 times the curvature)."""
        return self.field.straight_side_corners(
            np.array([m.corners_mm for m in self.sheet.markers]))

    def corners_3d(self) -> np.ndarray:
        """(M, 4, 3) every printed corner where it lies in space (on the waves)."""
        c = self.printed_corners()
        return np.concatenate([c, self.waves.height_mm(c[..., 0], c[..., 1])[..., None]], axis=2)

    def hidden(self, T_cam_sheet) -> np.ndarray:
        """(M,) bool: markers with a corner behind the box from the camera at
        ``T_cam_sheet``."""
        if self.box is None:
            return np.zeros(len(self.sheet.markers), bool)
        T = np.asarray(T_cam_sheet, float)
        C = -T[:3, :3].T @ T[:3, 3]
        P = self.corners_3d().reshape(-1, 3)
        d = P - C
        t, _ = self.box.hit(C, d)
        return (t < 1.0).reshape(-1, 4).any(axis=1)

    def photograph(self, cam: TableCamera, T_cam_sheet, *, rng=None, supersample: int = 2
                   ) -> np.ndarray:
        """RGB uint8 (h, w, 3): the camera ``cam`` at ``T_cam_sheet`` (module docstring)."""
        rng = np.random.default_rng(rng)
        w, h = cam.size_px
        s = int(supersample)
        u = (np.arange(w * s) + 0.5) / s - 0.5
        v = (np.arange(h * s) + 0.5) / s - 0.5
        U, V = np.meshgrid(u, v)
        C, d = _rays(cam, T_cam_sheet, np.column_stack([U.ravel(), V.ravel()]))
        rgb = self._shade(C, d, (h * s, w * s))
        img = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA) if s > 1 else rgb
        return _sensor(img, cam, rng)

    def _meet_paper(self, C, d):
        """The rays ``C`` + t ``d`` (N, 3) met with the waved paper (the table at z = 0
        around it): (x, y) (N, 2), t (N,), on the paper (N,) bool."""
        x0, y0, x1, y1 = (float(v) for v in self.sheet.extent_mm)
        p = np.empty((len(d), 2))
        t = np.empty(len(d))
        for a in range(0, len(d), CHUNK):
            dc = d[a:a + CHUNK]
            tc = -C[2] / dc[:, 2]
            for _ in range(RAY_STEPS):
                pc = C[:2] + tc[:, None] * dc[:, :2]
                inside = ((pc[:, 0] >= x0) & (pc[:, 0] <= x1)
                          & (pc[:, 1] >= y0) & (pc[:, 1] <= y1))
                z = np.where(inside, self.waves.height_mm(pc[:, 0], pc[:, 1]), 0.0)
                tc = (z - C[2]) / dc[:, 2]
            p[a:a + CHUNK] = C[:2] + tc[:, None] * dc[:, :2]
            t[a:a + CHUNK] = tc
        on = (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)
        return p, t, on

    def _shade(self, C, d, shape) -> np.ndarray:
        """(h, w, 3) float colours of the rays ``C`` + t ``d`` (N = h w, row by row): paper,
        box or table."""
        p, t, on = self._meet_paper(C, d)
        tp = sheet_to_texture_pixel(p, extent_mm=self.sheet.extent_mm, px_per_mm=self.ppm)
        out = cv2.remap(self.texture, tp[:, 0].astype(np.float32).reshape(shape),
                        tp[:, 1].astype(np.float32).reshape(shape), cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE).reshape(-1, 3)
        out[~on] = _table(p[~on, 0], p[~on, 1])
        if self.box is not None:
            near = self._near_box(C, d)
            tb, n = self.box.hit(C, d[near])
            front = tb < t[near]
            lam = 0.35 + 0.65 * np.clip(n[front] @ LIGHT, 0.0, 1.0)
            idx = np.flatnonzero(near)[front]
            out[idx] = np.asarray(self.box.rgb, np.float32) * lam[:, None].astype(np.float32)
        return out.reshape(*shape, 3)

    def _near_box(self, C, d) -> np.ndarray:
        """(N,) bool: the rays whose direction lies within the box's corners' angular hull
        (a superset of those that hit it), by a cone about the ray to its centre."""
        b = self.box
        c, s = np.cos(np.radians(b.yaw_deg)), np.sin(np.radians(b.yaw_deg))
        hx, hy, hz = b.size_mm[0] / 2, b.size_mm[1] / 2, b.size_mm[2]
        pts = np.array([[b.centre_mm[0] + c * sx * hx - s * sy * hy,
                         b.centre_mm[1] + s * sx * hx + c * sy * hy, z]
                        for sx in (-1, 1) for sy in (-1, 1) for z in (0.0, hz)]) - C
        pts /= np.linalg.norm(pts, axis=1, keepdims=True)
        axis = pts.mean(axis=0)
        axis /= np.linalg.norm(axis)
        cos_max = float((pts @ axis).min())
        dn = d / np.linalg.norm(d, axis=1, keepdims=True)
        return dn @ axis >= cos_max - 1e-6


def _rays(cam: TableCamera, T_cam_sheet, uv) -> tuple[np.ndarray, np.ndarray]:
    """The camera's centre (3,) and the directions (N, 3) of the rays of pixels ``uv``
    (N, 2), sheet frame: each pixel undistorted by OpenCV's model of ``cam.dist``."""
    xy = cv2.undistortPoints(np.asarray(uv, np.float64).reshape(-1, 1, 2), cam.K,
                             np.asarray(cam.dist, float),
                             criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50,
                                       1e-10))
    rays_c = np.column_stack([xy.reshape(-1, 2), np.ones(len(xy))])
    T = np.asarray(T_cam_sheet, float)
    R = T[:3, :3]
    return -R.T @ T[:3, 3], rays_c @ R             # R^T d_cam, row by row


def _table(x, y) -> np.ndarray:
    """The table's wood at sheet points (x, y): grain along x, a slow shade."""
    g = 0.88 + 0.07 * np.sin(x / 2.3 + 3.0 * np.sin(y / 37.0)) + 0.04 * np.sin(y / 90.0)
    return (np.asarray(TABLE_RGB, np.float32)[None, :] * g[:, None]).astype(np.float32)


def _sensor(img: np.ndarray, cam: TableCamera, rng) -> np.ndarray:
    """The optics' blur, vignetting, signal-dependent noise and the camera's JPEG."""
    h, w = img.shape[:2]
    img = cv2.GaussianBlur(img, (0, 0), cam.blur_px) if cam.blur_px > 0 else img
    yy, xx = np.mgrid[0:h, 0:w]
    r2 = ((xx - cam.K[0, 2]) ** 2 + (yy - cam.K[1, 2]) ** 2) / float(cam.K[0, 0]) ** 2
    img = img * (1.0 / (1.0 + r2) ** 2 * 0.25 + 0.75)[..., None].astype(np.float32)
    img = img + rng.normal(0.0, 1.0, img.shape).astype(np.float32) * \
        (cam.noise * np.sqrt(0.25 + 0.75 * np.clip(img, 0, 255) / 255.0))
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if cam.jpeg_quality is not None:
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(out, cv2.COLOR_RGB2BGR),
                               [cv2.IMWRITE_JPEG_QUALITY, int(cam.jpeg_quality)])
        out = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return out


def table_world(seed: int, *, grid=(6, 8), marker_mm: float = 28.0, pitch_mm: float = 44.0,
                print_rms_mm: float = 0.2, toner_mm: float = 0.05, waves_mm: float = 1.0,
                box: bool = True, ppm: float = 8.0, dictionary: str = "DICT_6X6_1000"
                ) -> TableWorld:
    """The world of ``seed``: an ArUco grid of ``grid`` (columns, rows) markers of
    ``marker_mm`` every ``pitch_mm`` (the default: 6 x 8 markers over 272 x 360 mm of paper),
    printed ``print_rms_mm`` off its layout with ``toner_mm`` of toner, lying in waves of
    ``waves_mm``, with a block of about 80 x 60 x 90 mm standing on it near one side."""
    rng = np.random.default_rng([int(seed), 3700])
    nx, ny = int(grid[0]), int(grid[1])
    margin = 12.0
    size = ((nx - 1) * pitch_mm + marker_mm + 2 * margin, (ny - 1) * pitch_mm + marker_mm + 2 * margin)
    sheet = make_sheet(size_mm=size, bottom_left_mm=(-size[0] / 2, -size[1] / 2),
                       dictionary=dictionary, marker_mm=marker_mm, grid=(nx, ny),
                       margin_mm=margin)
    corners = np.array([m.corners_mm for m in sheet.markers])
    field = PrintScene(print_rms_mm, toner_mm).field(sheet.extent_mm, corners,
                                                      seed=int(rng.integers(1 << 30)))
    waves = Waves.random(rng, peak_mm=waves_mm)
    blk = None
    if box:
        side = rng.choice([-1, 1])
        blk = Box((float(side * size[0] * rng.uniform(0.15, 0.3)),
                   float(rng.uniform(-0.3, 0.3) * size[1])),
                  (float(rng.uniform(70, 90)), float(rng.uniform(50, 70)),
                   float(rng.uniform(70, 100))), float(rng.uniform(0, 90)))
    tex = sheet_texture(sheet, marks_xy_mm=np.zeros((0, 2)), px_per_mm=ppm,
                        rng=int(rng.integers(1 << 30)), print_field=field)
    tex = cv2.GaussianBlur(tex.astype(np.float32), (0, 0), 0.08 * ppm)   # the ink's edge
    return TableWorld(sheet, field, waves, blk, tex, float(ppm))
