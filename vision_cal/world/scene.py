"""Render scenes: a YAML file that describes a synthetic world, read into a frozen ``Scene``.

A scene says what the robot truly is, what the user believes it is, the sheet it draws on,
the plan it follows and how it is photographed. ``vision-cal render SCENE.yaml --out DIR``
turns it into a dataset folder (docs/format.md). Every section and every
field is optional; a missing one takes the default below (the seed's SM5 beside an A2 sheet).
Unknown fields are errors (a typo must not silently fall back to a default). Lengths in mm,
angles in degrees, as in every file.

Sections and fields::

    seed: 1                       # int: one seed drives everything (noise, plan, views)
    robot:
      nominal:                    # what the user knows (written to session.json)
        L1_mm: 350.0
        L2_mm: 260.0
        joint_zero_deg: [0.0, 0.0]
        base_mm: [-400.0, -250.0] # a rough guess, tens of mm off the truth
        home_deg: [0.0, 0.0]      # where the arm starts
      truth:                      # what the robot really is (truth.json only)
        L1_mm: 344.05
        L2_mm: 259.87
        joint_zero_deg: [-2.57, -8.13]
        base_mm: [-420.0, -230.0]
      effects: []                 # format effect dicts: joint_backlash, joint_scale,
                                  # joint_cyclic, sheet_affine, joint_terms (coupling,
                                  # polynomial: {name: joint_terms, joint: 2, terms:
                                  # [{feature: q1, coef: 0.001}]}), drift ({name: drift,
                                  # param: z1_deg | z2_deg | L1_mm | L2_mm | base_x_mm |
                                  # base_y_mm, change: 0.02, shape: linear | warmup,
                                  # tau: 0.2}; see world/truth_model.py)
      repeatability_mm: 0.01      # sigma of the isotropic noise of each mark, per axis
      pen_diameter_mm: 1.2        # nominal diameter of a pen mark (session.json pen)
      controller: smc             # smc (default) | pd: vision_cal.world.simulate runs the plan
                                  # (trajectory, controller, dynamics, gear play = the
                                  # joint_backlash effects) and the pen touches down where
                                  # the joints settle | kinematic: links reach each
                                  # command exactly, from the planned side
    sheet:                        # the printed ArUco sheet (frame S: x right, y up)
      size_mm: [594.0, 420.0]     # A2 landscape
      bottom_left_mm: [-297.0, -210.0]   # paper corner in frame S: origin at the centre
      dictionary: DICT_5X5_100
      marker_mm: 30.0
      grid: [6, 4]                # markers across x, y (spread evenly over the sheet)
      margin_mm: 15.0
      height:                     # the paper is not flat (absent: flat), heights in mm
        bumps: [{centre_mm: [x, y], sigma_mm: 30, height_mm: 0.65}]   # Gaussian bumps
        curls: [{edge: right, height_mm: 1.5, width_mm: 40}]  # left|right|bottom|top
        sag_mm: 0.3               # the middle lower than the edges by this much
        random: {n: 4, height_mm: [0.3, 0.65], sigma_mm: [25, 60], signed: true}
                                  # bumps drawn from the seed (see world/height.py)
      print:                      # printed off the layout (absent: exactly on it)
        deviation_rms_mm: 0.17    # a smooth field in the paper's plane (feed wave, bow,
                                  # skew; no overall shift, turn or scale), its RMS
        toner_mm: 0.06            # the markers' black squares grown this much a side
                                  # (see world/print_deviation.py)
    plan:
      kind: informative           # informative | paper (the seed paper's 5 poses)
      n_calibration: 30
      n_validation: 8
      min_separation_mm: 10.0
    camera:
      size_px: [2400, 1800]
      f_px: 2600.0
      dist: [0, 0, 0, 0, 0]       # true lens, OpenCV k1 k2 p1 p2 k3 (4, 5, 8, 12 or 14
                                  # numbers: + k4 k5 k6, + thin prism s1 s2 s3 s4, + tilt
                                  # tx ty; world.camera.phone_lens builds p and s terms
                                  # from their size in pixels)
      declared: true              # write K and dist into session.json (false: unknown lens)
      n_views: 4                  # distinct camera poses
      tilt_deg: [0.0, 12.0]       # views tilt from looking straight down by an angle
                                  # drawn in [min, max] (a number t means [0, t])
      moving: false               # series: cycle through the views from photo to photo
      fill: 0.96                  # the paper's corners stay inside this central fraction
                                  # of the image (the view aims within (1-fill)/2 of the
                                  # sheet size of its centre)
      principal_px: null          # [u, v] principal point in pixels (null: image centre)
      f_scatter: 0.0              # phones: each photo's focal length is f_px times a
                                  # factor drawn uniformly in [1 - f_scatter, 1 + f_scatter]
                                  # (needs declared: false; the contract has one K)
    photos:
      mode: series                # series: one photo after each mark | single: one photo
                                  # | survey: one photo of the blank sheet (no mark yet)
                                  # from each of camera.n_views places (vision-cal survey)
      texture_px_per_mm: 8.0      # resolution of the rendered sheet texture
      vignetting: 0.15            # 0..1 light fall-off in the corners
      noise_sigma: 1.5            # sensor noise, grey levels
      jpeg_quality: null          # null: PNG; 1..100: JPEG of that quality
      arm_parked: false           # park the arm over the sheet in every third photo
                                  # (and in a single photo)
      extra_files: []             # bad photos added to the dataset, each
                                  # {file: bad.png, kind: blank | noise | corrupt}; listed
                                  # in session.json with all marks, so a calibrator must
                                  # skip them with a reason
    survey:                       # vision-cal loop only (absent: no survey): the blank
                                  # sheet of the same world (seed, print, lens) surveyed
                                  # before the robot draws, as docs/sheet.md asks of a user
      n_views: 6                  # photos, each from another place (3..50)
      tilt_deg: [10.0, 30.0]      # each tilted from straight down by an angle drawn in
                                  # [min, max] (a number t means [0, t]); 0..60

The default robot is the seed's SM5 as measured, placed so that the sheet origin is
comfortably reachable (``|pen - base|`` well inside ``[|L1-L2|, L1+L2]``) and most of
the reachable annulus lies on the sheet.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from vision_cal.dataset.io import read_yaml
from vision_cal.dataset.fields import FieldReader
from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import Effect, effect_from_json
from vision_cal.world.height import HeightScene, height_scene_from_dict
from vision_cal.world.print_deviation import PrintScene
from vision_cal.world.printed import load_printed_sheet
from vision_cal.world.sheet import make_sheet
from vision_cal.world.truth_model import DRIFT_PARAMS, TrueRobot

PLAN_KINDS = ("informative", "paper")
PHOTO_MODES = ("series", "single", "survey")
CONTROLLERS = ("kinematic", "smc", "pd")
EXTRA_KINDS = ("blank", "noise", "corrupt")


@dataclass(frozen=True)
class NominalScene:
    """What the user knows about the robot (session.json ``robot``)."""

    L1_mm: float = 350.0
    L2_mm: float = 260.0
    joint_zero_deg: tuple[float, float] = (0.0, 0.0)
    base_mm: tuple[float, float] = (-400.0, -250.0)
    home_deg: tuple[float, float] = (0.0, 0.0)
    tool_mm: tuple[float, float] | None = None   # the user's rough tool (docs/format.md)

    @property
    def params(self) -> ScaraParams:
        return ScaraParams(self.L1_mm, self.L2_mm, *self.joint_zero_deg, *self.base_mm)

    def to_json(self) -> dict:
        return {"L1_mm": self.L1_mm, "L2_mm": self.L2_mm,
                "joint_zero_deg": list(self.joint_zero_deg), "base_mm": list(self.base_mm),
                "home_deg": list(self.home_deg),
                **({"tool_mm": list(self.tool_mm)} if self.tool_mm is not None else {})}


@dataclass(frozen=True)
class RobotScene:
    nominal: NominalScene = field(default_factory=NominalScene)
    truth: ScaraParams = ScaraParams(344.05, 259.87, -2.57, -8.13, -420.0, -230.0)
    effects: tuple[Effect, ...] = ()
    repeatability_mm: float = 0.01
    pen_diameter_mm: float = 1.2
    controller: str = "smc"
    drift: tuple[dict, ...] = ()   # the world's drift effects (truth.json dicts)
    tool_mm: tuple[float, float] | None = None   # the pen off the joint-4 axis (truth)

    @property
    def true_robot(self):
        """The world's own robot (:mod:`vision_cal.world.truth_model`), built from the
        truth's JSON blocks only."""
        return TrueRobot.from_json(self.truth_params_json,
                                   [e.to_json() for e in self.effects] + list(self.drift))

    @property
    def truth_params_json(self) -> dict:
        """truth.json's ``params`` (with ``tool_mm`` when the pen is off the joint-4 axis)."""
        d = self.truth.to_json()
        if self.tool_mm is not None:
            d["tool_mm"] = [float(v) for v in self.tool_mm]
        return d


@dataclass(frozen=True)
class SheetScene:
    size_mm: tuple[float, float] = (594.0, 420.0)
    bottom_left_mm: tuple[float, float] = (-297.0, -210.0)
    dictionary: str = "DICT_5X5_100"
    marker_mm: float = 30.0
    grid: tuple[int, int] = (6, 4)
    margin_mm: float = 15.0
    height: HeightScene | None = None   # not flat: vision_cal.world.height
    printed: str | None = None   # a vision-cal sheet's sheet.json: photograph its own raster
    print: PrintScene | None = None   # printed off its layout: world.print_deviation


@dataclass(frozen=True)
class PlanScene:
    kind: str = "informative"
    n_calibration: int = 30
    n_validation: int = 8
    min_separation_mm: float = 10.0
    pilot: bool = True  # plan from a pilot calibration (the paper's 5 marks on scrap paper)


@dataclass(frozen=True)
class CameraScene:
    size_px: tuple[int, int] = (2400, 1800)
    f_px: float = 2600.0
    dist: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)   # OpenCV's 4/5/8/12/14 terms
    declared: bool = True
    n_views: int = 4
    tilt_deg: tuple[float, float] = (0.0, 12.0)
    moving: bool = False
    fill: float = 0.96
    principal_px: tuple[float, float] | None = None
    f_scatter: float = 0.0


@dataclass(frozen=True)
class ExtraFile:
    file: str
    kind: str = "blank"


@dataclass(frozen=True)
class PhotosScene:
    mode: str = "series"
    texture_px_per_mm: float = 8.0
    vignetting: float = 0.15
    noise_sigma: float = 1.5
    jpeg_quality: int | None = None
    arm_parked: bool = False
    extra_files: tuple[ExtraFile, ...] = ()


@dataclass(frozen=True)
class SurveyScene:
    """``survey``: the blank sheet photographed from ``n_views`` places, each tilted by an
    angle drawn in ``tilt_deg``, before the robot draws (``vision-cal loop`` surveys it)."""

    n_views: int = 6
    tilt_deg: tuple[float, float] = (10.0, 30.0)


@dataclass(frozen=True)
class Scene:
    """A whole synthetic world (see the module docstring for the YAML layout)."""

    seed: int = 0
    robot: RobotScene = field(default_factory=RobotScene)
    sheet: SheetScene = field(default_factory=SheetScene)
    plan: PlanScene = field(default_factory=PlanScene)
    camera: CameraScene = field(default_factory=CameraScene)
    photos: PhotosScene = field(default_factory=PhotosScene)
    source: str = "<default>"
    survey: SurveyScene | None = None   # the blank sheet surveyed first (vision-cal loop)

    def with_overrides(self, *, seed: int | None = None, mode: str | None = None) -> "Scene":
        """The same scene with a command-line ``--seed`` / ``--mode`` applied."""
        s = self
        if seed is not None:
            s = replace(s, seed=int(seed))
        if mode is not None:
            if mode not in PHOTO_MODES:
                raise VisionCalError(f"expected one of {PHOTO_MODES}, got {mode!r}",
                                     field="--mode")
            s = replace(s, photos=replace(s.photos, mode=mode))
        return s

    def survey_photos(self) -> "Scene":
        """The scene of its ``survey``: the same world (seed, sheet, print, lens) with the
        blank sheet photographed once from each of ``survey.n_views`` places tilted
        ``survey.tilt_deg`` (``photos.mode: survey``), the arm away, no bad files."""
        if self.survey is None:
            raise VisionCalError("the scene has no survey block", file=self.source,
                                 field="survey")
        sv = self.survey
        return replace(self, camera=replace(self.camera, n_views=sv.n_views,
                                            tilt_deg=sv.tilt_deg),
                       photos=replace(self.photos, mode="survey", arm_parked=False,
                                      extra_files=()))


# ---------------------------------------------------------------------------- reading


class _R(FieldReader):
    """The typed reader of session.json (one owner, :class:`vision_cal.dataset.fields.FieldReader`)
    with bounded numbers for scene files; every error names the file and the field."""

    def number(self, v, where: str, *, lo=None, hi=None, lo_open=False) -> float:
        v = super().number(v, where)
        if lo is not None and (v < lo or (lo_open and v == lo)):
            self.fail(where, f"expected a number {'>' if lo_open else '>='} {lo}, got {v:g}")
        if hi is not None and v > hi:
            self.fail(where, f"expected a number <= {hi}, got {v:g}")
        return v

    def vector(self, v, where: str, n: int, **kw) -> tuple[float, ...]:
        if not isinstance(v, (list, tuple)) or len(v) != n:
            self.fail(where, f"expected a list of {n} numbers, got {v!r}")
        return tuple(self.number(x, f"{where}[{i}]", **kw) for i, x in enumerate(v))


def _params(r: _R, d: dict, where: str, default: ScaraParams) -> ScaraParams:
    d = r.section(d, where, ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm"))
    L1 = r.number(d.get("L1_mm", default.L1_mm), f"{where}.L1_mm", lo=0, lo_open=True)
    L2 = r.number(d.get("L2_mm", default.L2_mm), f"{where}.L2_mm", lo=0, lo_open=True)
    z = r.vector(d.get("joint_zero_deg", list(default.joint_zero_deg)),
                 f"{where}.joint_zero_deg", 2)
    b = r.vector(d.get("base_mm", list(default.base_mm)), f"{where}.base_mm", 2)
    return ScaraParams(L1, L2, z[0], z[1], b[0], b[1])


def _robot(r: _R, d) -> RobotScene:
    d = r.section(d, "robot", ("nominal", "truth", "effects", "repeatability_mm",
                               "pen_diameter_mm", "controller", "tool_mm"))
    dflt = RobotScene()
    nd = dflt.nominal
    n = r.section(d.get("nominal"), "robot.nominal",
                  ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm", "home_deg", "tool_mm"))
    home = r.vector(n.get("home_deg", list(nd.home_deg)), "robot.nominal.home_deg", 2)
    p = _params(r, {k: v for k, v in n.items() if k not in ("home_deg", "tool_mm")},
                "robot.nominal", nd.params)
    ntool = (r.vector(n["tool_mm"], "robot.nominal.tool_mm", 2)
             if n.get("tool_mm") is not None else None)
    nominal = NominalScene(p.L1_mm, p.L2_mm, p.joint_zero_deg, p.base_mm, home, ntool)
    truth = _params(r, d.get("truth"), "robot.truth", dflt.truth)
    effects_raw = r.list_(d.get("effects") or [], "robot.effects")
    effects, drift = [], []
    for i, e in enumerate(effects_raw):
        where = f"robot.effects[{i}]"
        if not isinstance(e, dict):
            r.fail(where, f"expected an effect mapping like {{name: joint_backlash, ...}}, "
                          f"got {e!r}")
        if e.get("name") == "drift":
            drift.append(_drift(r, e, where))
            continue
        try:
            effects.append(effect_from_json(e, where=where))
        except VisionCalError as err:
            r.fail(err.field or where, err.reason)
    rep = r.number(d.get("repeatability_mm", dflt.repeatability_mm), "robot.repeatability_mm",
                   lo=0)
    pen = r.number(d.get("pen_diameter_mm", dflt.pen_diameter_mm), "robot.pen_diameter_mm",
                   lo=0, lo_open=True)
    ctrl = r.choice(d.get("controller", dflt.controller), "robot.controller", CONTROLLERS)
    tool = r.vector(d["tool_mm"], "robot.tool_mm", 2) if d.get("tool_mm") is not None else None
    return RobotScene(nominal, truth, tuple(effects), rep, pen, ctrl, tuple(drift), tool)


def _drift(r: _R, e: dict, where: str) -> dict:
    """A world drift effect (world/truth_model.py): one parameter changing with time."""
    e = r.section(e, where, ("name", "param", "change", "shape", "tau"))
    param = r.choice(e.get("param"), f"{where}.param", DRIFT_PARAMS)
    change = r.number(e.get("change"), f"{where}.change", lo=-10, hi=10)
    shape = r.choice(e.get("shape", "linear"), f"{where}.shape", ("linear", "warmup"))
    tau = r.number(e.get("tau", 0.2), f"{where}.tau", lo=0, lo_open=True, hi=10)
    return {"name": "drift", "param": param, "change": change, "shape": shape, "tau": tau}


def _sheet(r: _R, d) -> SheetScene:
    d = r.section(d, "sheet", ("size_mm", "bottom_left_mm", "dictionary", "marker_mm", "grid",
                               "margin_mm", "height", "printed", "print"))
    dflt = SheetScene()
    if d.get("printed") is not None:
        return _printed_sheet(r, d)
    size = r.vector(d.get("size_mm", list(dflt.size_mm)), "sheet.size_mm", 2, lo=0, lo_open=True)
    if "bottom_left_mm" in d:
        bl = r.vector(d["bottom_left_mm"], "sheet.bottom_left_mm", 2)
    elif "size_mm" in d:
        bl = (-size[0] / 2, -size[1] / 2)  # the origin stays at the centre
    else:
        bl = dflt.bottom_left_mm
    dic = d.get("dictionary", dflt.dictionary)
    if not isinstance(dic, str) or not dic.startswith("DICT_"):
        r.fail("sheet.dictionary", f"expected an OpenCV ArUco dictionary name like "
                                   f"DICT_5X5_100, got {dic!r}")
    import cv2  # only to check the name

    if not isinstance(getattr(cv2.aruco, dic, None), int):
        r.fail("sheet.dictionary", f"unknown OpenCV ArUco dictionary {dic!r}")
    marker = r.number(d.get("marker_mm", dflt.marker_mm), "sheet.marker_mm", lo=0, lo_open=True)
    grid_raw = d.get("grid", list(dflt.grid))
    if not isinstance(grid_raw, (list, tuple)) or len(grid_raw) != 2:
        r.fail("sheet.grid", f"expected [columns, rows], got {grid_raw!r}")
    grid = tuple(r.integer(v, f"sheet.grid[{i}]", lo=1) for i, v in enumerate(grid_raw))
    margin = r.number(d.get("margin_mm", dflt.margin_mm), "sheet.margin_mm", lo=0)
    if 2 * margin + marker > min(size):
        r.fail("sheet.marker_mm", f"a {marker:g} mm marker with {margin:g} mm margins does "
                                  f"not fit on a {size[0]:g} x {size[1]:g} mm sheet")

    try:  # the layout's own checks (quiet zones, enough ids in the dictionary)
        make_sheet(size_mm=size, bottom_left_mm=bl, dictionary=dic, marker_mm=marker, grid=grid,
                   margin_mm=margin)
    except VisionCalError as e:
        r.fail(f"sheet.{e.field}" if e.field else "sheet", e.reason)

    height = height_scene_from_dict(r, d.get("height"))
    return SheetScene(size, bl, dic, marker, grid, margin, height,
                      print=_print(r, d.get("print")))


def _print(r: _R, d) -> PrintScene | None:
    """``sheet.print``: the printer's displacement field and toner growth."""
    if d is None:
        return None
    d = r.section(d, "sheet.print", ("deviation_rms_mm", "toner_mm"))
    return PrintScene(r.number(d.get("deviation_rms_mm", 0.0), "sheet.print.deviation_rms_mm",
                               lo=0, hi=5),
                      r.number(d.get("toner_mm", 0.0), "sheet.print.toner_mm", lo=0, hi=1))


def _printed_sheet(r: _R, d) -> SheetScene:
    """``sheet.printed: path/sheet.json`` (relative to the scene file): the sheet written by
    ``vision-cal sheet --png-dpi N``, photographed through its own ``sheet.png`` (whose dpi
    then sets the texture resolution); the analytic layout keys do not apply."""
    other = [k for k in ("size_mm", "bottom_left_mm", "dictionary", "marker_mm", "grid",
                         "margin_mm") if k in d]
    if other:
        r.fail("sheet.printed", f"a printed sheet brings its own layout; remove sheet.{other[0]}")
    raw = d["printed"]
    if not isinstance(raw, str) or not raw:
        r.fail("sheet.printed", f"expected the path of a sheet.json, got {raw!r}")
    path = Path(raw) if Path(raw).is_absolute() else Path(r.file).parent / raw
    try:
        pr = load_printed_sheet(path)
    except VisionCalError as e:
        r.fail("sheet.printed", str(e))

    return SheetScene(pr.sheet.size_mm, pr.sheet.bottom_left_mm, pr.sheet.aruco_dictionary,
                      height=height_scene_from_dict(r, d.get("height")),
                      printed=str(path.absolute()), print=_print(r, d.get("print")))


def _plan(r: _R, d) -> PlanScene:
    d = r.section(d, "plan", ("kind", "n_calibration", "n_validation", "min_separation_mm",
                              "pilot"))
    dflt = PlanScene()
    kind = r.choice(d.get("kind", dflt.kind), "plan.kind", PLAN_KINDS)
    nc = r.integer(d.get("n_calibration", dflt.n_calibration), "plan.n_calibration", lo=1)
    nv = r.integer(d.get("n_validation", dflt.n_validation), "plan.n_validation", lo=0)
    sep = r.number(d.get("min_separation_mm", dflt.min_separation_mm), "plan.min_separation_mm",
                   lo=0)
    pilot = d.get("pilot", dflt.pilot)
    if not isinstance(pilot, bool):
        r.fail("plan.pilot", f"expected true or false, got {pilot!r}")
    return PlanScene(kind, nc, nv, sep, pilot)


def _camera(r: _R, d) -> CameraScene:
    d = r.section(d, "camera", ("size_px", "f_px", "dist", "declared", "n_views", "tilt_deg",
                                "moving", "fill", "principal_px", "f_scatter"))
    dflt = CameraScene()
    size = d.get("size_px", list(dflt.size_px))
    if not isinstance(size, (list, tuple)) or len(size) != 2:
        r.fail("camera.size_px", f"expected [width, height] in pixels, got {size!r}")
    size = tuple(r.integer(v, f"camera.size_px[{i}]", lo=16, hi=16384) for i, v in enumerate(size))
    f = r.number(d.get("f_px", dflt.f_px), "camera.f_px", lo=0, lo_open=True)
    dist_raw = d.get("dist", list(dflt.dist))
    if not isinstance(dist_raw, (list, tuple)) or len(dist_raw) not in (4, 5, 8, 12, 14):
        r.fail("camera.dist", "expected 4, 5, 8, 12 or 14 OpenCV coefficients (k1 k2 p1 p2 "
                              f"k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]), got {dist_raw!r}")
    dist = r.vector(dist_raw, "camera.dist", len(dist_raw))
    declared = r.boolean(d.get("declared", dflt.declared), "camera.declared")
    nv = r.integer(d.get("n_views", dflt.n_views), "camera.n_views", lo=1)
    tilt = _tilt(r, d.get("tilt_deg", list(dflt.tilt_deg)), "camera.tilt_deg")
    moving = r.boolean(d.get("moving", dflt.moving), "camera.moving")
    fill = r.number(d.get("fill", dflt.fill), "camera.fill", lo=0.3, hi=1.0)
    pp = d.get("principal_px")
    if pp is not None:
        pp = r.vector(pp, "camera.principal_px", 2)
        if not (0 <= pp[0] <= size[0] - 1 and 0 <= pp[1] <= size[1] - 1):
            r.fail("camera.principal_px", f"expected a point inside the {size[0]}x{size[1]} "
                                          f"image, got {list(pp)}")
    fs = r.number(d.get("f_scatter", dflt.f_scatter), "camera.f_scatter", lo=0, hi=0.5)
    if fs > 0 and declared:
        r.fail("camera.f_scatter", "a focal length that changes between photos cannot be "
                                   "declared (session.json has one K): set declared: false")
    return CameraScene(size, f, dist, declared, nv, tilt, moving, fill, pp, fs)


def _tilt(r: _R, raw, where: str) -> tuple[float, float]:
    """Views' tilt off straight down: ``[min, max]`` or a number ``t`` (``[0, t]``), deg."""
    if isinstance(raw, (list, tuple)):
        tilt = r.vector(raw, where, 2, lo=0, hi=60)
        if tilt[0] > tilt[1]:
            r.fail(where, f"expected [min, max], got {raw!r}")
        return tilt
    return (0.0, r.number(raw, where, lo=0, hi=60))


def _survey(r: _R, d) -> SurveyScene | None:
    """``survey``: the blank sheet's survey photos (absent or null: no survey)."""
    if d is None:
        return None
    d = r.section(d, "survey", ("n_views", "tilt_deg"))
    dflt = SurveyScene()
    nv = r.integer(d.get("n_views", dflt.n_views), "survey.n_views", lo=3, hi=50)
    return SurveyScene(nv, _tilt(r, d.get("tilt_deg", list(dflt.tilt_deg)), "survey.tilt_deg"))


def _photos(r: _R, d) -> PhotosScene:
    d = r.section(d, "photos", ("mode", "texture_px_per_mm", "vignetting", "noise_sigma",
                                "jpeg_quality", "arm_parked", "extra_files"))
    dflt = PhotosScene()
    mode = r.choice(d.get("mode", dflt.mode), "photos.mode", PHOTO_MODES)
    ppm = r.number(d.get("texture_px_per_mm", dflt.texture_px_per_mm),
                   "photos.texture_px_per_mm", lo=0.5, hi=40)
    vig = r.number(d.get("vignetting", dflt.vignetting), "photos.vignetting", lo=0, hi=1)
    noise = r.number(d.get("noise_sigma", dflt.noise_sigma), "photos.noise_sigma", lo=0, hi=128)
    jq = d.get("jpeg_quality", dflt.jpeg_quality)
    if jq is not None:
        jq = r.integer(jq, "photos.jpeg_quality", lo=1, hi=100)
    parked = r.boolean(d.get("arm_parked", dflt.arm_parked), "photos.arm_parked")
    extra_raw = r.list_(d.get("extra_files") or [], "photos.extra_files")
    extras, names = [], set()
    for i, e in enumerate(extra_raw):
        w = f"photos.extra_files[{i}]"
        e = r.section(e, w, ("file", "kind"))
        name = e.get("file")
        if (not isinstance(name, str) or not name or "/" in name or "\\" in name
                or name.startswith(".") or name in ("session.json", "truth.json")):
            r.fail(f"{w}.file", f"expected a plain file name, got {name!r}")
        if name.startswith("img_") or name in names:
            r.fail(f"{w}.file", f"{name!r} clashes with another image name")
        names.add(name)
        extras.append(ExtraFile(name, r.choice(e.get("kind", "blank"), f"{w}.kind",
                                               EXTRA_KINDS)))
    return PhotosScene(mode, ppm, vig, noise, jq, parked, tuple(extras))


def scene_from_dict(d: dict | None, *, file: str = "<scene>") -> Scene:
    """Validate a parsed YAML tree into a :class:`Scene` (errors name ``file`` and field)."""
    r = _R(file)
    d = r.section(d, "", ("seed", "robot", "sheet", "plan", "camera", "photos", "survey"))
    seed = r.integer(d.get("seed", 0), "seed", lo=0)
    scene = Scene(seed, _robot(r, d.get("robot")), _sheet(r, d.get("sheet")),
                  _plan(r, d.get("plan")), _camera(r, d.get("camera")),
                  _photos(r, d.get("photos")), file, _survey(r, d.get("survey")))
    ppm = scene.photos.texture_px_per_mm
    for axis, size in zip("xy", scene.sheet.size_mm):
        if abs(size * ppm - round(size * ppm)) > 1e-6:
            r.fail("photos.texture_px_per_mm",
                   f"the sheet's {size:g} mm along {axis} is not a whole number of texture "
                   f"pixels at {ppm:g} px/mm")
    return scene


def load_scene(path) -> Scene:
    """Read and validate a scene YAML file."""
    path = Path(path)
    tree = read_yaml(path, what="scene file")
    return scene_from_dict(tree, file=str(path))
