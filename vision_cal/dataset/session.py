"""Reading and validating ``session.json`` (format ``vision-cal/1``).

    session = load_session("run/")            # marks the pen drew, the photos of them
    session = load_arm_session("arm/")        # poses the arm's camera took its photos at

Every malformed input raises :class:`VisionCalError` with one line naming the file, the
field (``marks[3].joints_deg[0]``) and what was expected. Either session lists its photos
in ``images``, which the measurement reads the same way (``measure/listing.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vision_cal.dataset.camera_block import read_lens
from vision_cal.dataset.fields import MAX_JOINT_DEG, MAX_MM, MAX_PEN_MM, FieldReader
from vision_cal.dataset.io import read_json
from vision_cal.dataset.photos import normalise_name
from vision_cal.errors import VisionCalError
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.motion import approach_signs

FORMAT = "vision-cal/1"
ROLES = ("calibration", "validation")


@dataclass(frozen=True)
class SheetMarker:
    id: int
    corners_mm: np.ndarray  # (4, 2): TL, TR, BR, BL of the upright printed marker


@dataclass(frozen=True)
class SheetGrid:
    """The printed plotting grid (``sheet.grid``): lines at ``origin_mm + k * pitch_mm``
    in x and in y; every ``bold_every``-th one (counted from the origin) is bold. Added
    optional fields: ``fine_width_mm`` / ``bold_width_mm`` (line widths) and ``extent_mm``
    ([x0, y0, x1, y1], where the lines are printed; absent: the whole paper)."""

    pitch_mm: float = 1.0
    bold_every: int = 10
    origin_mm: tuple[float, float] = (0.0, 0.0)
    fine_width_mm: float | None = None
    bold_width_mm: float | None = None
    extent_mm: tuple[float, float, float, float] | None = None

    def to_json(self) -> dict:
        d = {"pitch_mm": self.pitch_mm, "bold_every": self.bold_every,
             "origin_mm": list(self.origin_mm)}
        if self.fine_width_mm is not None:
            d["fine_width_mm"] = self.fine_width_mm
        if self.bold_width_mm is not None:
            d["bold_width_mm"] = self.bold_width_mm
        if self.extent_mm is not None:
            d["extent_mm"] = list(self.extent_mm)
        return d


@dataclass(frozen=True)
class Sheet:
    aruco_dictionary: str
    markers: tuple[SheetMarker, ...]
    size_mm: tuple[float, float]
    bottom_left_mm: tuple[float, float] | None = None  # added field: paper corner in frame S
    grid: dict | None = None      # the printed grid as in the file (pitch_mm, origin_mm, ...)
    printed: dict | None = None   # how it was printed (module_mm, quiet_zone_modules, ...)

    def markers_hull_mm(self) -> tuple[float, float, float, float] | None:
        """(x_min, y_min, x_max, y_max) of every printed marker corner, None without markers."""
        if not self.markers:
            return None
        c = np.concatenate([np.asarray(m.corners_mm, float).reshape(-1, 2)
                            for m in self.markers])
        return (float(c[:, 0].min()), float(c[:, 1].min()), float(c[:, 0].max()),
                float(c[:, 1].max()))

    @property
    def grid_spec(self) -> "SheetGrid | None":
        """``grid`` as a typed :class:`SheetGrid` (None when no grid is declared)."""
        return None if self.grid is None else sheet_grid_from_dict(self.grid)

    @property
    def extent_mm(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of what is surely paper in the sheet frame: the
        declared paper (``bottom_left_mm`` + ``size_mm``) with the markers printed on it;
        without ``bottom_left_mm``, the markers' bounding box (the paper is somewhere around
        them, where, the sheet does not say). Nothing else about the frame is assumed."""
        hull = self.markers_hull_mm()
        if self.bottom_left_mm is None:
            if hull is None:
                return (0.0, 0.0, float(self.size_mm[0]), float(self.size_mm[1]))
            return hull
        x0, y0 = self.bottom_left_mm
        box = (x0, y0, x0 + self.size_mm[0], y0 + self.size_mm[1])
        return _union(box, hull)

    @property
    def search_extent_mm(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of where the paper may be (where pen marks are looked
        for): the declared paper, or without ``bottom_left_mm`` every place a paper of
        ``size_mm`` holding all the markers can lie."""
        hull = self.markers_hull_mm()
        if self.bottom_left_mm is not None or hull is None:
            return self.extent_mm
        w, h = self.size_mm
        return _union((hull[2] - w, hull[3] - h, hull[0] + w, hull[1] + h), hull)

    def to_json(self) -> dict:
        out = {"aruco_dictionary": self.aruco_dictionary,
               "markers": [{"id": m.id, "corners_mm": np.asarray(m.corners_mm).tolist()}
                           for m in self.markers],
               "size_mm": list(self.size_mm)}
        if self.bottom_left_mm is not None:
            out["bottom_left_mm"] = list(self.bottom_left_mm)
        if self.grid is not None:
            out["grid"] = self.grid
        if self.printed is not None:
            out["printed"] = self.printed
        return out

    def corners_by_id(self) -> dict[int, np.ndarray]:
        return {m.id: m.corners_mm for m in self.markers}


def _union(a, b):
    """Bounding box of two boxes (x_min, y_min, x_max, y_max); ``b`` may be None."""
    if b is None:
        return tuple(float(v) for v in a)
    return (float(min(a[0], b[0])), float(min(a[1], b[1])), float(max(a[2], b[2])),
            float(max(a[3], b[3])))


@dataclass(frozen=True)
class NominalRobot:
    L1_mm: float
    L2_mm: float
    joint_zero_deg: tuple[float, float]
    base_mm: tuple[float, float]
    home_deg: tuple[float, float] = (0.0, 0.0)
    #: added: the commanded joint limits [[lo, hi], [lo, hi]] (deg), when the block has them
    joint_limits_deg: tuple | None = None
    #: the robot's positioning repeatability (mm, per axis, one std; docs/format.md), None:
    #: not declared (the noise-floor gate then takes DEFAULT_REPEATABILITY_MM)
    repeatability_mm: float | None = None
    tool_mm: tuple[float, float] | None = None   # contract "Joint 4 and the tool" (nominal)
    j4_deg: float | None = None                  # default commanded joint 4 of the marks

    @property
    def params(self) -> ScaraParams:
        return ScaraParams(self.L1_mm, self.L2_mm, self.joint_zero_deg[0], self.joint_zero_deg[1],
                           self.base_mm[0], self.base_mm[1])

    def to_json(self) -> dict:
        """The session's ``robot`` block."""
        d = {"L1_mm": self.L1_mm, "L2_mm": self.L2_mm,
             "joint_zero_deg": list(self.joint_zero_deg), "base_mm": list(self.base_mm),
             "home_deg": list(self.home_deg)}
        if self.joint_limits_deg is not None:
            d["joint_limits_deg"] = [list(p) for p in self.joint_limits_deg]
        if self.repeatability_mm is not None:
            d["repeatability_mm"] = self.repeatability_mm
        if self.tool_mm is not None:
            d["tool_mm"] = list(self.tool_mm)
        if self.j4_deg is not None:
            d["j4_deg"] = self.j4_deg
        return d


@dataclass(frozen=True)
class Mark:
    id: str
    joints_deg: tuple[float, float]
    role: str = "calibration"
    approach: tuple[int, int] | None = None
    target_mm: tuple[float, float] | None = None
    measured_mm: tuple[float, float] | None = None
    j4_deg: float | None = None   # commanded joint 4 (contract "Joint 4 and the tool")
    repeat_of: str | None = None  # the mark whose pose this one returns to (docs/format.md)
    #: the per-axis std (mm) of ``measured_mm``: a stated instrument accuracy (issue 32)
    measured_sigma_mm: float | None = None


@dataclass(frozen=True)
class ImageEntry:
    file: str
    marks: tuple[str, ...]


@dataclass(frozen=True)
class Camera:
    size_px: tuple[int, int]
    K: np.ndarray  # (3, 3)
    dist: np.ndarray  # (n,) OpenCV order k1 k2 p1 p2 [k3 ...]


@dataclass(frozen=True)
class Session:
    """A dataset folder: what a real user knows (nominal model, sheet, plan, photos)."""

    root: Path
    sheet: Sheet | None
    robot: NominalRobot
    marks: tuple[Mark, ...]
    images: tuple[ImageEntry, ...]
    camera: Camera | None = None
    pen_mark_diameter_mm: float | None = None
    raw: dict = field(default_factory=dict, repr=False, compare=False)
    #: False when session.json has no ``images``: every photo in the folder is used and
    #: which marks each shows is found from the photos (``vision_cal.identify.infer``)
    images_listed: bool = True
    #: the file the session was read from when it is not ``root/session.json`` (a marks
    #: CSV, :mod:`vision_cal.dataset.marks_csv`): what errors name
    source: Path | None = field(default=None, compare=False)
    #: a camera on the arm (:func:`load_arm_session`): each photo's command, in the order of
    #: ``images``, and where the camera sits (:data:`CAMERA_MOUNTS`); no marks then
    poses: tuple["Pose", ...] = ()
    camera_mount: str | None = None

    @property
    def path(self) -> Path:
        return self.source if self.source is not None else self.root / "session.json"

    @property
    def design_stage(self) -> str | None:
        """The stage ``vision-cal design`` planned this session for (its ``design.stage``:
        ``pilot``, ``informative``, ``verify``, ...; docs/format.md), None otherwise."""
        d = self.raw.get("design") if isinstance(self.raw, dict) else None
        stage = d.get("stage") if isinstance(d, dict) else None
        return stage if isinstance(stage, str) else None

    def mark_index(self) -> dict[str, int]:
        return {m.id: i for i, m in enumerate(self.marks)}

    @property
    def joints_deg(self) -> np.ndarray:
        """(N, 2) commanded joints of every mark, in drawing order."""
        return np.array([m.joints_deg for m in self.marks], dtype=float).reshape(-1, 2)

    @property
    def approach(self) -> np.ndarray:
        """(N, 2) approach signs of every mark, resolved as the format says."""
        return resolve_approach(self.marks, self.robot.home_deg)

    @property
    def j4_deg(self) -> np.ndarray:
        """(N,) commanded joint 4 of every mark: its ``j4_deg``, else the robot block's,
        else 0 (contract "Joint 4 and the tool")."""
        d = self.robot.j4_deg if self.robot.j4_deg is not None else 0.0
        return np.array([d if m.j4_deg is None else m.j4_deg for m in self.marks], dtype=float)

    @property
    def uses_joint4(self) -> bool:
        """True when the session says anything about joint 4 or the tool."""
        return (self.robot.tool_mm is not None or self.robot.j4_deg is not None
                or any(m.j4_deg is not None for m in self.marks))

    @property
    def approach4(self) -> np.ndarray:
        """(N,) approach sign of joint 4, by the format's rule (joint 4 starts at the robot
        block's ``j4_deg``, else 0)."""
        q4 = self.j4_deg
        start = self.robot.j4_deg if self.robot.j4_deg is not None else 0.0
        return approach_signs(np.column_stack([q4, q4]), (start, start))[:, 0]


def resolve_approach(marks, home_deg=(0.0, 0.0)) -> np.ndarray:
    """Approach signs (N, 2) of ``marks``: given, else the format's rule
    (:func:`vision_cal.model.motion.approach_signs`)."""
    return approach_signs([m.joints_deg for m in marks], home_deg,
                          given=[m.approach for m in marks])


def _aruco_dictionary_ok(name: str) -> bool:
    import cv2  # heavy import, only when a sheet is read

    return name.startswith("DICT_") and isinstance(getattr(cv2.aruco, name, None), int)


def read_robot_block(r: FieldReader, rob, where: str = "robot") -> NominalRobot:
    """The session's ``robot`` block (also the core of a robot file), validated.

    ``where`` is the block's path in its file (``"robot"`` in session.json, ``""`` for a
    robot file whose top level is the block)."""
    def w(key):
        return f"{where}.{key}" if where else key

    if not isinstance(rob, dict):
        r.fail(where or "(top level)", f"expected an object, got {type(rob).__name__}")
    L1 = r.length(r.get(rob, "L1_mm", where), w("L1_mm"), positive=True)
    L2 = r.length(r.get(rob, "L2_mm", where), w("L2_mm"), positive=True)
    jz = r.angles(r.get(rob, "joint_zero_deg", where), w("joint_zero_deg"))
    base = r.point(r.get(rob, "base_mm", where), w("base_mm"))
    home_raw = r.get(rob, "home_deg", where, required=False)
    home = r.angles(home_raw, w("home_deg")) if home_raw is not None else (0.0, 0.0)
    lim_raw = r.get(rob, "joint_limits_deg", where, required=False)
    limits = None
    if lim_raw is not None:   # added field: [[lo, hi], [lo, hi]] deg
        rows = r.list_(lim_raw, w("joint_limits_deg"))
        if len(rows) != 2:
            r.fail(w("joint_limits_deg"), f"expected [[lo, hi], [lo, hi]], got {lim_raw!r}")
        pairs = []
        for j, row in enumerate(rows):
            lo, hi = r.vector(row, w(f"joint_limits_deg[{j}]"), 2)
            if not lo < hi:
                r.fail(w(f"joint_limits_deg[{j}]"), f"expected lo < hi, got {row!r}")
            pairs.append((float(lo), float(hi)))
        limits = tuple(pairs)
    rep_raw = r.get(rob, "repeatability_mm", where, required=False)
    rep = None
    if rep_raw is not None:
        rep = r.length(rep_raw, w("repeatability_mm"))
        if not 0 <= rep <= 10:
            r.fail(w("repeatability_mm"), f"expected 0..10 mm (one std per axis), got {rep:g}")
    tool = r.get(rob, "tool_mm", where, required=False)
    tool = r.point(tool, w("tool_mm")) if tool is not None else None
    j4 = r.get(rob, "j4_deg", where, required=False)
    j4 = r.number(j4, w("j4_deg"), lo=-MAX_JOINT_DEG, hi=MAX_JOINT_DEG) if j4 is not None else None
    return NominalRobot(L1, L2, jz, base, home, limits, rep, tool, j4)


def read_sheet_block(r: FieldReader, sheet_raw, where: str = "sheet", *,
                     need_markers: bool = True) -> Sheet:
    """The session's ``sheet`` block (also a whole ``sheet.json``), validated."""
    def w(key):
        return f"{where}.{key}" if where else key

    if not isinstance(sheet_raw, dict):
        r.fail(where or "(top level)", f"expected an object, got {type(sheet_raw).__name__}")
    d = r.string(r.get(sheet_raw, "aruco_dictionary", where), w("aruco_dictionary"))
    if not _aruco_dictionary_ok(d):
        r.fail(w("aruco_dictionary"),
               f"unknown ArUco dictionary {d!r} (expected an OpenCV name like DICT_5X5_100)")
    size = r.vector(r.get(sheet_raw, "size_mm", where), w("size_mm"), 2, lo=0.0, hi=MAX_MM,
                    positive=True, what="length in mm")
    mk_raw = r.list_(r.get(sheet_raw, "markers", where), w("markers"),
                     nonempty=need_markers)
    mks: list[SheetMarker] = []
    ids_seen: set[int] = set()
    for i, mk in enumerate(mk_raw):
        wm = w(f"markers[{i}]")
        mid = r.get(mk, "id", wm)
        if isinstance(mid, bool) or not isinstance(mid, int) or mid < 0:
            r.fail(f"{wm}.id", f"expected a non-negative integer, got {mid!r}")
        if mid in ids_seen:
            r.fail(f"{wm}.id", f"duplicate marker id {mid}")
        ids_seen.add(mid)
        cs = r.list_(r.get(mk, "corners_mm", wm), f"{wm}.corners_mm")
        if len(cs) != 4:
            r.fail(f"{wm}.corners_mm", f"expected 4 corners, got {len(cs)}")
        c = np.array([r.point(p, f"{wm}.corners_mm[{j}]") for j, p in enumerate(cs)])
        mks.append(SheetMarker(int(mid), c))
    bl_raw = sheet_raw.get("bottom_left_mm")
    bl = r.point(bl_raw, w("bottom_left_mm")) if bl_raw is not None else None
    grid = _optional_object(r, sheet_raw, w("grid"))
    _sheet_grid(r, grid, w("grid"))   # the grid must make sense to be used
    printed = _optional_object(r, sheet_raw, w("printed"))
    if printed is not None:
        for k in ("module_mm", "quiet_zone_mm", "quiet_zone_modules"):
            if k in printed:
                v = r.number(printed[k], w(f"printed.{k}"))
                if v < 0 or (k == "module_mm" and v == 0):
                    r.fail(w(f"printed.{k}"), f"expected a size >= 0 (> 0 for a module), "
                                              f"got {v}")
        mb = printed.get("measured_bar_mm")
        if mb is not None:
            if any(v <= 0 for v in r.vector(mb, w("printed.measured_bar_mm"), 2)):
                r.fail(w("printed.measured_bar_mm"), f"expected two positive lengths, got {mb!r}")
    return Sheet(d, tuple(mks), size, bl, grid, printed)


def _sheet_grid(r: FieldReader, g, where: str = "sheet.grid") -> SheetGrid | None:
    """``sheet.grid`` (optional): pitch, bold_every, origin; line widths and extent added."""
    if g is None:
        return None
    if not isinstance(g, dict):
        r.fail(where, f"expected an object like {{\"pitch_mm\": 1.0, \"bold_every\": "
                             f"10, \"origin_mm\": [x, y]}}, got {g!r}")
    pitch = r.number(r.get(g, "pitch_mm", where), f"{where}.pitch_mm")
    if pitch <= 0:
        r.fail(f"{where}.pitch_mm", f"expected a positive pitch, got {pitch}")
    bold = g.get("bold_every", 10)
    if isinstance(bold, bool) or not isinstance(bold, int) or bold < 1:
        r.fail(f"{where}.bold_every", f"expected a positive integer, got {bold!r}")
    origin = r.vector(g.get("origin_mm", [0.0, 0.0]), f"{where}.origin_mm", 2)
    widths = {}
    for k in ("fine_width_mm", "bold_width_mm"):
        if g.get(k) is not None:
            v = r.number(g[k], f"{where}.{k}")
            if v <= 0 or v >= pitch:
                r.fail(f"{where}.{k}", f"expected a width between 0 and the pitch, got {v}")
            widths[k] = v
    ext = None
    if g.get("extent_mm") is not None:
        ext = r.vector(g["extent_mm"], f"{where}.extent_mm", 4)
        if ext[2] <= ext[0] or ext[3] <= ext[1]:
            r.fail(f"{where}.extent_mm", f"expected [x0, y0, x1, y1] with x1 > x0 and "
                                           f"y1 > y0, got {list(ext)}")
    return SheetGrid(pitch, int(bold), origin, widths.get("fine_width_mm"),
                     widths.get("bold_width_mm"), ext)


def sheet_grid_from_dict(g: dict) -> SheetGrid:
    """A declared grid (already validated by :func:`_sheet_grid`) as a :class:`SheetGrid`."""
    ext = g.get("extent_mm")
    return SheetGrid(float(g["pitch_mm"]), int(g.get("bold_every", 10)),
                     tuple(float(v) for v in g.get("origin_mm", (0.0, 0.0))),
                     g.get("fine_width_mm"), g.get("bold_width_mm"),
                     None if ext is None else tuple(float(v) for v in ext))


def _optional_object(r: FieldReader, obj: dict, where: str) -> dict | None:
    v = obj.get(where.rsplit(".", 1)[-1])
    if v is not None and not isinstance(v, dict):
        r.fail(where, f"expected an object, got {type(v).__name__}")
    return v


def sheet_file_block(path) -> tuple[dict, str]:
    """The raw sheet of a sheet file: ``(block, where)``, ``where`` its field in the file
    (``""``: a ``sheet.json``; ``"sheet"``: a ``session.json``, which carries the sheet it
    was designed on as its sheet block, so that a user who has that file has the sheet)."""
    path = Path(path)
    doc = read_json(path, what="sheet file")
    if (isinstance(doc, dict) and "markers" not in doc and isinstance(doc.get("sheet"), dict)
            and ("marks" in doc or "format" in doc)):
        return doc["sheet"], "sheet"
    return doc, ""


def load_sheet_file(path) -> Sheet:
    """Read and validate a ``sheet.json`` (the session's sheet block on its own), or the
    sheet block of a ``session.json`` (:func:`sheet_file_block`)."""
    block, where = sheet_file_block(path)
    return read_sheet_block(FieldReader(str(path)), block, where)


#: what a folder of photos without session.json needs (one line, issue 30)
MISSING_SESSION = ("missing: a dataset folder needs a session.json (what the robot drew): "
                   "`vision-cal design ... --out PLAN/` writes it; put the photos into PLAN/ "
                   "beside it (`vision-cal init PHOTOS/ --plan PLAN/session.json` shows which "
                   "marks each photo holds)")


def load_session(folder) -> Session:
    """Read and validate ``folder/session.json`` (or a path to the file itself)."""
    folder = Path(folder)
    given_file = folder.name.endswith(".json") or folder.is_file()
    path = folder if given_file else folder / "session.json"
    if given_file:   # the file itself (a PDF or photo given here is named as one on reading)
        folder = folder.parent
    if not path.exists():
        if given_file:
            raise VisionCalError("file not found", file=str(path))
        if not folder.exists():
            raise VisionCalError("folder not found", file=str(folder))
        raise VisionCalError(MISSING_SESSION, file=str(path))
    return session_from_raw(read_json(path, what="session"), folder, str(path))


def session_from_raw(raw: dict, folder, where: str) -> Session:
    """A session from its JSON (``where`` names it in errors): what :func:`load_session`
    reads, and what a marks CSV becomes (:mod:`vision_cal.dataset.marks_csv`)."""
    folder = Path(folder)
    r = FieldReader(where)

    fmt = r.get(raw, "format", "")
    if fmt != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {fmt!r}")
    robot = read_robot_block(r, r.get(raw, "robot", ""), "robot")
    marks = _read_marks(r, raw)
    _check_repeats(r, marks)

    # images (absent: every photo in the folder, marks found from the photos)
    images_listed = "images" in raw
    images = _read_images(r, raw, {m.id for m in marks})
    if images_listed and not images and any(m.measured_mm is None for m in marks):
        missing = next(m.id for m in marks if m.measured_mm is None)
        r.fail("images", f"no images, and mark {missing!r} has no measured_mm: "
                         "nothing to measure it from")
    needs_photos = bool(images) or (not images_listed
                                    and any(m.measured_mm is None for m in marks))

    sheet = None
    sheet_raw = raw.get("sheet")
    if sheet_raw is None:
        if needs_photos:
            r.fail("sheet", "missing required field (photos need the printed ArUco grid)")
    else:
        sheet = read_sheet_block(r, sheet_raw, "sheet", need_markers=needs_photos)

    camera = _read_camera(r, raw["camera"]) if raw.get("camera") is not None else None
    pen = raw.get("pen")
    dia = None
    if pen is not None:
        v = r.get(pen, "mark_diameter_mm", "pen", required=False)
        dia = (r.number(v, "pen.mark_diameter_mm", lo=0.0, hi=MAX_PEN_MM, positive=True,
                        what="diameter in mm") if v is not None else None)

    source = None if Path(where).name == "session.json" else Path(where)
    return Session(folder, sheet, robot, tuple(marks), tuple(images), camera, dia, raw,
                   images_listed, source)


def _read_marks(r: FieldReader, raw: dict) -> list[Mark]:
    """The ``marks`` list (non-empty, ids unique), each mark's fields checked."""
    marks_raw = r.list_(r.get(raw, "marks", ""), "marks", nonempty=True)
    marks: list[Mark] = []
    seen: set[str] = set()
    for i, m in enumerate(marks_raw):
        w = f"marks[{i}]"
        mid = r.string(r.get(m, "id", w), f"{w}.id")
        if mid in seen:
            r.fail(f"{w}.id", f"duplicate mark id {mid!r}")
        seen.add(mid)
        q = r.angles(r.get(m, "joints_deg", w), f"{w}.joints_deg")
        role = m.get("role", "calibration")
        if role not in ROLES:
            r.fail(f"{w}.role", f"expected one of {ROLES}, got {role!r}")
        appr = m.get("approach")
        if appr is not None:
            a = r.vector(appr, f"{w}.approach", 2)
            if any(x not in (1.0, -1.0) for x in a):
                r.fail(f"{w}.approach", f"expected [+1 or -1, +1 or -1], got {appr!r}")
            appr = (int(a[0]), int(a[1]))
        tgt = m.get("target_mm")
        tgt = r.point(tgt, f"{w}.target_mm") if tgt is not None else None
        meas = m.get("measured_mm")
        meas = r.point(meas, f"{w}.measured_mm") if meas is not None else None
        j4 = m.get("j4_deg")
        j4 = r.number(j4, f"{w}.j4_deg", lo=-MAX_JOINT_DEG, hi=MAX_JOINT_DEG) \
            if j4 is not None else None
        rep = m.get("repeat_of")
        rep = r.string(rep, f"{w}.repeat_of") if rep is not None else None
        msig = m.get("measured_sigma_mm")
        if msig is not None:
            if meas is None:
                r.fail(f"{w}.measured_sigma_mm", "given without measured_mm")
            msig = r.number(msig, f"{w}.measured_sigma_mm", lo=0.0, hi=MAX_PEN_MM,
                            positive=True, what="std in mm")
        marks.append(Mark(mid, q, role, appr, tgt, meas, j4, rep, msig))
    return marks


def _check_repeats(r: FieldReader, marks: list[Mark]) -> None:
    """A repeat returns to another mark's pose, from the same side; refuses any other."""
    by_id = {mk.id: mk for mk in marks}
    for i, mk in enumerate(marks):
        if mk.repeat_of is None:
            continue
        twin = by_id.get(mk.repeat_of)
        if twin is None or twin.id == mk.id:
            r.fail(f"marks[{i}].repeat_of", f"names {mk.repeat_of!r}, which is not another mark")
        if mk.approach != twin.approach:
            r.fail(f"marks[{i}].repeat_of", f"{mk.id!r} approaches from {mk.approach}, its twin "
                                            f"{twin.id!r} from {twin.approach}: a repeat comes "
                                            "from the same side")


def _read_images(r: FieldReader, raw: dict, mark_ids: set[str]) -> list[ImageEntry]:
    """The ``images`` list (empty when absent): file names normalised and unique, each
    image's marks among ``mark_ids``."""
    imgs_raw = r.list_(raw.get("images", []), "images")
    images: list[ImageEntry] = []
    files: dict[str, int] = {}
    for i, im in enumerate(imgs_raw):
        w = f"images[{i}]"
        given = r.string(r.get(im, "file", w), f"{w}.file")
        try:
            f = normalise_name(given)
        except ValueError as e:
            r.fail(f"{w}.file", str(e))
        if f in files:
            j = files[f]
            also = "" if imgs_raw[j].get("file") == given else \
                f" (images[{j}].file names it as {imgs_raw[j].get('file')!r})"
            r.fail(f"{w}.file", f"duplicate image file {given!r}{also}")
        files[f] = i
        ids = r.list_(r.get(im, "marks", w), f"{w}.marks")
        for j, mid in enumerate(ids):
            r.string(mid, f"{w}.marks[{j}]")
            if mid not in mark_ids:
                r.fail(f"{w}.marks[{j}]", f"names mark {mid!r}, which is not in marks")
        images.append(ImageEntry(f, tuple(ids)))
    return images


def _read_camera(r: FieldReader, cam) -> Camera:
    """The ``camera`` block: whole-pixel image size, an OpenCV camera matrix with positive
    focal lengths, 4 to 14 distortion coefficients (the one lens reader,
    :func:`vision_cal.dataset.camera_block.read_lens`)."""
    size, K, dist = read_lens(r, cam, "camera", principal_inside=False)
    return Camera(size, K, dist)


# --------------------------------------------------------------------------- a camera on the arm

#: where the arm's camera sits (session.json ``camera_mount``): on the flange, turning with
#: joint 4, or on link 2
CAMERA_MOUNTS = ("flange", "link2")
#: more photos than this a user could not mean (a typo, a generated list): refused before
#: anything is measured (each photo takes about a second to measure; 500 is several times
#: what the fit needs; issue 30, docs/format.md "Cameras")
MAX_POSES = 500


@dataclass(frozen=True)
class Pose:
    """A photo the arm's camera took: ``image`` (its path in the folder), the commanded
    ``joints_deg`` (q1, q2) and ``j4_deg``, and each joint's ``approach`` sign (the format's
    rule over the poses in order, from the robot's home)."""

    image: str
    joints_deg: tuple[float, float]
    j4_deg: float
    approach: tuple[float, float]


def load_arm_session(folder) -> Session:
    """The photos of a camera on the arm and the commands they were taken at.

        session = load_arm_session("arm/")    # session.poses[0].joints_deg, .camera_mount

    session.json (``docs/format.md``, "Cameras"): ``poses`` (each photo and its command),
    ``camera_mount``, the lens when declared, the ``sheet`` (its marker field) and
    ``robot`` blocks; every field checked, one line naming it. The photos are the
    session's ``images`` (no marks), in the poses' order, so the measurement lists, checks
    and detects them as any session's."""
    folder = Path(folder)
    path = folder / "session.json"
    if folder.is_dir() and not path.exists():
        raise VisionCalError("missing: a camera-on-arm folder needs a session.json (the poses "
                             "the photos were taken at): `vision-cal design --camera-on-arm` "
                             "writes it", file=str(path))
    raw = read_json(path)
    r = FieldReader(str(path))
    fmt = r.get(raw, "format", "")
    if fmt != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {fmt!r}")
    robot = read_robot_block(r, r.get(raw, "robot", ""), "robot")
    sheet = read_sheet_block(r, r.get(raw, "sheet", ""), "sheet")
    cam = raw.get("camera")
    camera = None if cam is None else Camera(*read_lens(r, cam, "camera"))
    mount = raw.get("camera_mount", "flange")
    if mount not in CAMERA_MOUNTS:
        r.fail("camera_mount", f"expected one of {', '.join(CAMERA_MOUNTS)}, got {mount!r}")
    poses = _read_poses(r, raw, mount)
    signs = approach_signs([q for _, q, _ in poses], robot.home_deg)
    poses = tuple(Pose(img, (float(q[0]), float(q[1])), j4, (float(s[0]), float(s[1])))
                  for (img, q, j4), s in zip(poses, signs))
    return Session(folder, sheet, robot, (), tuple(ImageEntry(p.image, ()) for p in poses),
                   camera, None, raw, True, None, poses, mount)


def _read_poses(r: FieldReader, raw: dict, mount: str) -> list[tuple[str, np.ndarray, float]]:
    """The ``poses`` list (non-empty, at most :data:`MAX_POSES`): (image, q (2,), j4)."""
    poses = []
    listed = r.list_(r.get(raw, "poses", ""), "poses", nonempty=True)
    if len(listed) > MAX_POSES:
        r.fail("poses", f"{len(listed)} poses: at most {MAX_POSES} (more adds nothing the fit "
                        "can use, and measuring them would take hours); keep a subset")
    for i, p in enumerate(listed):
        w = f"poses[{i}]"
        try:
            img = normalise_name(r.string(r.get(p, "image", w), f"{w}.image"))
        except ValueError as e:
            r.fail(f"{w}.image", f"{e}: the photos sit in the folder beside session.json")
        q = r.angles(r.get(p, "joints_deg", w), f"{w}.joints_deg")
        j4 = r.number(p.get("j4_deg", 0.0), f"{w}.j4_deg")
        if mount == "link2" and j4 != 0.0:
            r.fail(f"{w}.j4_deg", "a camera on link 2 does not turn with joint 4: leave "
                                  "j4_deg out or set camera_mount: flange")
        poses.append((img, np.asarray(q, float), float(j4)))
    return poses
