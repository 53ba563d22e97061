"""Reading and validating ``session.json`` (format ``vision-cal/1``).

Every malformed input raises :class:`VisionCalError` with one line naming the file, the
field (``marks[3].joints_deg[0]``) and what was expected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vision_cal.dataset.io import read_json
from vision_cal.errors import VisionCalError
from vision_cal.kinematics import ScaraParams

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
    bottom_left_mm: tuple[float, float] = (0.0, 0.0)  # added field: paper corner in frame S
    grid: SheetGrid | None = None                      # the printed grid, when declared

    @property
    def extent_mm(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of the paper in the sheet frame."""
        x0, y0 = self.bottom_left_mm
        return (x0, y0, x0 + self.size_mm[0], y0 + self.size_mm[1])

    def to_json(self) -> dict:
        return {"aruco_dictionary": self.aruco_dictionary,
                "markers": [{"id": m.id, "corners_mm": np.asarray(m.corners_mm).tolist()}
                            for m in self.markers],
                "size_mm": list(self.size_mm), "bottom_left_mm": list(self.bottom_left_mm),
                **({"grid": self.grid.to_json()} if self.grid is not None else {})}

    def corners_by_id(self) -> dict[int, np.ndarray]:
        return {m.id: m.corners_mm for m in self.markers}


@dataclass(frozen=True)
class NominalRobot:
    L1_mm: float
    L2_mm: float
    joint_zero_deg: tuple[float, float]
    base_mm: tuple[float, float]
    home_deg: tuple[float, float] = (0.0, 0.0)

    @property
    def params(self) -> ScaraParams:
        return ScaraParams(self.L1_mm, self.L2_mm, self.joint_zero_deg[0], self.joint_zero_deg[1],
                           self.base_mm[0], self.base_mm[1])


@dataclass(frozen=True)
class Mark:
    id: str
    joints_deg: tuple[float, float]
    role: str = "calibration"
    approach: tuple[int, int] | None = None
    target_mm: tuple[float, float] | None = None
    measured_mm: tuple[float, float] | None = None


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

    @property
    def path(self) -> Path:
        return self.root / "session.json"

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


def resolve_approach(marks, home_deg=(0.0, 0.0)) -> np.ndarray:
    """Approach signs (N, 2): given, else the sign of the change from the previous pose.

    A joint that did not move keeps its previous sign, starting at +1.
    """
    prev = np.asarray(home_deg, dtype=float)
    sign = np.ones(2)
    out = np.empty((len(marks), 2))
    for i, m in enumerate(marks):
        q = np.asarray(m.joints_deg, dtype=float)
        moved = np.sign(q - prev)
        sign = np.where(moved != 0, moved, sign)
        if m.approach is not None:
            sign = np.asarray(m.approach, dtype=float)
        out[i] = sign
        prev = q
    return out


class _Reader:
    """Typed field access that names the file and the field in every error."""

    def __init__(self, file: str):
        self.file = file

    def fail(self, where: str, msg: str):
        raise VisionCalError(msg, file=self.file, field=where)

    def get(self, obj: dict, key: str, where: str, *, required=True):
        if not isinstance(obj, dict):
            self.fail(where, f"expected an object, got {type(obj).__name__}")
        if key not in obj:
            if required:
                self.fail(f"{where}.{key}" if where else key, "missing required field")
            return None
        return obj[key]

    def number(self, v, where: str) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(where, f"expected a number, got {type(v).__name__} {v!r}")
        if not math.isfinite(v):
            self.fail(where, f"expected a finite number, got {v!r}")
        return float(v)

    def vector(self, v, where: str, n: int) -> tuple[float, ...]:
        if not isinstance(v, list) or len(v) != n:
            self.fail(where, f"expected a list of {n} numbers, got {v!r}")
        return tuple(self.number(x, f"{where}[{i}]") for i, x in enumerate(v))

    def string(self, v, where: str) -> str:
        if not isinstance(v, str) or not v:
            self.fail(where, f"expected a non-empty string, got {v!r}")
        return v

    def list_(self, v, where: str, *, nonempty=False) -> list:
        if not isinstance(v, list):
            self.fail(where, f"expected a list, got {type(v).__name__}")
        if nonempty and not v:
            self.fail(where, "expected a non-empty list")
        return v


def _aruco_dictionary_ok(name: str) -> bool:
    import cv2  # heavy import, only when a sheet is read

    return name.startswith("DICT_") and isinstance(getattr(cv2.aruco, name, None), int)


def _sheet_grid(r: "_Reader", g) -> SheetGrid | None:
    """``sheet.grid`` (optional): pitch, bold_every, origin; line widths and extent added."""
    if g is None:
        return None
    if not isinstance(g, dict):
        r.fail("sheet.grid", f"expected an object like {{\"pitch_mm\": 1.0, \"bold_every\": "
                             f"10, \"origin_mm\": [x, y]}}, got {g!r}")
    pitch = r.number(r.get(g, "pitch_mm", "sheet.grid"), "sheet.grid.pitch_mm")
    if pitch <= 0:
        r.fail("sheet.grid.pitch_mm", f"expected a positive pitch, got {pitch}")
    bold = g.get("bold_every", 10)
    if isinstance(bold, bool) or not isinstance(bold, int) or bold < 1:
        r.fail("sheet.grid.bold_every", f"expected a positive integer, got {bold!r}")
    origin = r.vector(g.get("origin_mm", [0.0, 0.0]), "sheet.grid.origin_mm", 2)
    widths = {}
    for k in ("fine_width_mm", "bold_width_mm"):
        if g.get(k) is not None:
            v = r.number(g[k], f"sheet.grid.{k}")
            if v <= 0 or v >= pitch:
                r.fail(f"sheet.grid.{k}", f"expected a width between 0 and the pitch, got {v}")
            widths[k] = v
    ext = None
    if g.get("extent_mm") is not None:
        ext = r.vector(g["extent_mm"], "sheet.grid.extent_mm", 4)
        if ext[2] <= ext[0] or ext[3] <= ext[1]:
            r.fail("sheet.grid.extent_mm", f"expected [x0, y0, x1, y1] with x1 > x0 and "
                                           f"y1 > y0, got {list(ext)}")
    return SheetGrid(pitch, int(bold), origin, widths.get("fine_width_mm"),
                     widths.get("bold_width_mm"), ext)


def load_session(folder) -> Session:
    """Read and validate ``folder/session.json`` (or a path to the file itself)."""
    folder = Path(folder)
    path = folder if folder.name.endswith(".json") else folder / "session.json"
    if folder.name.endswith(".json"):
        folder = folder.parent
    if not path.exists():
        if not folder.exists():
            raise VisionCalError("folder not found", file=str(folder))
        raise VisionCalError("missing: a dataset folder needs a session.json", file=str(path))
    raw = read_json(path)
    r = _Reader(str(path))

    fmt = r.get(raw, "format", "")
    if fmt != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {fmt!r}")

    # robot
    rob = r.get(raw, "robot", "")
    L1 = r.number(r.get(rob, "L1_mm", "robot"), "robot.L1_mm")
    L2 = r.number(r.get(rob, "L2_mm", "robot"), "robot.L2_mm")
    for k, v in (("L1_mm", L1), ("L2_mm", L2)):
        if v <= 0:
            r.fail(f"robot.{k}", f"expected a positive length, got {v}")
    jz = r.vector(r.get(rob, "joint_zero_deg", "robot"), "robot.joint_zero_deg", 2)
    base = r.vector(r.get(rob, "base_mm", "robot"), "robot.base_mm", 2)
    home_raw = r.get(rob, "home_deg", "robot", required=False)
    home = r.vector(home_raw, "robot.home_deg", 2) if home_raw is not None else (0.0, 0.0)
    robot = NominalRobot(L1, L2, jz, base, home)

    # marks
    marks_raw = r.list_(r.get(raw, "marks", ""), "marks", nonempty=True)
    marks: list[Mark] = []
    seen: set[str] = set()
    for i, m in enumerate(marks_raw):
        w = f"marks[{i}]"
        mid = r.string(r.get(m, "id", w), f"{w}.id")
        if mid in seen:
            r.fail(f"{w}.id", f"duplicate mark id {mid!r}")
        seen.add(mid)
        q = r.vector(r.get(m, "joints_deg", w), f"{w}.joints_deg", 2)
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
        tgt = r.vector(tgt, f"{w}.target_mm", 2) if tgt is not None else None
        meas = m.get("measured_mm")
        meas = r.vector(meas, f"{w}.measured_mm", 2) if meas is not None else None
        marks.append(Mark(mid, q, role, appr, tgt, meas))

    # images
    imgs_raw = raw.get("images", [])
    imgs_raw = r.list_(imgs_raw, "images")
    images: list[ImageEntry] = []
    files: set[str] = set()
    for i, im in enumerate(imgs_raw):
        w = f"images[{i}]"
        f = r.string(r.get(im, "file", w), f"{w}.file")
        if Path(f).is_absolute() or ".." in Path(f).parts:
            r.fail(f"{w}.file", f"expected a file name inside the dataset folder, got {f!r}")
        if f in files:
            r.fail(f"{w}.file", f"duplicate image file {f!r}")
        files.add(f)
        ids = r.list_(r.get(im, "marks", w), f"{w}.marks")
        for j, mid in enumerate(ids):
            r.string(mid, f"{w}.marks[{j}]")
            if mid not in seen:
                r.fail(f"{w}.marks[{j}]", f"names mark {mid!r}, which is not in marks")
        images.append(ImageEntry(f, tuple(ids)))
    if not images and any(m.measured_mm is None for m in marks):
        missing = next(m.id for m in marks if m.measured_mm is None)
        r.fail("images", f"no images, and mark {missing!r} has no measured_mm: "
                         "nothing to measure it from")

    # sheet
    sheet = None
    sheet_raw = raw.get("sheet")
    if sheet_raw is None:
        if images:
            r.fail("sheet", "missing required field (images need the printed ArUco grid)")
    else:
        d = r.string(r.get(sheet_raw, "aruco_dictionary", "sheet"), "sheet.aruco_dictionary")
        if not _aruco_dictionary_ok(d):
            r.fail("sheet.aruco_dictionary",
                   f"unknown ArUco dictionary {d!r} (expected an OpenCV name like DICT_5X5_100)")
        size = r.vector(r.get(sheet_raw, "size_mm", "sheet"), "sheet.size_mm", 2)
        mk_raw = r.list_(r.get(sheet_raw, "markers", "sheet"), "sheet.markers",
                         nonempty=bool(images))
        mks: list[SheetMarker] = []
        ids_seen: set[int] = set()
        for i, mk in enumerate(mk_raw):
            w = f"sheet.markers[{i}]"
            mid = r.get(mk, "id", w)
            if isinstance(mid, bool) or not isinstance(mid, int) or mid < 0:
                r.fail(f"{w}.id", f"expected a non-negative integer, got {mid!r}")
            if mid in ids_seen:
                r.fail(f"{w}.id", f"duplicate marker id {mid}")
            ids_seen.add(mid)
            cs = r.list_(r.get(mk, "corners_mm", w), f"{w}.corners_mm")
            if len(cs) != 4:
                r.fail(f"{w}.corners_mm", f"expected 4 corners, got {len(cs)}")
            c = np.array([r.vector(p, f"{w}.corners_mm[{j}]", 2) for j, p in enumerate(cs)])
            mks.append(SheetMarker(int(mid), c))
        bl_raw = sheet_raw.get("bottom_left_mm")
        bl = r.vector(bl_raw, "sheet.bottom_left_mm", 2) if bl_raw is not None else (0.0, 0.0)
        grid = _sheet_grid(r, sheet_raw.get("grid"))
        sheet = Sheet(d, tuple(mks), size, bl, grid)

    # camera
    camera = None
    cam = raw.get("camera")
    if cam is not None:
        size_px = r.vector(r.get(cam, "size_px", "camera"), "camera.size_px", 2)
        K_raw = r.list_(r.get(cam, "K", "camera"), "camera.K")
        if len(K_raw) != 3:
            r.fail("camera.K", "expected a 3x3 matrix")
        K = np.array([r.vector(row, f"camera.K[{i}]", 3) for i, row in enumerate(K_raw)])
        dist_raw = r.list_(r.get(cam, "dist", "camera"), "camera.dist")
        if len(dist_raw) not in (4, 5, 8, 12, 14):
            r.fail("camera.dist", f"expected 4, 5, 8, 12 or 14 OpenCV coefficients, got {len(dist_raw)}")
        dist = np.array([r.number(x, f"camera.dist[{i}]") for i, x in enumerate(dist_raw)])
        camera = Camera((int(size_px[0]), int(size_px[1])), K, dist)

    pen = raw.get("pen")
    dia = None
    if pen is not None:
        v = r.get(pen, "mark_diameter_mm", "pen", required=False)
        dia = r.number(v, "pen.mark_diameter_mm") if v is not None else None

    return Session(folder, sheet, robot, tuple(marks), tuple(images), camera, dia, raw)
