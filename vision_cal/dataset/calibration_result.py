"""calibration.json as one typed value: :class:`CalibrationResult` (docs/format.md), its one
writer and its one reader.

The estimator builds it once (:func:`vision_cal.estimate.document.document`), typed from the
fit to the file, and every calibration.json is written by :meth:`CalibrationResult.write`
(the pen's, the placements', the arm camera's, the hand-eye's) and read by
:meth:`CalibrationResult.read` (the planner, design, verify, locate, export, the report,
history: ``tests/test_architecture.py`` finds any other reader or writer of the file).
Reading is strict, as ``session.json``'s is, with the same typed helpers
(:class:`vision_cal.dataset.fields.FieldReader`): a calibration another program wrote, or
one edited by hand, either gives the values it describes or fails with one line naming the
file and the field. Nothing is silently dropped: an effect the planner cannot honour is an
error, not a model without it. :meth:`CalibrationResult.robot_model` is the model it
describes (:func:`vision_cal.dataset.calibration.load_calibration`: the planner's input).

The top level is typed field by field; the blocks the contract describes as free JSON
(``params``, ``effects`` entries, ``diagnosis``, ``marks`` entries, ...) stay JSON values,
as written. A method's own blocks (:data:`METHODS_EXTRA`) and keys this version does not
know are kept in ``extra`` and written back, so a file round-trips unchanged:
``CalibrationResult.from_json(d).to_json() == d`` (same keys and values). Every field but
``format`` is optional: a placement calibration, the arm camera's and the pose pairs' write
what they have. :data:`FORMAT` is the one spelling of the format string.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from vision_cal.dataset.fields import MAX_JOINT_DEG, FieldReader
from vision_cal.dataset.io import as_json, atomic_write_json, read_json
from vision_cal.errors import VisionCalError
from vision_cal.model.joint_terms import check_feature
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import RobotModel, Tool, effect_from_json

FORMAT = "vision-cal/calibration/1"   # the one spelling of calibration.json's ``format``

# The blocks each method writes beyond the typed fields, kept in ``extra`` (docs/format.md,
# "Method-specific blocks"): the lsq / paper pipeline writes ``print``; the others are the
# placement calibration's (robot frame, and each placement's sub-folder file), the arm
# camera's and the pose pairs' (vision-cal handeye).
METHODS_EXTRA = {
    "lsq": ("print",),
    "paper": ("print",),
    "lsq-placements": ("frame", "placements", "placement"),
    "arm_camera": ("not_identifiable", "pose_rms", "poses"),
    "pose_pairs": ("poses_file", "units_read", "mount", "not_identifiable", "pairs",
                   "pair_rms", "pair_scatter", "pair_checks"),
}


@dataclass(frozen=True)
class ModelRms:
    """``residual_rms_mm`` / ``validation_rms_mm``: RMS (mm) under the base and the final
    model; ``kind`` (validation only) how the held-out marks were chosen."""

    base_model: float | None
    final_model: float | None
    kind: str | None = None
    # False: the block has no ``base_model`` key (a placement calibration's: one model)
    base_written: bool = True

    def to_json(self) -> dict:
        d = {"base_model": self.base_model} if self.base_written else {}
        d["final_model"] = self.final_model
        if self.kind is not None:
            d["kind"] = self.kind
        return d

    @classmethod
    def from_json(cls, d: dict) -> "ModelRms":
        return cls(d.get("base_model"), d.get("final_model"), d.get("kind"),
                   base_written="base_model" in d)


@dataclass(frozen=True)
class CalibrationResult:
    """Everything calibration.json holds, in the order it is written. Optional blocks are
    None when absent (not written)."""

    method: str | None = None                 # "lsq", "paper", or a METHODS_EXTRA key
    config: dict | None = None                # vision_cal.config.EstimatorConfig.to_json()
    params: dict | None = None                # the calibrated base parameters
    std: dict | None = None                   # their one-sigma std
    effects: tuple[dict, ...] | None = None   # the contract's effect entries
    residual_rms_mm: ModelRms | None = None
    validation_rms_mm: ModelRms | None = None
    nominal: dict | None = None               # the model the OLP had (robot file)
    home_deg: tuple[float, float] | None = None   # where plans start
    marks: dict | None = None                 # id -> mark entry
    images: tuple[dict, ...] | None = None    # per photo: status, reason, counts
    verdict: dict | None = None               # estimate/verdict.judge's block
    base_model_params: dict | None = None
    base_model_std: dict | None = None
    initial_guess: dict | None = None
    identifiability: dict | None = None
    diagnosis: dict | None = None
    notes: tuple[str, ...] | None = None
    residual_scale: float | None = None
    covariance: dict | None = None
    tool: dict | None = None                  # joint 4's tool (issue 21)
    outliers: tuple[str, ...] | None = None
    circles: dict | None = None               # the paper's circle fits
    printed_content: list | None = None
    joint_limits_deg: list | None = None
    noise_floor_mm: float | None = None
    missing_marks: tuple[str, ...] | None = None
    targets: tuple[dict, ...] | None = None
    truth_comparison: dict | None = None
    printer_scale: dict | None = None
    cameras: list | None = None
    sheet: dict | None = None                 # which printed sheet (sheet_identity)
    dataset: str | None = None                # the input folder (estimate/report_data, for the report)
    starting_model: dict | None = None        # the model the plan was placed with (a pilot's)
    valid_for: dict | None = None             # what it was calibrated for (dataset/valid_for)
    # the method-specific blocks (METHODS_EXTRA, docs/format.md) and the keys this
    # version does not know, written after the typed fields in their own order
    extra: dict = field(default_factory=dict)
    format: str = FORMAT
    #: the file it was read from (:meth:`read`; not written): what its errors name
    path: str | None = field(default=None, compare=False)

    # the written order: format first, then the fields in the order the file has had
    _ORDER = ("format", "method", "config", "params", "std", "effects", "residual_rms_mm",
              "validation_rms_mm", "base_model_params", "base_model_std", "initial_guess",
              "identifiability", "diagnosis", "notes", "residual_scale", "covariance",
              "outliers", "circles", "tool", "nominal", "starting_model", "home_deg", "printed_content",
              "joint_limits_deg", "noise_floor_mm", "marks", "missing_marks", "images",
              "targets", "truth_comparison", "printer_scale", "cameras", "valid_for", "verdict",
              "dataset", "sheet")

    def __post_init__(self):
        # JSON lists and blocks as written are taken as the typed values
        for name in _TUPLES:
            v = getattr(self, name)
            if isinstance(v, list):
                object.__setattr__(self, name, tuple(v))
        for name in ("residual_rms_mm", "validation_rms_mm"):
            v = getattr(self, name)
            if isinstance(v, dict):
                object.__setattr__(self, name, ModelRms.from_json(v))

    def to_json(self) -> dict:
        out: dict[str, Any] = {}
        for name in self._ORDER:
            v = getattr(self, name)
            if v is None:
                continue
            if isinstance(v, ModelRms):
                v = v.to_json()
            elif isinstance(v, tuple):
                v = list(v)
            out[name] = v
        out.update(self.extra)
        return out

    @classmethod
    def from_json(cls, d: dict, *, path=None) -> "CalibrationResult":
        """The document ``d`` as one value, unchecked (what a run built; a file is
        :meth:`read`). ``path``: where it came from, for the errors it names."""
        known = {f.name for f in fields(cls)} - {"extra", "path"}
        kw = {name: d[name] for name in known & set(d)}
        return cls(**kw, extra={k: v for k, v in d.items() if k not in known},
                   path=None if path is None else str(path))

    def as_written(self) -> "CalibrationResult":
        """The values exactly as :meth:`write` puts them in the file and :meth:`read` gives
        them back (NaN as null, numpy numbers as Python's, tuples as lists)."""
        return CalibrationResult.from_json(as_json(self.to_json()), path=self.path)

    def write(self, path) -> Path:
        """calibration.json, atomically (nothing half-written): its one writer."""
        return atomic_write_json(Path(path), self.to_json())

    @classmethod
    def read(cls, path) -> "CalibrationResult":
        """calibration.json at ``path``, its one reader: the format, and every field a
        reader of it uses (``params``, ``nominal``, ``std``, ``effects``, ``home_deg``,
        ``params.tool_mm``) checked where present; the first bad one raises
        :class:`VisionCalError` naming the file and the field."""
        path = Path(path)
        doc = read_json(path, what="calibration")
        r = FieldReader(str(path))
        fmt = r.get(doc, "format", "")
        if fmt != FORMAT:
            r.fail("format", f"expected {FORMAT!r}, got {fmt!r}")
        if "params" in doc:
            _read_model(r, doc["params"], doc.get("effects", []), "params")
        else:                             # the effects alone (a camera's calibration)
            _read_effects(r, doc.get("effects", []))
        if "nominal" in doc:
            _read_model(r, doc["nominal"], None, "nominal")
        if doc.get("std") is not None:
            _read_std(r, doc["std"], "std")
        if doc.get("home_deg") is not None:
            r.angles(doc["home_deg"], "home_deg")
        return cls.from_json(doc, path=path)

    def robot_model(self, which: str = "calibrated") -> RobotModel:
        """The calibrated model (base parameters, the tool and every robot effect found), or
        with ``which="nominal"`` the nominal model the calibration started from; a missing
        block raises :class:`VisionCalError` naming the file and the field."""
        r = FieldReader(self.path or "calibration.json")
        key = "nominal" if which == "nominal" else "params"
        block = getattr(self, key)
        return _read_model(r, r.get({} if block is None else {key: block}, key, ""),
                           None if key == "nominal" else list(self.effects or ()), key)


# --------------------------------------------------------------------------- the reader

ROBOT_EFFECTS = ("joint_backlash", "joint_scale", "joint_cyclic", "sheet_affine", "joint_terms")
#: effects of the contract that do not act on the robot (the camera's, the paper's height,
#: what nothing explains): read, never planned with
OTHER_EFFECTS = ("lens_distortion", "sheet_height", "unexplained", "drift")
#: the largest effects a calibration can plausibly report (a joint error of 90 degrees, a
#: gear ratio off by half, a sheet scaled by half, is a broken file, not a robot)
MAX_EFFECT_DEG = 90.0
MAX_SCALE = 0.5


def read_params(r: FieldReader, obj, where: str) -> ScaraParams:
    """The base parameters block (``params``, ``nominal``), every field checked."""
    L1 = r.length(r.get(obj, "L1_mm", where), f"{where}.L1_mm", positive=True)
    L2 = r.length(r.get(obj, "L2_mm", where), f"{where}.L2_mm", positive=True)
    z = r.angles(r.get(obj, "joint_zero_deg", where), f"{where}.joint_zero_deg")
    b = r.point(r.get(obj, "base_mm", where), f"{where}.base_mm")
    return ScaraParams(L1, L2, z[0], z[1], b[0], b[1])


def _read_effect(r: FieldReader, e, where: str):
    """One ``effects[]`` entry: an effect of the robot model, or None for one that is not."""
    name = r.string(r.get(e, "name", where), f"{where}.name")
    if name in OTHER_EFFECTS:
        return None
    if name not in ROBOT_EFFECTS:
        r.fail(f"{where}.name", f"unknown effect {name!r} (expected one of "
                                f"{', '.join(ROBOT_EFFECTS + OTHER_EFFECTS)})")
    small_deg = dict(lo=-MAX_EFFECT_DEG, hi=MAX_EFFECT_DEG, what="angle in degrees")
    if name != "sheet_affine":
        j = r.get(e, "joint", where)
        joints = (1, 2, 4) if name in ("joint_backlash", "joint_scale") else (1, 2)
        if j not in joints or isinstance(j, bool):
            r.fail(f"{where}.joint",
                   f"expected {', '.join(map(str, joints[:-1]))} or {joints[-1]}, got {j!r}")
    if name == "joint_backlash":
        r.number(r.get(e, "deg", where), f"{where}.deg", **small_deg)
    elif name == "joint_scale":
        r.number(r.get(e, "scale", where), f"{where}.scale", lo=-MAX_SCALE, hi=MAX_SCALE,
                 what="scale")
    elif name == "joint_terms":
        terms = r.list_(r.get(e, "terms", where), f"{where}.terms", nonempty=True)
        for i, t in enumerate(terms):
            w = f"{where}.terms[{i}]"
            if not isinstance(t, dict):
                r.fail(w, f"expected {{feature, coef}}, got {t!r}")
            try:
                check_feature(r.get(t, "feature", w), f"{w}.feature")
            except VisionCalError as err:
                r.fail(err.field, err.reason)
            r.number(r.get(t, "coef", w), f"{w}.coef", lo=-MAX_EFFECT_DEG, hi=MAX_EFFECT_DEG,
                     what="coefficient (deg per feature unit)")
    elif name == "joint_cyclic":
        h = r.get(e, "harmonic", where)
        if h not in (1, 2) or isinstance(h, bool):
            r.fail(f"{where}.harmonic", f"expected 1 or 2, got {h!r}")
        r.number(r.get(e, "deg", where), f"{where}.deg", **small_deg)
        ph = r.get(e, "phase_deg", where, required=False)
        if ph is not None:
            r.number(ph, f"{where}.phase_deg", lo=-MAX_JOINT_DEG, hi=MAX_JOINT_DEG,
                     what="angle in degrees")
    else:  # sheet_affine
        rows = r.list_(r.get(e, "matrix", where), f"{where}.matrix")
        if len(rows) != 2:
            r.fail(f"{where}.matrix", "expected a 2x2 matrix")
        m = [r.vector(row, f"{where}.matrix[{i}]", 2, lo=-2.0, hi=2.0, what="matrix entry")
             for i, row in enumerate(rows)]
        det = m[0][0] * m[1][1] - m[0][1] * m[1][0]
        if not (1 - MAX_SCALE) ** 2 < det < (1 + MAX_SCALE) ** 2:
            r.fail(f"{where}.matrix", f"expected a sheet scaled by less than "
                                      f"{100 * MAX_SCALE:.0f} %, got determinant {det:.4g}")
        axis = e.get("axis", "fixed")
        if axis not in ("x", "y", "shear", "fixed"):
            r.fail(f"{where}.axis", f"expected x, y, shear or fixed, got {axis!r}")
    try:
        return effect_from_json(e, where=where)
    except VisionCalError as err:
        r.fail(err.field or where, err.reason)


def _read_std(r: FieldReader, obj, where: str) -> None:
    """``std``: like ``params``, each a non-negative number, or null where unknown."""
    if not isinstance(obj, dict):
        r.fail(where, f"expected an object, got {type(obj).__name__}")
    for k, n in (("L1_mm", 0), ("L2_mm", 0), ("joint_zero_deg", 2), ("base_mm", 2)):
        v = obj.get(k)
        for i, x in enumerate([v] if n == 0 else (v if isinstance(v, list) else [v])):
            w = f"{where}.{k}" + (f"[{i}]" if n else "")
            if x is not None:
                r.number(x, w, lo=0.0, hi=1e5, what="standard deviation")
        if n and v is not None and (not isinstance(v, list) or len(v) != n):
            r.fail(f"{where}.{k}", f"expected a list of {n} numbers or nulls")


def _read_effects(r: FieldReader, effects) -> list:
    """``effects``: each entry checked; the effects of the robot model (the others, a
    camera's or what nothing explains, are read and left out)."""
    out = []
    for i, e in enumerate(r.list_(effects, "effects")):
        eff = _read_effect(r, e, f"effects[{i}]")
        if eff is not None:
            out.append(eff)
    return out


def _read_model(r: FieldReader, params, effects, where: str) -> RobotModel:
    """The model a ``params`` block describes, with the robot effects of ``effects`` and the
    tool of ``params.tool_mm`` (contract "Joint 4 and the tool": the pen off the joint-4
    axis), every field checked; a ``nominal`` block (``effects`` None) is the base model
    alone."""
    base = read_params(r, params, where)
    out = [] if effects is None else _read_effects(r, effects)
    tool = params.get("tool_mm") if isinstance(params, dict) else None
    if tool is not None:
        out.insert(0, Tool(tool_mm=r.point(tool, f"{where}.tool_mm")))
    return RobotModel(base, tuple(out))


_TUPLES = ("effects", "images", "home_deg", "notes", "outliers", "missing_marks", "targets")
