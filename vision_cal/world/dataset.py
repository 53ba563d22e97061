"""Render a scene into a dataset folder in the shared format (``vision-cal/1``).

``render_dataset(scene, out_dir)`` builds the sheet, the plan (from the *nominal* model,
as a real user would), lets the *true* robot draw the marks (``world.draw_marks``),
photographs the sheet and writes::

    out_dir/
      img_000.png ...   photographs (JPEG ``img_000.jpg`` when photos.jpeg_quality is set)
      session.json      what a real user knows: nominal robot, sheet, plan, images, and
                        ``camera`` only when the scene declares the lens
      truth.json        true params, effects (plus ``lens_distortion`` when the lens is
                        present but undeclared), true mark positions, the camera's K, dist
                        and per-photo poses ``T_cam_sheet`` (added field: 4x4, sheet mm ->
                        camera mm, OpenCV camera axes); added fields: controller,
                        approach / link_q_deg per mark, off_paper, on_marker,
                        arm_parked_q_deg, extra_files, repeatability_mm, seed

The lens is applied by ``Photographer.photograph(dist=..., K_dist=K)`` on an ideal render
whose K is :func:`photographer_K` (wider than K for a barrel lens, so no black corners).

Photos: ``series`` takes one photo after each mark (``images[k].marks`` = marks 0..k);
``single`` one photo of the finished sheet. A moving camera cycles through
``camera.n_views`` poses; a still one keeps the first. With ``photos.arm_parked`` the arm
is parked over the sheet in every third photo of a series (photos 2, 5, 8, ...) and in a
single photo.

Everything is written into a hidden temporary folder next to ``out_dir`` that is renamed
to ``out_dir`` at the end, so a failed render leaves nothing half-written. An existing
``out_dir`` is replaced only when it is empty or a previous dataset (has session.json);
``vision-cal render`` moves that one to ``previous/render/`` first (dataset/out_folder.py).

Memory and time: the textures of the finished and of the mark-free sheet are built once
(one pass: :func:`build_textures`; with ``jobs`` > 1 in this process, and handed to every
rendering process), and the texture with k marks is kept up to date by copying each new
mark's small patch into the mark-free texture, so a 38-photo series at 2400 x 1800 holds
two textures (three in each rendering process) and one photo at a time.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing as mp
import os
import shutil
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vision_cal.dataset.io import atomic_write_json, note_written
from vision_cal.dataset.marker_geometry import marker_boxes_mm
from vision_cal.errors import VisionCalError
from vision_cal.plan import calibration_plan as cp
from vision_cal.plan.calibration_plan import paper_plan
from vision_cal.world.camera import camera_matrix, default_views, ideal_K
from vision_cal.world.photo import Photographer
from vision_cal.world.printed import load_printed_sheet, printed_textures
from vision_cal.world.scene import Scene
from vision_cal.world.sheet import make_sheet, sheet_textures
from vision_cal.progress import bar as progress_bar
from vision_cal.world.drawing import WorldMarks, arm_boxes, draw_marks, parking_pose, simulated_world

log = logging.getLogger(__name__)

FORMAT = "vision-cal/1"
PARK_EVERY = 3          # series: the arm is parked in photos k with k % 3 == 2
DOT_SIZE_MAX = 1.1 * np.sqrt(1.15)  # largest dot radius / nominal radius (sheet_texture)


@dataclass(frozen=True)
class _Streams:
    """Independent random streams, all from the scene seed (changing one part of a scene
    does not reshuffle the others)."""

    plan: np.random.Generator
    world: np.random.Generator
    texture_seed: int
    views: np.random.Generator
    photos: np.random.Generator
    park: np.random.Generator
    extras: np.random.Generator
    sim: np.random.Generator
    focal: np.random.Generator

    @classmethod
    def from_seed(cls, seed: int) -> "_Streams":
        ss = np.random.SeedSequence(seed).spawn(9)
        g = [np.random.default_rng(s) for s in ss]
        return cls(g[0], g[1], int(ss[2].generate_state(1)[0]), g[3], g[4], g[5], g[6], g[7],
                   g[8])


# --------------------------------------------------------------------------------- plan


def pilot_marks(scene: Scene, *, rng=None) -> tuple[np.ndarray, np.ndarray]:
    """A pilot run: the true robot draws the seed paper's five marks (zero, joint 1 at
    +-20 deg, joint 2 at +-60 deg) on scrap paper, measured to 0.05 mm. Returns the
    commanded joints (5, 2) deg and the measured marks (5, 2) mm."""
    rng = np.random.default_rng(rng)
    pilot = paper_plan()
    w = draw_marks(scene.robot.true_robot, pilot, home_deg=scene.robot.nominal.home_deg,
                   repeatability_mm=0.05, rng=rng)
    return np.array([m.joints_deg for m in pilot], dtype=float), w.xy_mm


def build_plan(scene: Scene, sheet, *, pilot=None, rng=None) -> list:
    """The scene's plan (``list[PlannedMark]``), computed from the nominal model, or with
    ``plan.pilot`` (the default) from a pilot calibration: the world draws
    :func:`pilot_marks` and ``pilot(q_deg, xy_mm) -> ScaraParams`` calibrates them (the
    caller passes the calibrator, e.g. ``vision_cal.estimate.paper.pilot_params``: the
    world does not import the estimator). The catalogue model misses by tens of
    millimetres (SM5: zeros 2.6 and 8.1 deg off), too much to keep marks off the printed
    markers; the pilot model misses by about a millimetre."""
    if scene.plan.kind == "paper":
        return list(cp.paper_plan())
    if scene.plan.pilot:
        if pilot is None:
            raise VisionCalError("the scene plans from a pilot calibration (plan.pilot): "
                                 "pass a calibrator, pilot=vision_cal.estimate.paper."
                                 "pilot_params", field="pilot")
        rng = np.random.default_rng(rng)
        model = pilot(*pilot_marks(scene, rng=rng))
    else:
        model = scene.robot.nominal.params
    return cp.informative_plan(model, sheet, n_calibration=scene.plan.n_calibration,
                               n_validation=scene.plan.n_validation,
                               pen_diameter_mm=scene.robot.pen_diameter_mm,
                               min_separation_mm=scene.plan.min_separation_mm, rng=rng)


# ----------------------------------------------------------------------------- textures


class Textures:
    """The texture with the first k marks, kept up to date cheaply.

    ``full`` is the finished sheet; ``current`` starts mark-free and gets each new mark's
    disc copied in from ``full`` (same paper grain: both come from one build, the sheet
    texture draws the paper before the dots). ``built``: the pair ``(full, mark-free)``
    of :func:`build_textures`, built once for every photo of a dataset (the rendering
    processes get it instead of building their own); None: built here.
    """

    def __init__(self, sheet, xy_mm, diameters_mm, *, px_per_mm, seed, printed=None,
                 print_field=None, built=None):
        if printed is not None:  # the printed sheet's own raster (vision_cal.world.printed)
            px_per_mm = printed.px_per_mm
        self.xy_mm = np.asarray(xy_mm, float)
        self.d_mm = np.asarray(diameters_mm, float)
        self.ppm = float(px_per_mm)
        self.extent = tuple(float(v) for v in sheet.extent_mm)
        if built is None:
            built = build_textures(sheet, self.xy_mm, self.d_mm, px_per_mm=self.ppm,
                                   seed=seed, printed=printed, print_field=print_field)
        self.full = built[0]
        self.current = built[1].copy()   # patched in place: the shared one stays mark-free
        self.k = 0

    def add_marks(self, k: int) -> np.ndarray:
        """The texture with marks 0..k-1 (in place; returns ``current``)."""
        H, W = self.current.shape[:2]
        x0, _, _, y1 = self.extent
        for i in range(self.k, k):
            u = (self.xy_mm[i, 0] - x0) * self.ppm - 0.5
            v = (y1 - self.xy_mm[i, 1]) * self.ppm - 0.5
            r = 0.5 * self.d_mm[i] * DOT_SIZE_MAX * self.ppm + 1.5
            c0, c1 = max(int(np.floor(u - r)), 0), min(int(np.ceil(u + r)) + 1, W)
            r0, r1 = max(int(np.floor(v - r)), 0), min(int(np.ceil(v + r)) + 1, H)
            if c1 <= c0 or r1 <= r0:
                continue  # off the paper
            yy, xx = np.mgrid[r0:r1, c0:c1]
            disc = (xx - u) ** 2 + (yy - v) ** 2 <= r * r
            self.current[r0:r1, c0:c1][disc] = self.full[r0:r1, c0:c1][disc]
        self.k = max(self.k, k)
        return self.current


def build_textures(sheet, xy_mm, diameters_mm, *, px_per_mm, seed, printed=None,
                   print_field=None):
    """``(finished sheet, mark-free sheet)`` textures from one build (paper, grid and
    markers drawn once; the same bytes as two separate ``sheet_texture`` calls);
    ``print_field``: the printer's displacement and toner (world.print_deviation)."""
    rng = np.random.default_rng(seed)
    if printed is not None:
        return printed_textures(printed, marks_xy_mm=xy_mm, mark_diameters_mm=diameters_mm,
                                px_per_mm=printed.px_per_mm, rng=rng, print_field=print_field)
    return sheet_textures(sheet, marks_xy_mm=xy_mm, mark_diameters_mm=diameters_mm,
                          px_per_mm=px_per_mm, rng=rng, print_field=print_field)


# ------------------------------------------------------------------------------- photos


@dataclass(frozen=True)
class _PhotoJob:
    """What every photo of one dataset shares (pickled to the rendering processes)."""

    sheet: object
    xy_mm: np.ndarray
    diameters_mm: np.ndarray
    texture_seed: int
    photos: object          # the scene's PhotoSpec
    dist: np.ndarray | None
    folder: Path
    printed: object = None         # a PrintedSheet photographed instead of the analytic one
    height_grid: object = None     # the sheet's height map (world.height), if not flat
    print_field: object = None     # the printer's displacement (world.print_deviation)
    textures: tuple | None = None  # (finished, mark-free) sheet textures, built once


def _shoot(job: _PhotoJob, tasks, photographer, bar=None) -> int:
    """Render ``tasks`` ((file, n_marks, T_cam_sheet, arm, rng, K_dist), in series order)
    into ``job.folder``; returns how many."""
    ph = job.photos
    textures = Textures(job.sheet, job.xy_mm, job.diameters_mm,
                         px_per_mm=ph.texture_px_per_mm, seed=job.texture_seed,
                         printed=job.printed, print_field=job.print_field,
                         built=job.textures)
    extra = {} if job.height_grid is None else {"height_grid": job.height_grid}
    for fname, n_marks, T, arm, rng, K_dist in tasks:
        tex = textures.add_marks(n_marks)
        rgb = photographer.photograph(
            tex, extent_mm=job.sheet.extent_mm, T_cam_sheet=T, dist=job.dist,
            K_dist=K_dist, arm=arm, vignetting=ph.vignetting, noise_sigma=ph.noise_sigma,
            jpeg_quality=None, rng=rng, **extra)
        (job.folder / fname).write_bytes(encode_image(np.asarray(rgb), ph.jpeg_quality))
        del rgb
        if bar is not None:
            bar.update()
    return len(tasks)


def _render_chunk(job: _PhotoJob, tasks, size_px, K) -> int:
    """A rendering process's share: its own Photographer, then :func:`_shoot`."""
    p = Photographer(size_px=size_px, K=K)
    try:
        return _shoot(job, tasks, p)
    finally:
        p.close()


# ------------------------------------------------------------------------------- output


def encode_image(rgb: np.ndarray, jpeg_quality: int | None) -> bytes:
    """PNG (lossless) or JPEG bytes of an RGB image."""
    # OpenCV takes 0.2 s to import: loaded here, when used
    import cv2

    bgr = np.ascontiguousarray(rgb[:, :, ::-1])
    if jpeg_quality is None:
        # level 1: 40 % less CPU than 3 for 3 % more bytes (2400 x 1800: 0.26 against 0.44 s,
        # 7.3 against 7.1 MB), decoded as fast; the pixels are the same
        ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    else:
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
    if not ok:
        raise VisionCalError("could not encode an image")
    return buf.tobytes()


def _extra_image(kind: str, size_px, rng: np.random.Generator) -> bytes:
    """A bad photo: ``blank`` (grey), ``noise`` (random pixels) or ``corrupt`` (bad bytes)."""
    w, h = size_px
    if kind == "blank":
        return encode_image(np.full((h, w, 3), 128, np.uint8), None)
    if kind == "noise":
        return encode_image(rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8), None)
    good = encode_image(np.full((h // 4, w // 4, 3), 200, np.uint8), None)
    return good[:64] + rng.integers(0, 256, size=256, dtype=np.uint8).tobytes()


def _entries(out_dir: Path) -> list[Path]:
    """What a dataset folder holds, without what vision-cal keeps beside a run (hidden
    files: the lock, the record, a cache; ``previous/``: earlier runs)."""
    return [p for p in out_dir.iterdir() if not p.name.startswith(".") and p.name != "previous"]


def _prepare_out(out_dir: Path) -> None:
    if out_dir.exists():
        if not out_dir.is_dir():
            raise VisionCalError("exists and is not a folder", file=str(out_dir))
        if _entries(out_dir) and not (out_dir / "session.json").exists():
            raise VisionCalError("exists and is not a dataset folder; refusing to replace it "
                                 "(choose another --out or empty it)", file=str(out_dir))
    out_dir.parent.mkdir(parents=True, exist_ok=True)


def _commit(tmp: Path, out_dir: Path) -> None:
    """Move the finished temp folder to ``out_dir`` (replacing an old dataset; what
    vision-cal keeps beside a run, :func:`_entries`, stays), each file told to the output
    set being written (``vision-cal render``: the old dataset was moved to previous/ by
    then)."""
    if not out_dir.exists():
        os.replace(tmp, out_dir)
        note_written(out_dir)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.old.", dir=out_dir.parent))
    moved = []
    try:
        for p in _entries(out_dir):
            os.replace(p, old / p.name)
            moved.append(p.name)
        for p in sorted(tmp.iterdir()):
            os.replace(p, out_dir / p.name)
            note_written(out_dir / p.name)
    except BaseException:
        for name in moved:
            with contextlib.suppress(OSError):
                os.replace(old / name, out_dir / name)
        raise
    shutil.rmtree(old, ignore_errors=True)
    shutil.rmtree(tmp, ignore_errors=True)


def lens_effect(scene: Scene) -> dict | None:
    """truth.json's ``lens_distortion`` entry: a present lens the session does not declare."""
    dist = [float(v) for v in scene.camera.dist]
    if scene.camera.declared or not any(dist):
        return None
    return {"name": "lens_distortion", "model": "opencv", "coefficients": dist}


def marks_on_markers(world: WorldMarks, sheet, *, pad_mm: float = 0.0) -> list[str]:
    """Ids of the marks that landed on a printed ArUco square (grown by ``pad_mm``)."""
    on = np.zeros(len(world.ids), dtype=bool)
    for box in marker_boxes_mm(sheet, pad_mm):
        on |= np.all((world.xy_mm >= box[:2]) & (world.xy_mm <= box[2:]), axis=1)
    return [world.ids[i] for i in np.flatnonzero(on)]


def marks_off_paper(world: WorldMarks, sheet) -> list[str]:
    """Ids of the marks that really landed off the paper (the pen drew on the table)."""
    x0, y0, x1, y1 = sheet.extent_mm
    xy = world.xy_mm
    off = np.flatnonzero((xy[:, 0] < x0) | (xy[:, 0] > x1) | (xy[:, 1] < y0) | (xy[:, 1] > y1))
    if off.size:
        log.warning("%d of %d marks land off the paper (first: %s at %s mm); they appear in "
                    "no photo", off.size, len(xy), world.ids[off[0]],
                    np.round(xy[off[0]], 1).tolist())
    return [world.ids[i] for i in off]


def photographer_K(scene: Scene) -> np.ndarray:
    """K (3, 3) the ideal pinhole render needs so that the lens fills the whole photo.

    The scene's own K, except for a lens that pulls the corners in (barrel): then the
    ideal render uses a shorter focal length (same principal point) wide enough to hold
    every undistorted photo corner, and ``photograph(K_dist=K, dist=...)`` maps it back.
    """
    cam = scene.camera
    # the shortest focal length any photo has (phones: camera.f_scatter)
    K = np.asarray(camera_matrix(size_px=cam.size_px, f_px=cam.f_px * (1.0 - cam.f_scatter),
                                 principal_px=cam.principal_px), dtype=float)
    return ideal_K(cam.size_px, K, cam.dist)


@dataclass(frozen=True)
class _SheetSetup:
    """The sheet as the world has it: ``sheet`` (the analytic one, or ``printed.sheet``),
    ``printed`` (a PrintedSheet photographed instead, or None), ``hfield`` / ``height_grid``
    (the paper's height field and its grid; None: flat), ``pfield`` (the printer's
    displacement; None: printed exactly)."""

    sheet: object
    printed: object
    hfield: object
    height_grid: object
    pfield: object


def _sheet_setup(scene: Scene, printed) -> _SheetSetup:
    """The scene's sheet (``printed`` given, the scene's printed sheet, or the analytic one
    made from its spec), its height field and its print field."""
    sh = scene.sheet
    if printed is None and sh.printed is not None:
        printed = load_printed_sheet(sh.printed)
    sheet = make_sheet(size_mm=sh.size_mm, bottom_left_mm=sh.bottom_left_mm,
                       dictionary=sh.dictionary, marker_mm=sh.marker_mm, grid=sh.grid,
                       margin_mm=sh.margin_mm) if printed is None else printed.sheet
    hfield = None
    if sh.height is not None:
        hfield = sh.height.field(sheet.extent_mm, scene.seed)
        if hfield.is_flat:
            hfield = None
    height_grid = None if hfield is None else hfield.grid()
    pfield = None
    if sh.print is not None and not sh.print.is_exact:
        pfield = sh.print.field(sheet.extent_mm, [m.corners_mm for m in sheet.markers],
                                scene.seed)
    return _SheetSetup(sheet, printed, hfield, height_grid, pfield)


@dataclass(frozen=True)
class _Drawn:
    """What the true robot drew: the ``plan`` (list of PlannedMark), the ``world`` (where
    every mark landed), the joint ``source`` used (None: kinematic), ``j4`` (each mark's
    commanded joint 4, or None), ``off_paper`` (ids of the marks on the table)."""

    plan: list
    world: WorldMarks
    source: object
    j4: list | None
    off_paper: list


def _draw(scene: Scene, sheet, st: _Streams, *, plan, pilot, joint_source,
          joint4_deg) -> _Drawn:
    """The plan (``plan``, else the scene's: :func:`build_plan`) drawn by the true robot,
    through the scene's simulated controller unless ``joint_source`` is given."""
    rob = scene.robot
    if plan is None:
        plan = build_plan(scene, sheet, pilot=pilot, rng=st.plan)
    plan = list(plan)
    truth = rob.true_robot
    predict_model, source = truth, joint_source
    if source is None and rob.controller != "kinematic":
        source, predict_model = simulated_world(truth, controller=rob.controller, rng=st.sim)
    j4 = None if joint4_deg is None else [float(joint4_deg.get(m.id, 0.0)) for m in plan]
    world = draw_marks(predict_model, plan, home_deg=rob.nominal.home_deg,
                       repeatability_mm=rob.repeatability_mm, joint_source=source,
                       rng=st.world, joint4_deg=j4)
    return _Drawn(plan, world, source, j4, marks_off_paper(world, sheet))


@dataclass(frozen=True)
class _Shots:
    """The photos to take: ``K`` / ``dist`` the scene's lens, ``views`` the camera poses,
    ``shots`` (file, marks drawn by then) in order, ``Ks`` each photo's camera matrix."""

    K: np.ndarray
    dist: np.ndarray
    views: list
    shots: list
    Ks: list


def _shots(scene: Scene, sheet, n: int, st: _Streams) -> _Shots:
    """The camera's views of ``sheet`` and the photos of the scene's mode (``series``: one
    after each of the ``n`` marks; ``survey``: the blank sheet from every view; ``single``:
    the finished sheet), each with its camera matrix (phones refocus: ``camera.f_scatter``)."""
    cam, ph = scene.camera, scene.photos
    K = np.asarray(camera_matrix(size_px=cam.size_px, f_px=cam.f_px,
                                 principal_px=cam.principal_px), dtype=float)
    dist = np.asarray(cam.dist, dtype=float)
    # the views keep the sheet in frame at the longest focal length any photo has
    K_long = K.copy()
    K_long[0, 0] = K_long[1, 1] = cam.f_px * (1.0 + cam.f_scatter)
    views = default_views(sheet, n=cam.n_views, size_px=cam.size_px, K=K_long,
                          tilt_deg=cam.tilt_deg, rng=st.views, fill=cam.fill,
                          target_jitter=(1.0 - cam.fill) / 2)
    ext = "jpg" if ph.jpeg_quality is not None else "png"
    if ph.mode == "series":
        shots = [(f"img_{k:03d}.{ext}", k + 1) for k in range(n)]
    elif ph.mode == "survey":   # the blank sheet from every view, before the robot draws
        shots = [(f"survey_{k:03d}.{ext}", 0) for k in range(len(views))]
    else:
        shots = [(f"img_000.{ext}", n)]
    Ks = []
    for _ in shots:
        Ki = K.copy()
        if cam.f_scatter > 0:
            Ki[0, 0] = Ki[1, 1] = cam.f_px * st.focal.uniform(1 - cam.f_scatter,
                                                              1 + cam.f_scatter)
        Ks.append(Ki)
    return _Shots(K, dist, views, shots, Ks)


def _check_photographer(scene: Scene, photographer, K_ideal: np.ndarray) -> None:
    """Refuse a ``photographer`` built for another camera than the scene's (its size, its
    K against ``K_ideal``); one without ``K`` / ``size_px`` is taken as it is."""
    cam = scene.camera
    if hasattr(photographer, "K") and hasattr(photographer, "size_px"):
        if (tuple(photographer.size_px) != tuple(cam.size_px)
                or not np.allclose(photographer.K, K_ideal)):
            raise VisionCalError("the photographer given was built for another camera "
                                 f"(size {tuple(photographer.size_px)}, K "
                                 f"{np.round(photographer.K, 3).tolist()}); this scene needs "
                                 f"size {tuple(cam.size_px)}, K "
                                 f"{np.round(K_ideal, 3).tolist()}", field="photographer")


@dataclass(frozen=True)
class _Tasks:
    """Every photo's rendering task (file, n_marks, T_cam_sheet, arm, rng, K_dist) and
    what the dataset says of it: ``images`` (session.json), ``poses`` / ``K_photo`` /
    ``parked`` (truth.json: T_cam_sheet, K_per_photo, arm_parked_q_deg, by file)."""

    tasks: list
    images: list
    poses: dict
    parked: dict
    K_photo: dict


def _photo_tasks(scene: Scene, sheet, drawn: _Drawn, sh: _Shots, K_ideal: np.ndarray,
                 st: _Streams) -> _Tasks:
    """Every photo's task, everything random drawn here, in photo order, so the photos do
    not depend on how many processes render them (serial and --jobs N are bit-identical)."""
    cam, ph, truth, world = scene.camera, scene.photos, scene.robot.true_robot, drawn.world
    images, poses, parked, tasks, K_photo = [], {}, {}, [], {}
    photo_rngs = st.photos.spawn(len(sh.shots))
    for i, (fname, n_marks) in enumerate(sh.shots):
        # the views are rigid poses of the arm frame; a deformed sheet (sheet_affine)
        # lies physically shrunk in it: T maps printed sheet points to the camera
        T = truth.T_render(sh.views[i % len(sh.views)] if cam.moving or ph.mode == "survey"
                           else sh.views[0])
        arm = None
        if ph.arm_parked and (ph.mode == "single" or i % PARK_EVERY == PARK_EVERY - 1):
            q_park = parking_pose(truth, sheet.extent_mm, rng=st.park)
            arm = arm_boxes(truth, q_park)
            parked[fname] = [float(v) for v in q_park]
        Ki = sh.Ks[i]
        lens = any(sh.dist) or not np.allclose(Ki, K_ideal)
        tasks.append((fname, n_marks, T, arm, photo_rngs[i], Ki if lens else None))
        images.append({"file": fname, "marks": list(world.ids[:n_marks])})
        poses[fname] = T.tolist()
        K_photo[fname] = Ki.tolist()
    return _Tasks(tasks, images, poses, parked, K_photo)


def _render_photos(job: _PhotoJob, tasks, photographer, bar, *, n_jobs: int, size_px,
                   K_ideal) -> None:
    """Render ``tasks`` into ``job.folder``: here with ``photographer``, or (``n_jobs`` > 1)
    in contiguous runs, one spawned process each (its own OpenGL context)."""
    if n_jobs <= 1:
        _shoot(job, tasks, photographer, bar)
        return
    chunks = [c for c in np.array_split(np.arange(len(tasks)), n_jobs) if len(c)]
    # spawn: a fresh process per worker, each with its own OpenGL context
    with ProcessPoolExecutor(len(chunks), mp_context=mp.get_context("spawn")) as ex:
        futs = [ex.submit(_render_chunk, job, [tasks[k] for k in c],
                          tuple(size_px), K_ideal) for c in chunks]
        for f in futs:
            bar.update(f.result())


def _session_json(scene: Scene, sheet, drawn: _Drawn, sh: _Shots, images: list,
                  targets_mm: dict | None) -> dict:
    """session.json: what a real user knows (the nominal robot, the sheet, the plan with
    its targets and joint 4, the images; the camera only when the scene declares it)."""
    rob, cam, j4 = scene.robot, scene.camera, drawn.j4
    session = {
        "format": FORMAT,
        "sheet": sheet.to_json(),
        "robot": rob.nominal.to_json(),
        "pen": {"mark_diameter_mm": rob.pen_diameter_mm},
        "marks": [dict(m.to_json(), **({"target_mm": [float(v) for v in targets_mm[m.id]]}
                                       if targets_mm and m.id in targets_mm else {}),
                       **({"j4_deg": j4[i]} if j4 is not None else {}))
                  for i, m in enumerate(drawn.plan)],
        "images": images,
    }
    if cam.declared:
        session["camera"] = {"size_px": list(cam.size_px), "K": sh.K.tolist(),
                             "dist": sh.dist.tolist()}
    return session


def _truth_json(scene: Scene, ss: _SheetSetup, drawn: _Drawn, sh: _Shots, t: _Tasks, *,
                custom_source: bool) -> dict:
    """truth.json: the true params and effects, where every mark landed, the camera and
    each photo's pose, and how the world got there (module docstring's added fields)."""
    rob, cam, ph, world = scene.robot, scene.camera, scene.photos, drawn.world
    hfield, pfield, sheet = ss.hfield, ss.pfield, ss.sheet
    effects = [e.to_json() for e in rob.effects] + list(rob.drift)
    lens = lens_effect(scene)
    if lens is not None:
        effects.append(lens)
    if hfield is not None:
        effects.append(hfield.effect_json())
    truth_json = {
        "params": rob.truth_params_json,
        "effects": effects,
        "marks": {mid: world.xy_mm[i].tolist() for i, mid in enumerate(world.ids)},
        "camera": {"size_px": list(cam.size_px), "K": sh.K.tolist(), "dist": sh.dist.tolist(),
                   "declared": cam.declared, "T_cam_sheet": t.poses,
                   "K_per_photo": t.K_photo},
        # added fields: how the world got there
        "repeatability_mm": rob.repeatability_mm,
        "controller": rob.controller if not custom_source else "custom",
        "approach": {mid: world.approach[i].tolist() for i, mid in enumerate(world.ids)},
        "link_q_deg": {mid: world.q_deg[i].tolist() for i, mid in enumerate(world.ids)},
        "off_paper": drawn.off_paper,
        "on_marker": marks_on_markers(world, sheet),
        "arm_parked_q_deg": t.parked,
        "extra_files": {e.file: e.kind for e in ph.extra_files},
        "seed": scene.seed,
        "controller_report": getattr(drawn.source, "report", None),
    }
    if hfield is not None:  # added fields: the paper's height field, each mark's height
        truth_json["sheet_height"] = hfield.to_json()
        truth_json["mark_height_mm"] = {mid: float(z) for mid, z in zip(
            world.ids, hfield.height_mm(world.xy_mm))}
    if pfield is not None:  # added field: the sheet as printed (world.print_deviation)
        truth_json["print"] = pfield.to_json([m.id for m in sheet.markers],
                                             [m.corners_mm for m in sheet.markers])
    return truth_json


def render_dataset(scene: Scene, out_dir, *, progress: bool = False, photographer=None,
                   joint_source=None, plan=None, targets_mm: dict | None = None,
                   pilot=None, printed=None, jobs: int | None = 1,
                   joint4_deg: dict | None = None) -> Path:
    """Render ``scene`` into the dataset folder ``out_dir``; return its path.

    ``plan``: draw these ``PlannedMark`` instead of the scene's calibration plan (the
    closed loop draws planned targets); ``pilot``: the calibrator of the pilot run (see
    :func:`build_plan`), needed when the scene plans from one; ``targets_mm``: id -> the sheet point the OLP meant
    to hit, written as the marks' ``target_mm``.

    ``photographer``: an existing ``Photographer`` for this scene's camera (size K from
    :func:`photographer_K`) to reuse (tests share one); by default one is built.
    ``joint_source``: see :mod:`vision_cal.world.drawing` (overrides ``robot.controller``;
    the truth model then predicts with every effect, backlash included).
    ``printed``: a :class:`vision_cal.world.printed.PrintedSheet` (``vision-cal sheet``'s
    sheet.json and PNG) photographed instead of the scene's analytic sheet.
    ``jobs``: processes that render photos (contiguous runs of the series, one renderer
    each; only with the default photographer); the photos are the same for any number.
    ``progress``: see :mod:`vision_cal.progress`.
    ``joint4_deg``: mark id -> commanded joint 4 (deg), written as the marks' ``j4_deg``
    (marks not named: 0); the world turns joint 4 there (``robot.tool_mm`` in the scene).
    """
    out_dir = Path(out_dir).absolute()
    _prepare_out(out_dir)
    st = _Streams.from_seed(scene.seed)
    cam, ph = scene.camera, scene.photos
    ss = _sheet_setup(scene, printed)
    sheet = ss.sheet
    drawn = _draw(scene, sheet, st, plan=plan, pilot=pilot, joint_source=joint_source,
                  joint4_deg=joint4_deg)
    world = drawn.world
    diameters = scene.robot.pen_diameter_mm * np.ones(len(drawn.plan))
    sh = _shots(scene, sheet, len(drawn.plan), st)

    K_ideal = photographer_K(scene)
    own = photographer is None
    if own:
        photographer = Photographer(size_px=cam.size_px, K=K_ideal)
    else:
        _check_photographer(scene, photographer, K_ideal)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.tmp.", dir=out_dir.parent))
    bar = None
    try:
        t = _photo_tasks(scene, sheet, drawn, sh, K_ideal, st)
        n_jobs = min(int(jobs or 1), len(t.tasks)) if own else 1
        # the sheet's textures are built once here and shared by every rendering process
        built = (build_textures(sheet, world.xy_mm, diameters, px_per_mm=ph.texture_px_per_mm,
                                seed=st.texture_seed, printed=ss.printed, print_field=ss.pfield)
                 if n_jobs > 1 else None)
        job = _PhotoJob(sheet, world.xy_mm, diameters, st.texture_seed, ph,
                        sh.dist if any(sh.dist) else None, tmp,
                        ss.printed, ss.height_grid, ss.pfield, built)
        bar = progress_bar(progress, total=len(t.tasks), desc=f"render {out_dir.name}",
                           unit="photo", note=f"{max(n_jobs, 1)} job(s)")
        _render_photos(job, t.tasks, photographer, bar, n_jobs=n_jobs, size_px=cam.size_px,
                       K_ideal=K_ideal)
        for e in ph.extra_files:
            (tmp / e.file).write_bytes(_extra_image(e.kind, cam.size_px, st.extras))
            t.images.append({"file": e.file, "marks": list(world.ids)})
        atomic_write_json(tmp / "session.json",
                          _session_json(scene, sheet, drawn, sh, t.images, targets_mm))
        atomic_write_json(tmp / "truth.json", _truth_json(
            scene, ss, drawn, sh, t, custom_source=joint_source is not None))
        _commit(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        if bar is not None:
            bar.close()
        if own and hasattr(photographer, "close"):
            photographer.close()
    return out_dir
