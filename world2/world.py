"""A whole print-off world: the robot, its marks, the paper, the camera(s), and the dataset
folder written per the contract (session.json, photos, truth.json)."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from .camera import Lens, photograph, view_from
from .robot import Scara, approach_of, ik
from .scene import Scene
from .sheet import Layout, PaperShape, PrintField, a2_layout


@dataclass
class Options:
    seed: int = 0
    views: int = 6                    # camera places (moving camera) ...
    fixed: bool = False               # ... or one camera standing still
    fixed_photos: int = 4             # photos taken by the fixed camera as marks are drawn
    tilt_deg: tuple[float, float] = (8.0, 20.0)
    size_px: tuple[int, int] = (2400, 1800)
    f_over_w: float = 1.08            # focal length in units of the image width
    dist: tuple = (-0.06, 0.03, 0.0004, -0.0003, 0.0)
    declare_lens: bool = False
    print_rms_mm: float = 0.2
    toner_mm: float = 0.06
    paper_peak_mm: float = 0.1
    backlash2_deg: float = 0.1
    repeat_mm: float = 0.005
    pen_mm: float = 1.2
    n_validation: int = 8
    plan_grid: tuple[int, int] = (5, 6)   # calibration marks: joint-1 turns x joint-2 turns
    ss: int = 1                       # samples per pixel side (box-filtered anyway)
    blur_px: float = 0.7
    noise: float = 0.006              # sensor noise, linear units
    gamma: float = 2.2                # the photo's encoding (sRGB-like); 1: linear values
    texture_px_per_mm: float = 50.0
    jpeg_quality: int | None = 95
    layout: Layout | None = None


@dataclass
class World:
    opt: Options
    layout: Layout
    robot: Scara
    nominal: dict
    marks: list[dict]                 # session marks (id, joints_deg, role, ...)
    true_xy: np.ndarray               # (N, 2) where the pen really put each mark
    true_s: np.ndarray                # (N, 2) the side each joint came from
    field: PrintField | None
    shape: PaperShape | None
    lens: Lens
    poses: list[np.ndarray]           # T_cam_sheet per photo
    on_sheet: list[int]               # marks drawn when each photo was taken
    scene: Scene = field(repr=False, default=None)


def _robot(rng) -> tuple[Scara, dict]:
    L1, L2 = 350 + rng.normal(0, 2.5), 260 + rng.normal(0, 1.5)
    z1, z2 = rng.uniform(-6, 6), rng.uniform(-6, 6)
    centre = rng.uniform(-15, 15, 2)
    a1, a12 = np.radians(z1), np.radians(z1 + 90 + z2)
    base = centre - [L1 * np.cos(a1) + L2 * np.cos(a12), L1 * np.sin(a1) + L2 * np.sin(a12)]
    guess = np.round(base / 10) * 10 + rng.choice([-10, 10], 2)
    nominal = {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
               "base_mm": guess.tolist(), "home_deg": [0.0, 90.0]}
    return Scara(L1, L2, z1, z2, tuple(base)), nominal


def _clear(layout: Layout, xy: np.ndarray, quiet_mm: float = 5.0) -> np.ndarray:
    """Points inside the grid area, away from every marker."""
    x0, y0, x1, y1 = layout.grid_extent_mm
    ok = (xy[:, 0] > x0 + 4) & (xy[:, 0] < x1 - 4) & (xy[:, 1] > y0 + 4) & (xy[:, 1] < y1 - 4)
    for c in layout.markers.values():
        lo, hi = c.min(axis=0) - quiet_mm, c.max(axis=0) + quiet_mm
        ok &= ~np.all((xy > lo) & (xy < hi), axis=1)
    return ok


def _plan(robot: Scara, nominal: dict, layout: Layout, opt: Options, rng):
    """Calibration marks on a serpentine over a (q1, q2) grid (the paper's turns of each
    joint), validation marks at random targets commanded with the nominal model."""
    q1s = np.linspace(-18, 18, opt.plan_grid[0])
    q2s = 90 + np.linspace(-48, 48, opt.plan_grid[1])
    cal = []
    for i, q1 in enumerate(q1s):
        for q2 in (q2s if i % 2 == 0 else q2s[::-1]):
            cal.append([q1, q2])
    cal = np.array(cal) + rng.normal(0, 0.3, (len(cal), 2))
    xy = robot.pen(cal, approach_of(cal, nominal["home_deg"]))
    cal = cal[_clear(layout, xy)]
    x0, y0, x1, y1 = layout.grid_extent_mm
    val, targets = [], []
    while len(val) < opt.n_validation:
        t = rng.uniform([x0 + 30, y0 + 30], [x1 - 30, y1 - 30])
        q = ik(nominal["L1_mm"], nominal["L2_mm"], *nominal["joint_zero_deg"], nominal["base_mm"], t)[0]
        p = robot.pen(q, [1, 1])
        near = np.concatenate([robot.pen(cal, np.ones_like(cal)), robot.pen(np.array(val).reshape(-1, 2), np.ones((len(val), 2)))])
        if _clear(layout, p)[0] and np.min(np.linalg.norm(near - p, axis=1)) > 10:
            val.append(np.round(q, 3))
            targets.append(t)
    order = list(range(len(cal)))
    for k in range(len(val)):                       # validation marks among the others
        order.insert(int(rng.integers(0, len(order) + 1)), len(cal) + k)
    marks, q_all, s_written = [], [], []
    for n, j in enumerate(order):
        if j < len(cal):
            marks.append({"id": f"c{j:02d}", "joints_deg": np.round(cal[j], 3).tolist(),
                          "role": "calibration"})
            q_all.append(np.round(cal[j], 3))
            s_written.append(None)
        else:
            k = j - len(cal)
            s = rng.choice([-1, 1], 2)
            marks.append({"id": f"v{k:02d}", "joints_deg": val[k].tolist(), "approach": s.tolist(),
                          "role": "validation", "target_mm": np.round(targets[k], 3).tolist()})
            q_all.append(val[k])
            s_written.append(s)
    q_all = np.array(q_all)
    s = approach_of(q_all, nominal["home_deg"])
    for i, w in enumerate(s_written):
        if w is not None:      # the arm overshot and came back from the written side
            s[i] = w
    return marks, q_all, s


def make_world(opt: Options) -> World:
    rng = np.random.default_rng([2024, opt.seed])
    layout = opt.layout or a2_layout()
    robot, nominal = _robot(rng)
    robot = Scara(robot.L1, robot.L2, robot.z1_deg, robot.z2_deg, robot.base,
                  opt.backlash2_deg, opt.repeat_mm)
    marks, q, s = _plan(robot, nominal, layout, opt, rng)
    true_xy = robot.pen(q, s) + rng.normal(0, opt.repeat_mm, (len(q), 2))
    fld = PrintField(layout, opt.print_rms_mm, rng) if opt.print_rms_mm > 0 else None
    shape = PaperShape(layout, opt.paper_peak_mm, rng) if opt.paper_peak_mm > 0 else None
    w, h = opt.size_px
    f = opt.f_over_w * w
    K = np.array([[f, 0, w / 2 - 0.5 + rng.normal(0, w * 0.004)],
                  [0, f, h / 2 - 0.5 + rng.normal(0, h * 0.004)], [0, 0, 1]])
    lens = Lens(K, np.asarray(opt.dist, float), (w, h))
    (bx, by), (sw, sh) = layout.bottom_left_mm, layout.size_mm
    paper = np.array([[bx, by], [bx + sw, by], [bx + sw, by + sh], [bx, by + sh]])
    centre = np.array([bx + sw / 2, by + sh / 2, 0.0])
    poses, on_sheet = [], []
    if opt.fixed:
        T = view_from(lens, paper, centre + [*rng.uniform(-10, 10, 2), 0], np.mean(opt.tilt_deg),
                      rng.uniform(0, 360), rng.uniform(-4, 4), fill=0.92)
        for k in range(opt.fixed_photos):
            poses.append(T)
            on_sheet.append(int(round(len(marks) * (k + 1) / opt.fixed_photos)))
    else:
        az0 = rng.uniform(0, 360)
        for k in range(opt.views):
            tilt = rng.uniform(*opt.tilt_deg)
            az = az0 + 360 * k / opt.views + rng.uniform(-15, 15)
            poses.append(view_from(lens, paper, centre + [*rng.uniform(-15, 15, 2), 0], tilt, az,
                                   rng.uniform(-6, 6), fill=rng.uniform(0.88, 0.95)))
            on_sheet.append(len(marks))
    d = opt.pen_mm * rng.uniform(0.94, 1.06, len(marks))
    ell = np.column_stack([rng.uniform(0.9, 1.0, len(marks)), rng.uniform(0, np.pi, len(marks))])
    scene = Scene(layout, fld, shape, opt.toner_mm, true_xy, d, ell, opt.texture_px_per_mm)
    return World(opt, layout, robot, nominal, marks, true_xy, s, fld, shape, lens, poses,
                 on_sheet, scene)


def _print_truth(world: World) -> dict:
    L = world.layout
    (bx, by), (sw, sh) = L.bottom_left_mm, L.size_mm
    X, Y = np.meshgrid(np.linspace(bx, bx + sw, 60), np.linspace(by, by + sh, 43))
    out = {"toner_mm": world.opt.toner_mm, "generator": "world2"}
    if world.field is not None:
        dp = world.field(np.column_stack([X.ravel(), Y.ravel()]))
        dc = world.field(L.marker_corners())
        dm = world.field(world.true_xy)
        nrm = lambda d: np.linalg.norm(d, axis=1)      # noqa: E731
        out.update({"rms_mm": float(np.sqrt(np.mean(nrm(dp) ** 2))), "max_mm": float(nrm(dp).max()),
                    "corner_rms_mm": float(np.sqrt(np.mean(nrm(dc) ** 2))),
                    "at_marks_rms_mm": float(np.sqrt(np.mean(nrm(dm) ** 2))),
                    "markers_printed": {str(i): (c + world.field(c)).round(4).tolist()
                                        for i, c in sorted(L.markers.items())}})
    return out


def session_and_truth(world: World, files: list[str]) -> tuple[dict, dict]:
    ids = [m["id"] for m in world.marks]
    session = {"format": "vision-cal/1", "sheet": world.layout.sheet_block(),
               "robot": world.nominal, "pen": {"mark_diameter_mm": world.opt.pen_mm},
               "marks": world.marks,
               "images": [{"file": f, "marks": ids[:n]} for f, n in zip(files, world.on_sheet)]}
    cam = {"size_px": list(world.lens.size_px), "K": world.lens.K.tolist(),
           "dist": world.lens.dist.tolist()}
    if world.opt.declare_lens:
        session["camera"] = cam
    effects = world.robot.truth_effects()
    if not world.opt.declare_lens and np.any(world.lens.dist):
        effects.append({"name": "lens_distortion", "model": "opencv5", "dist": cam["dist"]})
    truth = {"params": world.robot.truth_params(), "effects": effects,
             "marks": {i: world.true_xy[k].round(5).tolist() for k, i in enumerate(ids)},
             "approach": {i: world.true_s[k].astype(int).tolist() for k, i in enumerate(ids)},
             "camera": {**cam, "T_cam_sheet": [T.tolist() for T in world.poses]},
             "print": _print_truth(world), "repeatability_mm": world.opt.repeat_mm,
             "paper_peak_mm": world.opt.paper_peak_mm, "seed": world.opt.seed,
             "generator": "world2"}
    return session, truth


def write_dataset(world: World, folder: str | os.PathLike) -> Path:
    """Photograph the world and write the folder (replaced whole: written beside, renamed)."""
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".world2-", dir=folder.parent))
    rng = np.random.default_rng([77, world.opt.seed])
    ext = "jpg" if world.opt.jpeg_quality else "png"
    files = []
    for k, (T, n) in enumerate(zip(world.poses, world.on_sheet)):
        world.scene.visible = np.arange(len(world.marks)) < n
        light = np.array([rng.uniform(0.85, 1.0), *rng.uniform(-0.12, 0.12, 2), rng.uniform(0.1, 0.3)])
        img = photograph(world.lens, T, world.scene, ss=world.opt.ss, blur_px=world.opt.blur_px,
                         noise=world.opt.noise, rng=rng, light=light,
                         gamma=world.opt.gamma)
        name = f"photo_{k + 1:02d}.{ext}"
        params = [cv2.IMWRITE_JPEG_QUALITY, world.opt.jpeg_quality] if ext == "jpg" else []
        cv2.imwrite(str(tmp / name), img, params)
        files.append(name)
    session, truth = session_and_truth(world, files)
    (tmp / "session.json").write_text(json.dumps(session, indent=1))
    (tmp / "truth.json").write_text(json.dumps(truth, indent=1))
    if folder.exists():
        shutil.rmtree(folder)
    tmp.rename(folder)
    return folder
