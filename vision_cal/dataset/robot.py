"""The robot file (YAML or JSON): what ``vision-cal design`` and the programs need.

The session's ``robot`` block (``L1_mm``, ``L2_mm``, ``joint_zero_deg``, ``base_mm``,
``home_deg``; docs/format.md) at the top level, plus optional fields::

    name: SM5                        # shown in program headers
    placement_tolerance:             # how far the nominal values may be off (worst case, +-)
      base_mm: 40.0                  #   the base anywhere within this radius of base_mm
      joint_zero_deg: [5.0, 10.0]    #   z1 (robot rotation + joint-1 zero) and z2
      link_mm: 8.0                   #   L1 and L2
    joint_limits_deg: [[-170, 170], [-150, 150]]
    speed_limits_deg_s: [90, 120]    # the planned trajectory's joint speed limits
    accel_limits_deg_s2: [300, 400]  # and acceleration limits
    elbows: [1, -1]                  # allowed elbow solutions (+1: sin(q2 + z2) > 0)
    pen_up_mm: -10.0                 # joint 3 (mm) with the pen clear of the paper
    pen_down_mm: -25.0               # joint 3 (mm) with the pen touching it
    j4_deg: 0.0                      # joint 4, held still (the marks' default j4_deg)
    tool_mm: [0.0, 0.0]              # the pen in the flange frame at j4 = 0 (rough; docs/format.md)
    joint4_limits_deg: [-360, 360]   # joint 4's commanded range
    joint3_limits_mm: [-200, 0]      # joint 3's commanded travel (mm; the URDF's limits)
    repeatability_mm: 0.01           # positioning repeatability, one std per axis (the
                                     # noise-floor gate's robot part; default 0.01)
    mark_diameter_mm: 1.2            # the pen's mark (session.json pen block)
    overshoot_deg: 3.0               # the via point's distance before each mark
    program:                         # controller-native settings of the robot program
      power: low                     #   low | high
      speed_percent: 10              #   SPEL+ Speed (PTP, % of the rated speed)
      accel_percent: [10, 10]        #   SPEL+ Accel (acceleration, deceleration %)
      settle_s: 0.3                  #   wait on the mark before the pen goes down
      pen_dwell_s: 0.2               #   pen down this long
      pen_output_bit: 9              #   optional: the pen is lowered by this output (On/Off)
                                     #   instead of by joint 3
      safe_z_mm: -5.0                #   optional: travel with Jump ... LimZ at this height
                                     #   (inside joint3_limits_mm, at or above pen_up_mm)
      motor_off: true                #   optional: Motor Off at the end (default false)
      pen_signal: doPen              #   optional: the pen output's name where signals have
                                     #   names (RAPID SetDO doPen, VAL3
                                     #   doPen = true); see docs/controllers.md
      tool_number: 1                 #   optional: the controller tool the calibrated tool
                                     #   is written to (SPEL+ TLSet n, PacScript Tool n);
                                     #   without it the program overwrites no tool

Every malformed field is one line naming the file and the field (the typed readers of
:mod:`vision_cal.dataset.session`); unknown fields are logged and ignored, so files
written by other tools with more fields still read. YAML is read with ``safe_load`` (no
tags, nothing read can run code).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import read_json, read_yaml
from vision_cal.dataset.session import NominalRobot, read_robot_block
from vision_cal.errors import VisionCalError
from vision_cal.model.motion import (ACCEL_DEG_S2, JOINT3_LIMITS_MM, JOINT4_LIMITS_DEG,
                               JOINT_LIMITS_DEG, SPEED_DEG_S)

log = logging.getLogger(__name__)

ROBOT_BLOCK = ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm", "home_deg", "repeatability_mm")
#: an output bit's number (the pen's, a camera trigger's): what controllers number
OUTPUT_BITS = (0, 9999)


@dataclass(frozen=True)
class PlacementTolerance:
    """How far the nominal model may be off, worst case (+-)."""

    base_mm: float = 30.0
    joint_zero_deg: tuple[float, float] = (5.0, 5.0)
    link_mm: float = 2.0


@dataclass(frozen=True)
class ProgramSettings:
    power: str = "low"
    speed_percent: float = 10.0
    accel_percent: tuple[float, float] = (10.0, 10.0)
    settle_s: float = 0.3
    pen_dwell_s: float = 0.2
    pen_output_bit: int | None = None   # SPEL+ On/Off output that lowers the pen
    safe_z_mm: float | None = None      # travel height of Jump ... LimZ (joint 3, mm)
    motor_off: bool = False             # Motor Off at the end of the program
    pen_signal: str | None = None       # the pen output's name, for controllers that name
    #                                     signals (RAPID ``SetDO name``), issue 32
    tool_number: int | None = None      # the controller tool entry a program may define
    #                                     (None: it defines none), issue 38


@dataclass(frozen=True)
class RobotFile:
    path: Path
    nominal: NominalRobot
    name: str = "robot"
    tolerance: PlacementTolerance = field(default_factory=PlacementTolerance)
    joint_limits_deg: tuple[tuple[float, float], tuple[float, float]] = JOINT_LIMITS_DEG
    speed_limits_deg_s: tuple[float, float] = SPEED_DEG_S
    accel_limits_deg_s2: tuple[float, float] = ACCEL_DEG_S2
    elbows: tuple[int, ...] = (1, -1)
    pen_up_mm: float | None = None
    pen_down_mm: float | None = None
    j4_deg: float = 0.0
    mark_diameter_mm: float = 1.2
    overshoot_deg: float = 3.0
    program: ProgramSettings = field(default_factory=ProgramSettings)
    joint4_limits_deg: tuple[float, float] = JOINT4_LIMITS_DEG
    joint3_limits_mm: tuple[float, float] = JOINT3_LIMITS_MM

    def require_pen_heights(self) -> tuple[float, float]:
        """(pen_up_mm, pen_down_mm); a program cannot be written without them."""
        for k in ("pen_up_mm", "pen_down_mm"):
            if getattr(self, k) is None:
                raise VisionCalError("missing: a robot program needs the pen-up and pen-down "
                                     "heights (joint 3, mm)", file=str(self.path), field=k)
        return float(self.pen_up_mm), float(self.pen_down_mm)

    def check_travel_height(self) -> None:
        """``program.safe_z_mm`` as a program may drive it (:func:`travel_height_problem`),
        else one line naming the file and the field."""
        problem = travel_height_problem(self.program.safe_z_mm, self.pen_up_mm,
                                        self.pen_down_mm, self.joint3_limits_mm)
        if problem is not None:
            raise VisionCalError(problem, file=str(self.path), field="program.safe_z_mm")


def travel_height_problem(safe, up, down, joint3_limits_mm) -> str | None:
    """Why the travel height ``safe`` (joint 3, mm; None: none) cannot be driven (None: it
    can): outside joint 3's travel, or below the pen-up height. Up is the side of
    ``pen_up_mm`` from ``pen_down_mm`` (the sign of joint 3 differs between vendors), so
    the travel height must lie at or beyond pen up on that side: never between the pen
    heights or below pen down, where the arm would sweep the pen across (or into) the
    table."""
    if safe is None:
        return None
    lo, hi = joint3_limits_mm
    if not lo <= safe <= hi:
        return (f"{safe:.3f} mm is outside joint 3's travel [{lo:g}, {hi:g}] mm "
                "(joint3_limits_mm)")
    if up is not None and down is not None and (safe - up) * (up - down) < 0:
        side = "above" if up > down else "below"
        return (f"{safe:.3f} mm is below the pen-up height: the travel height must be at or "
                f"beyond pen_up_mm {up:g} on its side of pen_down_mm {down:g} (here: "
                f"{side} {up:g}), or the arm travels with the pen at or into the paper")
    return None


def read_robot_tree(path: Path) -> dict:
    if path.suffix.lower() == ".json":
        tree = read_json(path, what="robot file")
    else:
        tree = read_yaml(path, what="robot file")
    if not isinstance(tree, dict):
        raise VisionCalError("expected a mapping of robot fields at the top level",
                             file=str(path))
    return tree


def _positive(r: FieldReader, v, where: str, *, zero_ok=False) -> float:
    x = r.number(v, where)
    if x < 0 or (x == 0 and not zero_ok):
        r.fail(where, f"expected a {'non-negative' if zero_ok else 'positive'} number, got {v!r}")
    return x


def load_robot_file(path) -> RobotFile:
    """Read and validate a robot file (YAML, or JSON when it ends in .json)."""
    path = Path(path)
    tree = read_robot_tree(path)
    r = FieldReader(str(path))
    nominal = read_robot_block(r, tree, "")
    kw: dict = {}
    if tree.get("name") is not None:
        kw["name"] = r.string(tree.get("name"), "name")
    if tree.get("placement_tolerance") is not None:
        kw["tolerance"] = _read_tolerance(r, tree.get("placement_tolerance"), path)
    kw.update(_read_limits(r, tree))
    kw.update(_read_pen(r, tree, kw.get("joint3_limits_mm", JOINT3_LIMITS_MM)))
    if tree.get("program") is not None:
        kw["program"] = _read_program(r, tree.get("program"), path)
        problem = travel_height_problem(kw["program"].safe_z_mm, kw.get("pen_up_mm"),
                                        kw.get("pen_down_mm"),
                                        kw.get("joint3_limits_mm", JOINT3_LIMITS_MM))
        if problem is not None:
            r.fail("program.safe_z_mm", problem)
    known = set(ROBOT_BLOCK) | {f for f in RobotFile.__dataclass_fields__} | {
        "placement_tolerance", "tool_mm"}
    extra = set(tree) - known
    if extra:
        log.warning("%s: ignoring unknown fields %s", path, ", ".join(sorted(map(str, extra))))
    home = nominal.home_deg
    lims = kw.get("joint_limits_deg", JOINT_LIMITS_DEG)
    for j in range(2):
        if not lims[j][0] <= home[j] <= lims[j][1]:
            r.fail("home_deg", f"joint {j + 1} at {home[j]:g} deg is outside joint_limits_deg "
                               f"{list(lims[j])}")
    return RobotFile(path, nominal, **kw)


def _read_tolerance(r: FieldReader, t, path: Path) -> PlacementTolerance:
    """The ``placement_tolerance`` block (defaults for what it leaves out; unknown fields
    logged and ignored)."""
    if not isinstance(t, dict):
        r.fail("placement_tolerance", f"expected an object, got {type(t).__name__}")
    d = PlacementTolerance()
    b = _positive(r, t["base_mm"], "placement_tolerance.base_mm", zero_ok=True) \
        if "base_mm" in t else d.base_mm
    z = r.vector(t["joint_zero_deg"], "placement_tolerance.joint_zero_deg", 2) \
        if "joint_zero_deg" in t else d.joint_zero_deg
    for i, v in enumerate(z):
        _positive(r, v, f"placement_tolerance.joint_zero_deg[{i}]", zero_ok=True)
    ln = _positive(r, t["link_mm"], "placement_tolerance.link_mm", zero_ok=True) \
        if "link_mm" in t else d.link_mm
    extra = set(t) - {"base_mm", "joint_zero_deg", "link_mm"}
    if extra:
        log.warning("%s: placement_tolerance: ignoring unknown fields %s", path,
                    ", ".join(sorted(extra)))
    return PlacementTolerance(b, z, ln)


def _read_limits(r: FieldReader, tree: dict) -> dict:
    """The joint limits, speed and acceleration limits and elbows the file gives, as
    ``RobotFile`` keyword arguments (each ``lo < hi``, positive, distinct +1/-1)."""
    kw: dict = {}
    lim = tree.get("joint_limits_deg")
    if lim is not None:
        rows = r.list_(lim, "joint_limits_deg")
        if len(rows) != 2:
            r.fail("joint_limits_deg", f"expected [[lo, hi], [lo, hi]], got {lim!r}")
        pairs = []
        for j, row in enumerate(rows):
            lo, hi = r.vector(row, f"joint_limits_deg[{j}]", 2)
            if not lo < hi:
                r.fail(f"joint_limits_deg[{j}]", f"expected lo < hi, got {row!r}")
            pairs.append((lo, hi))
        kw["joint_limits_deg"] = tuple(pairs)
    for key in ("joint4_limits_deg", "joint3_limits_mm"):
        if tree.get(key) is not None:
            lo, hi = r.vector(tree.get(key), key, 2)
            if not lo < hi:
                r.fail(key, f"expected lo < hi, got {tree.get(key)!r}")
            kw[key] = (lo, hi)
    for key in ("speed_limits_deg_s", "accel_limits_deg_s2"):
        if tree.get(key) is not None:
            v = r.vector(tree.get(key), key, 2)
            for i, x in enumerate(v):
                _positive(r, x, f"{key}[{i}]")
            kw[key] = v
    if tree.get("elbows") is not None:
        els = r.list_(tree.get("elbows"), "elbows", nonempty=True)
        for i, e in enumerate(els):
            if isinstance(e, bool) or e not in (1, -1):
                r.fail(f"elbows[{i}]", f"expected +1 or -1, got {e!r}")
        if len(set(els)) != len(els):
            r.fail("elbows", f"expected distinct values, got {els!r}")
        kw["elbows"] = tuple(int(e) for e in els)
    return kw


def _read_pen(r: FieldReader, tree: dict, joint3_limits_mm) -> dict:
    """The pen's heights (both or neither, different, inside joint 3's travel), the tool's
    angle, the mark's diameter and the overshoot, as ``RobotFile`` keyword arguments."""
    kw: dict = {}
    for key in ("pen_up_mm", "pen_down_mm", "j4_deg"):
        if tree.get(key) is not None:
            kw[key] = r.number(tree.get(key), key)
    if ("pen_up_mm" in kw) != ("pen_down_mm" in kw):
        missing = "pen_down_mm" if "pen_up_mm" in kw else "pen_up_mm"
        r.fail(missing, "missing: give both pen heights or neither")
    if "pen_up_mm" in kw and kw["pen_up_mm"] == kw["pen_down_mm"]:
        r.fail("pen_down_mm", "must differ from pen_up_mm")
    lo3, hi3 = joint3_limits_mm
    for key in ("pen_up_mm", "pen_down_mm"):
        if key in kw and not lo3 <= kw[key] <= hi3:
            r.fail(key, f"{kw[key]:g} mm is outside joint 3's travel [{lo3:g}, {hi3:g}] mm "
                        "(joint3_limits_mm)")
    for key in ("mark_diameter_mm", "overshoot_deg"):
        if tree.get(key) is not None:
            kw[key] = _positive(r, tree.get(key), key)
    return kw


def _read_program(r: FieldReader, p, path: Path) -> ProgramSettings:
    """The ``program`` block (defaults for what it leaves out; unknown fields logged and
    ignored)."""
    if not isinstance(p, dict):
        r.fail("program", f"expected an object, got {type(p).__name__}")
    d = ProgramSettings()
    power = p.get("power", d.power)
    if power not in ("low", "high"):
        r.fail("program.power", f"expected 'low' or 'high', got {power!r}")
    sp = r.number(p["speed_percent"], "program.speed_percent") \
        if "speed_percent" in p else d.speed_percent
    if not 1 <= sp <= 100:
        r.fail("program.speed_percent", f"expected 1..100, got {sp:g}")
    ac = r.vector(p["accel_percent"], "program.accel_percent", 2) \
        if "accel_percent" in p else d.accel_percent
    for i, a in enumerate(ac):
        if not 1 <= a <= 100:
            r.fail(f"program.accel_percent[{i}]", f"expected 1..100, got {a:g}")
    settle = _positive(r, p["settle_s"], "program.settle_s", zero_ok=True) \
        if "settle_s" in p else d.settle_s
    dwell = _positive(r, p["pen_dwell_s"], "program.pen_dwell_s", zero_ok=True) \
        if "pen_dwell_s" in p else d.pen_dwell_s
    bit = p.get("pen_output_bit")
    lo, hi = OUTPUT_BITS
    if bit is not None and (isinstance(bit, bool) or not isinstance(bit, int)
                            or not lo <= bit <= hi):
        r.fail("program.pen_output_bit", f"expected an output bit number {lo}..{hi}, got {bit!r}")
    safe = r.number(p["safe_z_mm"], "program.safe_z_mm") if p.get("safe_z_mm") is not None \
        else None
    moff = p.get("motor_off", False)
    if not isinstance(moff, bool):
        r.fail("program.motor_off", f"expected true or false, got {moff!r}")
    sig = p.get("pen_signal")
    if sig is not None and not (isinstance(sig, str)
                                and re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,31}", sig)):
        r.fail("program.pen_signal", f"expected a signal name (a letter, then letters, "
                                     f"digits or _, at most 32), got {sig!r}")
    tool = p.get("tool_number")
    if tool is not None and (isinstance(tool, bool) or not isinstance(tool, int)
                             or not 1 <= tool <= 99):
        r.fail("program.tool_number", f"expected a controller tool number 1..99, got {tool!r}")
    extra = set(p) - {"power", "speed_percent", "accel_percent", "settle_s", "pen_dwell_s",
                      "pen_output_bit", "safe_z_mm", "motor_off", "pen_signal", "tool_number"}
    if extra:
        log.warning("%s: program: ignoring unknown fields %s", path, ", ".join(sorted(extra)))
    return ProgramSettings(power, sp, ac, settle, dwell, bit, safe, moff, sig, tool)
