"""Rehearse the job without a robot: a simulated robot draws a planned session and is photographed.

``vision-cal simulate PLAN_DIR --truth TRUE_ROBOT.yaml --out PHOTOS/`` stands in for the
robot's part of the README walkthrough (draw the program, photograph the sheet):

- the **simulated robot** is the user's robot file plus what the real robot hides: offsets
  of the link lengths, joint zeros and base from the robot file's values, the format's
  effects (backlash, gear scale, cyclic errors, sheet affine), the repeatability and the
  controller; its own keys, read here (:func:`load_simulated_robot`, see
  ``vision_cal/templates/simulated_robot.yaml``);
- it follows the **robot program** in PLAN_DIR (``program.prg``, SPEL+, or
  ``program_points.csv``) as a controller would: every ``Go``, with the pen down where
  joint 3 goes to the pen-down height (the marks are matched in order to session.json's
  marks), joint 4 where the program turns it (the robot file's ``tool_mm`` turns with it);
  a statement it does not know, a point beyond the robot file's joint limits, a folder
  without a program and targets whose ids are not the plan's are refused (the rehearsal
  runs what the robot will run, or nothing);
- the **sheet** is the printed one: its raster is rebuilt from the session's sheet block
  (``vision_cal.sheet.rebuild``: the same layout ``vision-cal sheet`` printed, checked by
  its ``sheet_id``), so no ``sheet.png`` is needed; marks drawn before on the same sheet
  (the pilot under the informative plan) come from the earlier folder's ``truth.json``
  (``--after``);
- the **photos**: ``camera.photos`` views of the finished sheet from above (pyrender, as
  ``vision-cal render``), written as ``IMG_0001.png`` ... with ``truth.json`` (where each
  mark really is, the true robot, each photo's pose) into PHOTOS/ (and a copy of
  session.json, without an images list, when PHOTOS/ is not PLAN_DIR).

Everything is computed and rendered in memory before anything is written; each file is
written atomically and ``truth.json`` last.

This module is the synthetic world's: it uses the world's own true robot
(:mod:`vision_cal.world.truth_model`) and simulator, never the estimator's model.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from vision_cal.dataset.csvio import read_plan, read_rows, read_targets
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import (atomic_write_bytes, atomic_write_json, read_json, read_text,
                                   read_yaml)
from vision_cal.dataset.photos import list_photos
from vision_cal.dataset.robot import load_robot_file
from vision_cal.dataset.session import read_sheet_block, sheet_file_block
from vision_cal.errors import VisionCalError
from vision_cal.progress import bar as progress_bar
from vision_cal.world.arm_camera import T_flange_camera_true, photograph_poses
from vision_cal.world.camera import camera_matrix, default_views
from vision_cal.world.dataset import encode_image, marks_off_paper, marks_on_markers
from vision_cal.world.photo import Photographer
from vision_cal.world.print_deviation import PrintScene
from vision_cal.world.printed import PrintedSheet, printed_texture
from vision_cal.world.truth_model import TrueRobot
from vision_cal.world.drawing import draw_marks, simulated_world
from vision_cal.sheet.png import rasterise
from vision_cal.sheet.rebuild import layout_from_sheet_json

CONTROLLERS = ("smc", "pd", "kinematic")
SECTIONS = ("robot", "hidden", "camera", "print", "seed")
HIDDEN = ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm", "tool_mm", "effects",
          "repeatability_mm", "controller")
CAMERA = ("size_px", "f_px", "photos", "tilt_deg", "vignetting", "noise_sigma", "fixed")
#: the programs a designed folder may hold, in the order they are looked for
PROGRAMS = ("program.prg", "program_points.csv")
#: the blank sheet photographed for a survey (``simulate SHEET.json``): how many photos
#: when ``--photos`` is not given, and their tilt off the vertical (deg), as docs/sheet.md
#: asks of a phone: 6-10 photos from several places, tilted 10-30 deg
SURVEY_PHOTOS = 8
SURVEY_TILT_DEG = (10.0, 30.0)


@dataclass(frozen=True)
class SimCamera:
    size_px: tuple[int, int] = (1600, 1200)
    f_px: float = 1750.0
    photos: int = 2
    tilt_deg: tuple[float, float] = (0.0, 12.0)
    vignetting: float = 0.15
    noise_sigma: float = 1.5
    fixed: bool = False             # every photo from the first view: a still camera


@dataclass(frozen=True)
class SimulatedRobot:
    """The robot file (``robot``: a ``RobotFile``) and what the real robot hides.

    ``truth``: the world's true robot (params = robot file + offsets, effects);
    ``effects``: the format effect dicts (truth.json); ``repeatability_mm`` per axis;
    ``controller``: smc | pd | kinematic; ``camera``; ``seed`` (None: fresh every run);
    ``print``: the printer's deviation of the sheet from its layout
    (:class:`vision_cal.world.print_deviation.PrintScene`; exact when absent), its field
    drawn from the sheet's id so that every photo of one sheet (the blank one surveyed,
    the pilot's, the plan's) shows the same print.
    """

    path: Path
    robot: object
    truth: TrueRobot
    params: dict
    effects: tuple
    repeatability_mm: float
    controller: str
    camera: SimCamera
    seed: int | None
    print: PrintScene = PrintScene()


def load_simulated_robot(path) -> SimulatedRobot:
    """Read a simulated robot file (YAML; the template: ``vision-cal robot-template
    --simulated``). Unknown keys are errors (a typo must not fall back to a default)."""
    path = Path(path)
    tree = read_yaml(path, what="simulated robot file")
    r = FieldReader(str(path))
    if isinstance(tree, dict) and "hidden" not in tree and not isinstance(tree.get("robot"), str):
        r.fail("", "is a robot file, not a simulated robot: write one that names it with "
                   "`vision-cal robot-template --simulated -o true_robot.yaml` and pass that")
    tree = r.section(tree, "", SECTIONS)
    robot_ref = r.string(r.get(tree, "robot", ""), "robot")
    robot_path = (path.parent / robot_ref) if not Path(robot_ref).is_absolute() else Path(robot_ref)
    robot = load_robot_file(robot_path)
    n = robot.nominal
    h = r.section(tree.get("hidden"), "hidden", HIDDEN)
    dz = r.vector(h.get("joint_zero_deg", [0.0, 0.0]), "hidden.joint_zero_deg", 2, lo=-90, hi=90)
    db = r.vector(h.get("base_mm", [0.0, 0.0]), "hidden.base_mm", 2, lo=-1000, hi=1000)
    dl1 = r.number(h.get("L1_mm", 0.0), "hidden.L1_mm", lo=-100, hi=100)
    dl2 = r.number(h.get("L2_mm", 0.0), "hidden.L2_mm", lo=-100, hi=100)
    dt = r.vector(h.get("tool_mm", [0.0, 0.0]), "hidden.tool_mm", 2, lo=-100, hi=100)
    tool = n.tool_mm if n.tool_mm is not None else (0.0, 0.0)
    params = {"L1_mm": n.L1_mm + dl1, "L2_mm": n.L2_mm + dl2,
              "joint_zero_deg": [n.joint_zero_deg[0] + dz[0], n.joint_zero_deg[1] + dz[1]],
              "base_mm": [n.base_mm[0] + db[0], n.base_mm[1] + db[1]],
              # the pen in the flange frame: the robot file's tool (its joint 4 turns it)
              "tool_mm": [tool[0] + dt[0], tool[1] + dt[1]]}
    if not (params["L1_mm"] > 0 and params["L2_mm"] > 0):
        r.fail("hidden.L1_mm", "the true link lengths must stay positive")
    effects = r.list_(h.get("effects") or [], "hidden.effects")
    for i, e in enumerate(effects):
        if not isinstance(e, dict):
            r.fail(f"hidden.effects[{i}]", f"expected an effect mapping like "
                                           f"{{name: joint_backlash, joint: 2, deg: 0.1}}, got {e!r}")
        try:
            TrueRobot.from_json(params, [e])
        except VisionCalError as err:
            r.fail(f"hidden.effects[{i}]", err.reason)
    truth = TrueRobot.from_json(params, effects)
    rep = r.number(h.get("repeatability_mm", 0.01), "hidden.repeatability_mm", lo=0, hi=5)
    ctrl = h.get("controller", "smc")
    if ctrl not in CONTROLLERS:
        r.fail("hidden.controller", f"expected one of {', '.join(CONTROLLERS)}, got {ctrl!r}")
    c = r.section(tree.get("camera"), "camera", CAMERA)
    d = SimCamera()
    size = r.vector(c.get("size_px", list(d.size_px)), "camera.size_px", 2, lo=64, hi=8000)
    cam = SimCamera(
        (int(size[0]), int(size[1])),
        r.number(c.get("f_px", d.f_px), "camera.f_px", lo=50, hi=50000),
        int(r.number(c.get("photos", d.photos), "camera.photos", lo=1, hi=50)),
        r.vector(c.get("tilt_deg", list(d.tilt_deg)), "camera.tilt_deg", 2, lo=0, hi=60),
        r.number(c.get("vignetting", d.vignetting), "camera.vignetting", lo=0, hi=1),
        r.number(c.get("noise_sigma", d.noise_sigma), "camera.noise_sigma", lo=0, hi=50),
        r.boolean(c.get("fixed", d.fixed), "camera.fixed"))
    seed = tree.get("seed")
    if seed is not None:
        seed = int(r.number(seed, "seed", lo=0, hi=2**32 - 1))
    pr = r.section(tree.get("print"), "print", ("deviation_rms_mm",))
    printer = PrintScene(r.number(pr.get("deviation_rms_mm", 0.0), "print.deviation_rms_mm",
                                  lo=0, hi=2))
    return SimulatedRobot(path, robot, truth, params, tuple(effects), rep, ctrl, cam, seed,
                          printer)


def print_field(sim: SimulatedRobot, sheet, sheet_id):
    """The printer's field of this sheet (None: printed exactly), drawn from its id: every
    rehearsal of one printed sheet photographs the same print."""
    if sim.print.is_exact:
        return None
    seed = int.from_bytes(hashlib.sha256(str(sheet_id).encode()).digest()[:4], "little")
    return sim.print.field(sheet.extent_mm, [m.corners_mm for m in sheet.markers], seed)


# ----------------------------------------------------------------------- the program


@dataclass(frozen=True)
class _Mark:
    """A mark as the world follows it (the shape of ``PlannedMark``)."""

    id: str
    joints_deg: tuple[float, float]
    via_deg: tuple[tuple[float, float], ...]
    role: str = "calibration"
    approach: tuple[int, int] = (1, 1)
    j4_deg: float = 0.0             # joint 4's command while the pen is down


@dataclass(frozen=True)
class _Move:
    """One commanded point of a robot program: joints 1, 2 (deg), joint 3 (mm, None: not
    given), joint 4 (deg), the pen down there, and the program's line (row) it came from."""

    q: tuple[float, float]
    down: bool
    j3_mm: float | None
    j4_deg: float
    line: int


#: the SPEL+ statements a vision-cal program holds (program/spel.py, camera/arm_design.py);
#: anything else is refused, never skipped: the simulated robot runs what the real one would
_SPEL_KNOWN = re.compile(
    r"^\s*(?:$|Function\s+\w+\s*$|Fend\s*$|Motor\s+(?:On|Off)\s*$|Power\s+(?:Low|High)\s*$"
    r"|Speed\s+[\d.]+\s*$|Accel\s+[\d.]+\s*,\s*[\d.]+\s*$|Print\s+\"[^\"]*\"\s*$"
    r"|Wait\s+[\d.]+\s*$|(?:On|Off)\s+\d+\s*$|TLSet\s+\d+\s*,\s*XY\([^()]*\)\s*$)",
    re.IGNORECASE)
_GO_FULL = re.compile(r"^\s*(?:Go|Jump)\s+JA\(\s*([^,()]+),\s*([^,()]+),\s*([^,()]+),"
                      r"\s*([^,()]+)\)\s*(?:LimZ\s+(-?[\d.]+)\s*)?$", re.IGNORECASE)


def program_moves(path: Path, *, pen_down_mm: float,
                  pen_bit: int | None = None) -> list[_Move]:
    """The joint moves of a robot program, in order (:class:`_Move`).

    SPEL+ (``.prg``): every ``Go``/``Jump JA(j1, j2, j3, j4)`` line; the pen is down where
    joint 3 is at ``pen_down_mm``, or at ``On pen_bit`` (the robot file's pen output). A
    statement a vision-cal program does not hold is refused with its line. The neutral
    point list (``_points.csv``): each ``mark`` row is a stop with the pen going down,
    ``home`` and ``via`` rows are driven through.
    """
    moves = []
    if path.suffix.lower() == ".csv":   # one CSV reader (a column named twice is refused)
        for line, row in read_rows(path, ("kind", "j1_deg", "j2_deg"), what="point list CSV"):
            try:
                q = (float(row["j1_deg"]), float(row["j2_deg"]))
                kind = row["kind"]
                j3 = float(row["j3_mm"]) if row.get("j3_mm") not in (None, "") else None
                j4 = float(row["j4_deg"]) if row.get("j4_deg") not in (None, "") else 0.0
            except (KeyError, TypeError, ValueError) as e:
                raise VisionCalError(f"line {line}: unreadable point ({e})", file=str(path)) from e
            if kind not in ("home", "via", "mark"):
                raise VisionCalError(f"line {line}: unknown kind {kind!r} (expected home, via "
                                     "or mark)", file=str(path))
            moves.append(_Move(q, False, j3, j4, line))
            if kind == "mark":
                moves.append(_Move(q, True, pen_down_mm, j4, line))
        return moves
    text = read_text(path)
    on = re.compile(rf"^\s*On\s+{pen_bit}\s*$", re.IGNORECASE) if pen_bit is not None else None
    for ln, line in enumerate(text.splitlines(), 1):
        code = _strip_comment(line)
        if on is not None and on.match(code) and moves:
            last = moves[-1]
            moves.append(_Move(last.q, True, last.j3_mm, last.j4_deg, ln))
            continue
        m = _GO_FULL.match(code)
        if not m:
            if not _SPEL_KNOWN.match(code):
                raise VisionCalError(f"line {ln}: {code.strip()[:60]!r} is a statement the "
                                     "simulated robot does not know (it runs only what "
                                     "vision-cal writes: Go/Jump JA, On/Off, Wait, Speed, "
                                     "Accel, Power, Motor, Print, TLSet)", file=str(path))
            continue
        try:
            j1, j2, j3, j4 = (float(v) for v in m.groups()[:4])
        except ValueError as e:
            raise VisionCalError(f"line {ln}: unreadable JA point ({e})", file=str(path)) from e
        moves.append(_Move((j1, j2), abs(j3 - pen_down_mm) < 1e-3, j3, j4, ln))
    return moves


def _strip_comment(line: str) -> str:
    """A SPEL+ line without its ``'`` comment (a ``'`` inside a string is not one)."""
    inside = False
    for i, c in enumerate(line):
        if c == '"':
            inside = not inside
        elif c == "'" and not inside:
            return line[:i]
    return line


def check_moves_in_limits(moves: list[_Move], robot, path: Path) -> None:
    """Every commanded point within the robot file's joint limits (joints 1, 2, 3 and 4),
    or one line naming the program's line and the limit: the simulated robot is the robot
    file, and a real controller would stop there."""
    where = "line" if path.suffix.lower() != ".csv" else "row"
    lim = robot.joint_limits_deg
    for mv in moves:
        for j in range(2):
            lo, hi = lim[j]
            if not lo <= mv.q[j] <= hi:
                raise VisionCalError(f"{where} {mv.line}: joint {j + 1} at {mv.q[j]:g} deg is "
                                     f"beyond the robot file's limits [{lo:g}, {hi:g}] "
                                     f"({robot.path}: joint_limits_deg)", file=str(path))
        lo, hi = robot.joint4_limits_deg
        if not lo <= mv.j4_deg <= hi:
            raise VisionCalError(f"{where} {mv.line}: joint 4 at {mv.j4_deg:g} deg is beyond "
                                 f"the robot file's limits [{lo:g}, {hi:g}] ({robot.path}: "
                                 "joint4_limits_deg)", file=str(path))
        lo, hi = robot.joint3_limits_mm
        if mv.j3_mm is not None and not lo <= mv.j3_mm <= hi:
            raise VisionCalError(f"{where} {mv.line}: joint 3 at {mv.j3_mm:g} mm is beyond "
                                 f"the robot file's travel [{lo:g}, {hi:g}] ({robot.path}: "
                                 "joint3_limits_mm)", file=str(path))


def marks_from_program(path: Path, marks: list[dict], *, pen_down_mm: float,
                       pen_bit: int | None = None, robot=None) -> list[_Mark]:
    """The program's pen-down points matched in order to session.json's ``marks``, each
    with the points driven through since the previous pen-down (its via points) and the
    joint 4 it was drawn at. With ``robot`` (a ``RobotFile``), every point is checked
    against its joint limits first."""
    moves = program_moves(path, pen_down_mm=pen_down_mm, pen_bit=pen_bit)
    if robot is not None:
        check_moves_in_limits(moves, robot, path)
    out, path_q, last = [], [], None
    for mv in moves:
        q = mv.q
        if mv.down:
            k = len(out)
            if k >= len(marks):
                raise VisionCalError(f"puts the pen down more often than session.json has "
                                     f"marks ({len(marks)})", file=str(path))
            want = marks[k]["joints_deg"]
            if max(abs(q[0] - want[0]), abs(q[1] - want[1])) > 1e-3:
                raise VisionCalError(f"pen-down point {k + 1} at {list(q)} deg is not "
                                     f"session.json's mark {marks[k]['id']} at {want} deg: the "
                                     "program is not this plan's", file=str(path))
            vias = [p for p in path_q if p != q and p != last]
            out.append(_Mark(str(marks[k]["id"]), q, tuple(vias), j4_deg=mv.j4_deg))
            path_q, last = [], q
        elif not path_q or path_q[-1] != q:
            path_q.append(q)
    if len(out) != len(marks):
        raise VisionCalError(f"draws {len(out)} marks, session.json plans {len(marks)}",
                             file=str(path))
    return out


# ----------------------------------------------------------------------- the sheet


def printed_sheet(sheet_block: dict, *, file: str, size_px, f_px: float):
    """The printed sheet (``PrintedSheet``) rebuilt from a session's sheet block, its raster
    at a whole number of px/mm: at least twice the photos' resolution on the paper."""
    layout = layout_from_sheet_json(sheet_block, file=file)
    sheet = read_sheet_block(FieldReader(file), sheet_block, "sheet")
    w_mm = max(layout.size_mm)
    px_per_mm_photo = max(size_px) / w_mm   # the sheet fills the photo at best
    k = int(np.clip(np.ceil(2.0 * px_per_mm_photo), 4, 16))
    return PrintedSheet(sheet, rasterise(layout, 25.4 * k), float(k))


# ----------------------------------------------------------------------- the rehearsal


@dataclass(frozen=True)
class SimulateResult:
    out_dir: Path
    photos: tuple[Path, ...]
    n_marks: int
    off_paper: tuple[str, ...]
    on_marker: tuple[str, ...]
    truth_path: Path
    blank: bool = False              # the blank sheet photographed (for a survey)
    n_poses: int = 0                 # a camera on the arm: the poses it stood at


def _simulate_arm(session: dict, session_path: Path, sim, out: Path, rng) -> SimulateResult:
    """A camera-on-arm session (``vision-cal design --camera-on-arm``): the simulated robot
    stands at each pose and its camera (a mount drawn by the world, looking down, on the
    flange or link 2 as ``camera_mount`` says) photographs the marker field. The
    simulated camera's lens is added to session.json when it declares none (what the user
    adds by hand), and truth.json holds ``T_flange_camera``."""
    r = FieldReader(str(session_path))
    sheet = read_sheet_block(r, r.get(session, "sheet", ""), "sheet")
    poses = r.list_(session["poses"], "poses", nonempty=True)
    try:
        files = [str(p["image"]) for p in poses]
        q = np.array([p["joints_deg"][:2] for p in poses], float)
        j4 = np.array([float(p.get("j4_deg", 0.0)) for p in poses])
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise VisionCalError(f"expected image, joints_deg, j4_deg in every pose: {e}",
                             file=str(session_path), field="poses") from e
    cam = sim.camera
    K = np.asarray(camera_matrix(size_px=cam.size_px, f_px=cam.f_px), dtype=float)
    X = T_flange_camera_true(rng)
    out.mkdir(parents=True, exist_ok=True)
    # the world's own record of the motion: each joint's last move from the previous pose
    # (from home for the first), kept when it did not move
    steps = np.diff(np.vstack([np.asarray(sim.robot.nominal.home_deg, float)[:2], q]), axis=0)
    approach = np.ones_like(q)
    for i in range(len(q)):
        prev = approach[i - 1] if i else np.ones(2)
        approach[i] = np.where(steps[i] > 0, 1.0, np.where(steps[i] < 0, -1.0, prev))
    Ts = photograph_poses(out, sim.truth, sheet, q, j4, files, X, K=K, size_px=cam.size_px,
                          rng=rng, repeatability_mm=sim.repeatability_mm,
                          noise_sigma=cam.noise_sigma, approach=approach)
    if "camera" not in session:
        session = {**session, "camera": {"size_px": list(cam.size_px), "K": K.tolist(),
                                         "dist": [0.0] * 5}}
    atomic_write_json(out / "session.json", session)
    truth = {"params": sim.params, "effects": list(sim.effects), "T_flange_camera": X.tolist(),
             "repeatability_mm": sim.repeatability_mm, "simulated_robot": str(sim.path),
             "seed": sim.seed,
             "camera": {"size_px": list(cam.size_px), "K": K.tolist(), "dist": [0.0] * 5,
                        "T_cam_sheet": {f: T.tolist() for f, T in zip(files, Ts)}}}
    truth_path = atomic_write_json(out / "truth.json", truth)
    return SimulateResult(out, tuple(out / f for f in files), 0, (), (), truth_path,
                          n_poses=len(poses))


def _plan_marks(plan_dir: Path, session: dict, robot) -> tuple[list[_Mark], str]:
    """The marks of a designed folder as its program draws them; a folder without a program
    is refused (the rehearsal runs the program the robot will run, never session.json)."""
    marks = session.get("marks")
    if not isinstance(marks, list) or not marks:
        raise VisionCalError("no marks to draw", file=str(plan_dir / "session.json"),
                             field="marks")
    for name in PROGRAMS:
        p = plan_dir / name
        if p.is_file():
            if robot.pen_down_mm is None:
                raise VisionCalError("missing: the simulated robot follows the program's "
                                     "pen-down height", file=str(robot.path), field="pen_down_mm")
            return marks_from_program(p, marks, pen_down_mm=robot.pen_down_mm,
                                      pen_bit=robot.program.pen_output_bit, robot=robot), name
    raise VisionCalError(f"no robot program ({' or '.join(PROGRAMS)}) to run: the simulated "
                         "robot runs the program the robot will run, never session.json's "
                         "marks; write it with vision-cal design --program spel (the robot "
                         "file needs pen_up_mm and pen_down_mm)", file=str(plan_dir))


def targets_session(program: Path, sim: SimulatedRobot, *, sheet_json, targets=None) -> dict:
    """A session (no images) for a targets program written by ``vision-cal plan
    --program``: its marks are the rows of the plan CSV beside it (``PLAN.prg`` ->
    ``PLAN.csv``; joints, approach), with ``target_mm`` from ``targets`` (targets.csv)
    when given; the sheet from ``sheet_json``; the robot block the robot file's."""
    stem = program.with_suffix("") if program.suffix.lower() == ".prg" else \
        program.with_name(program.name.removesuffix("_points.csv"))
    plan_csv = stem.with_suffix(".csv")
    if sheet_json is None:
        raise VisionCalError("a targets program needs the sheet it is drawn on: give "
                             "--sheet SHEET.json", field="--sheet")
    if not plan_csv.is_file():   # a designed plan's program.prg given instead of its folder
        why = (f"is a designed plan's program: give its folder ({program.parent}) instead"
               if (program.parent / "session.json").is_file() else
               f"no {plan_csv.name} beside it: a targets program needs the plan CSV "
               "`vision-cal plan` wrote with it")
        raise VisionCalError(why, file=str(program))
    ids, q, s = read_plan(plan_csv)
    want = {}
    if targets is not None:
        tid, txy = read_targets(targets)
        want = dict(zip(tid, txy))
        _same_ids(list(ids), list(tid), plan_csv, Path(targets))
    n = sim.robot.nominal
    marks = []
    for i, mid in enumerate(ids):
        m = {"id": mid, "joints_deg": [float(q[i, 0]), float(q[i, 1])],
             "approach": [int(s[i, 0]), int(s[i, 1])], "role": "calibration"}
        if mid in want:
            m["target_mm"] = [float(v) for v in want[mid]]
        marks.append(m)
    return {"format": "vision-cal/1", "sheet": sheet_file_block(sheet_json)[0],
            "robot": {"L1_mm": n.L1_mm, "L2_mm": n.L2_mm,
                      "joint_zero_deg": list(n.joint_zero_deg), "base_mm": list(n.base_mm),
                      "home_deg": list(n.home_deg)},
            "pen": {"mark_diameter_mm": sim.robot.mark_diameter_mm}, "marks": marks,
            "design": {"stage": "targets", "program": str(program)}}


def _same_ids(plan_ids: list, target_ids: list, plan_csv: Path, targets: Path) -> None:
    """The targets and the plan name the same marks, or one line naming what differs (a
    target dropped or never planned is a rehearsal of another job)."""
    missing = [t for t in target_ids if t not in set(plan_ids)]
    extra = [p for p in plan_ids if p not in set(target_ids)]
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"targets not in the plan ({plan_csv}): {', '.join(missing[:5])}"
                         + (" ..." if len(missing) > 5 else ""))
        if extra:
            parts.append(f"planned marks not among the targets: {', '.join(extra[:5])}"
                         + (" ..." if len(extra) > 5 else ""))
        raise VisionCalError(f"the ids do not match the plan's: {'; '.join(parts)}",
                             file=str(targets))


def simulate_session(plan_dir, truth_path, out_dir, *, after=(), progress: bool = False,
                     rng=None, sheet_json=None, targets=None,
                     photos: int | None = None) -> SimulateResult:
    """The simulated robot of ``truth_path`` draws the plan in ``plan_dir`` on the printed
    sheet (with the true marks of the folders in ``after`` already on it) and photographs
    it into ``out_dir``. See the module docstring.

    ``plan_dir`` may also be a targets program of ``vision-cal plan --program`` (``.prg``
    or ``_points.csv``): then ``sheet_json`` says the sheet, ``targets`` (targets.csv) the
    targets, and ``out_dir`` gets a session.json of the drawn targets (calibrate it to
    measure where they landed: calibration.json ``targets``). ``plan_dir`` a sheet.json (or
    a session.json, whose sheet is used): the blank sheet, before any mark, photographed
    for a survey (:func:`_simulate_blank`). ``photos``: how many photos (default: the
    simulated robot's ``camera.photos``; a blank sheet :data:`SURVEY_PHOTOS`)."""
    plan_dir, out = Path(plan_dir), Path(out_dir)
    sim = load_simulated_robot(truth_path)
    blank = plan_dir.is_file() and plan_dir.suffix.lower() == ".json"
    if blank and after:
        raise VisionCalError("a blank sheet (a sheet.json given) has no marks drawn before "
                             "it", field="--after")
    if photos is not None and not 1 <= photos <= 50:
        raise VisionCalError(f"expected 1..50 photos, got {photos}", field="--photos")
    if not blank:
        program, session, session_path, plan_dir = _open_plan(plan_dir, out, sim, sheet_json,
                                                              targets)
    if out.exists() and not out.is_dir():
        raise VisionCalError("exists and is not a folder", file=str(out))
    if out.is_dir():
        there = list_photos(out)
        if there:
            raise VisionCalError(f"holds photos already ({there[0]}, ...): a rehearsal adds "
                                 "its own; choose an empty folder", file=str(out))
    rng = np.random.default_rng(sim.seed if rng is None else rng)
    if blank:
        return _simulate_blank(plan_dir, sim, out, rng, photos or SURVEY_PHOTOS,
                               progress=progress)
    if photos is not None:
        sim = replace(sim, camera=replace(sim.camera, photos=photos))
    if program is None and session.get("poses") and not session.get("marks"):
        return _simulate_arm(session, session_path, sim, out, rng)
    if program is not None:
        plan = marks_from_program(program, session["marks"], pen_down_mm=sim.robot.pen_down_mm,
                                  pen_bit=sim.robot.program.pen_output_bit, robot=sim.robot)
        source_name = program.name
    else:
        plan, source_name = _plan_marks(plan_dir, session, sim.robot)
    sheet_block = session.get("sheet")
    if not isinstance(sheet_block, dict):
        raise VisionCalError("missing the sheet block", file=str(session_path), field="sheet")
    printed = printed_sheet(sheet_block, file=str(session_path), size_px=sim.camera.size_px,
                            f_px=sim.camera.f_px)
    sheet_id = (sheet_block.get("printed") or {}).get("sheet_id")
    earlier_xy = _earlier_marks(after, sheet_id)
    source, world = _draw(sim, plan, rng)
    sheet = printed.sheet
    off = marks_off_paper(world, sheet)
    on = marks_on_markers(world, sheet)
    pen = session.get("pen") or {}
    dia = float(pen.get("mark_diameter_mm", sim.robot.mark_diameter_mm))
    K = np.asarray(camera_matrix(size_px=sim.camera.size_px, f_px=sim.camera.f_px), dtype=float)
    field = print_field(sim, sheet, sheet_id)
    images = _photograph(sim, printed, np.vstack([earlier_xy, world.xy_mm]), dia, K, rng,
                         progress=progress, desc=f"simulate {out.name}", field=field)
    truth = {
        "params": sim.params, "effects": list(sim.effects),
        "marks": {mid: world.xy_mm[i].tolist() for i, mid in enumerate(world.ids)},
        "camera": {"size_px": list(sim.camera.size_px), "K": K.tolist(), "dist": [0.0] * 5,
                   "declared": False,
                   "T_cam_sheet": {f: sim.truth.T_render(T).tolist() for f, _, T in images}},
        "repeatability_mm": sim.repeatability_mm, "controller": sim.controller,
        "approach": {mid: world.approach[i].tolist() for i, mid in enumerate(world.ids)},
        "link_q_deg": {mid: world.q_deg[i].tolist() for i, mid in enumerate(world.ids)},
        "off_paper": off, "on_marker": on, "sheet_id": sheet_id,
        "earlier_marks_mm": earlier_xy.tolist(), "followed": source_name,
        "simulated_robot": str(sim.path), "seed": sim.seed,
        "controller_report": getattr(source, "report", None),
    }
    if field is not None:   # added field: the sheet as printed (world.print_deviation)
        truth["print"] = field.to_json([m.id for m in sheet.markers],
                                       [m.corners_mm for m in sheet.markers])
    # everything is computed: now write (truth.json last)
    out.mkdir(parents=True, exist_ok=True)
    if program is not None or out.resolve() != plan_dir.resolve():
        atomic_write_json(out / "session.json", {k: v for k, v in session.items()
                                                 if k != "images"})
    paths = tuple(atomic_write_bytes(out / f, data) for f, data, _ in images)
    truth_path_out = atomic_write_json(out / "truth.json", truth)
    return SimulateResult(out, paths, len(world.ids), tuple(off), tuple(on), truth_path_out)


def _open_plan(plan_dir: Path, out: Path, sim: SimulatedRobot, sheet_json, targets):
    """What the simulated robot runs: ``(program, session, session_path, plan_dir)``, with
    ``program`` the targets program given instead of a designed folder (its session built
    from ``sheet_json`` and ``targets``; ``plan_dir`` is then ``out``), else None and the
    folder's session.json."""
    if not plan_dir.exists():
        raise VisionCalError("no such program or folder: the simulated robot runs the program "
                             "you give it", file=str(plan_dir))
    if plan_dir.is_file():
        session = targets_session(plan_dir, sim, sheet_json=sheet_json, targets=targets)
        return plan_dir, session, Path(sheet_json), out
    session_path = plan_dir / "session.json"
    return None, read_json(session_path), session_path, plan_dir


def _earlier_marks(after, sheet_id) -> np.ndarray:
    """The true marks (N, 2) of the rehearsals in ``after``, already on the sheet; refuses
    one drawn on another sheet."""
    earlier = []
    for d in after:
        if not Path(d).is_dir():
            raise VisionCalError("expected a folder simulated before (its truth.json says "
                                 "which marks are already on the sheet)", file=str(d),
                                 field="--after")
        t = read_json(Path(d) / "truth.json")
        if (t.get("sheet_id") or sheet_id) != sheet_id:
            raise VisionCalError(f"was drawn on sheet {t.get('sheet_id')}, this plan is for "
                                 f"{sheet_id}", file=str(Path(d) / "truth.json"), field="sheet_id")
        earlier += [v for v in (t.get("marks") or {}).values()]
    return np.asarray(earlier, dtype=float).reshape(-1, 2)


def _draw(sim: SimulatedRobot, plan, rng):
    """The true robot draws ``plan``: ``(source, world)``, with ``source`` the simulated
    controller and arm (None for the kinematic robot) and ``world`` the drawn marks."""
    if sim.controller == "kinematic":
        source, model = None, sim.truth
    else:
        # the robot file's speed and acceleration limits shape the trajectory it follows
        source, model = simulated_world(sim.truth, controller=sim.controller, rng=rng,
                                        vmax_deg_s=tuple(sim.robot.speed_limits_deg_s),
                                        amax_deg_s2=tuple(sim.robot.accel_limits_deg_s2))
    # joint 4 as the program commands it: the robot file's tool turns with it
    world = draw_marks(model, plan, home_deg=sim.robot.nominal.home_deg,
                       repeatability_mm=sim.repeatability_mm, joint_source=source, rng=rng,
                       joint4_deg=np.array([m.j4_deg for m in plan], dtype=float))
    return source, world


def _simulate_blank(sheet_path: Path, sim: SimulatedRobot, out: Path, rng, n: int, *,
                    progress: bool) -> SimulateResult:
    """The blank sheet of ``sheet_path`` (sheet.json, or a session.json's sheet), before any
    mark, photographed ``n`` times from several places tilted :data:`SURVEY_TILT_DEG` (what
    ``vision-cal survey`` measures), printed as the simulated robot's ``print`` says: the
    photos and truth.json (the camera poses; ``print``, the markers as printed)."""
    block = sheet_file_block(sheet_path)[0]
    if not isinstance(block, dict):
        raise VisionCalError("expected a sheet.json (or a session.json with its sheet block)",
                             file=str(sheet_path))
    cam = sim.camera
    printed = printed_sheet(block, file=str(sheet_path), size_px=cam.size_px, f_px=cam.f_px)
    sheet = printed.sheet
    sheet_id = (block.get("printed") or {}).get("sheet_id")
    field = print_field(sim, sheet, sheet_id)
    K = np.asarray(camera_matrix(size_px=cam.size_px, f_px=cam.f_px), dtype=float)
    phone = replace(sim, camera=replace(cam, photos=n, tilt_deg=SURVEY_TILT_DEG, fixed=False))
    images = _photograph(phone, printed, np.zeros((0, 2)), 1.0, K, rng, progress=progress,
                         desc=f"simulate {out.name}", field=field)
    truth = {"blank_sheet": str(sheet_path), "sheet_id": sheet_id,
             "camera": {"size_px": list(cam.size_px), "K": K.tolist(), "dist": [0.0] * 5,
                        "declared": False,
                        "T_cam_sheet": {f: sim.truth.T_render(T).tolist()
                                        for f, _, T in images}},
             "print": (None if field is None else
                       field.to_json([m.id for m in sheet.markers],
                                     [m.corners_mm for m in sheet.markers])),
             "simulated_robot": str(sim.path), "seed": sim.seed}
    out.mkdir(parents=True, exist_ok=True)
    paths = tuple(atomic_write_bytes(out / f, data) for f, data, _ in images)
    truth_path_out = atomic_write_json(out / "truth.json", truth)
    return SimulateResult(out, paths, 0, (), (), truth_path_out, blank=True)


def _photograph(sim: SimulatedRobot, printed, marks_xy, dia: float, K, rng, *,
                progress: bool, desc: str, field=None) -> list:
    """The photos of the printed sheet (its ink displaced by the printer's ``field``) with
    the marks ``marks_xy`` (mm) on it, from the simulated camera's views (one place when
    it is fixed): ``[(file, png bytes, T)]``."""
    cam = sim.camera
    sheet = printed.sheet
    tex = printed_texture(printed, marks_xy_mm=marks_xy, mark_diameters_mm=dia, rng=rng,
                          print_field=field)
    views = default_views(sheet, n=cam.photos, size_px=cam.size_px, K=K,
                          tilt_deg=cam.tilt_deg, rng=rng, fill=0.96, target_jitter=0.02)
    if cam.fixed:   # a camera fixed over the work area: one place, several photos
        views = [views[0]] * len(views)
    bar = progress_bar(progress, total=len(views), desc=desc, unit="photo")
    photographer = Photographer(size_px=cam.size_px, K=K)
    images = []
    try:
        for i, T in enumerate(views):
            rgb = photographer.photograph(tex, extent_mm=sheet.extent_mm,
                                          T_cam_sheet=sim.truth.T_render(T),
                                          vignetting=cam.vignetting,
                                          noise_sigma=cam.noise_sigma, rng=rng)
            images.append((f"IMG_{i + 1:04d}.png", encode_image(np.asarray(rgb), None), T))
            bar.update()
    finally:
        photographer.close()
        bar.close()
    return images
