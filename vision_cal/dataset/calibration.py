"""Reading ``calibration.json`` back into a model (the planner's input).

Validated as strictly as ``session.json`` and with the same typed helpers
(:class:`vision_cal.dataset.fields.FieldReader`): a calibration another program wrote, or
one edited by hand, either gives the model it describes or fails with one line naming the
file and the field. Nothing is silently dropped: an effect the planner cannot honour is an
error, not a model without it.
"""

from __future__ import annotations

from pathlib import Path

from vision_cal.dataset.calibration_result import FORMAT, CalibrationResult
from vision_cal.dataset.io import read_json
from vision_cal.dataset.valid_for import build as build_valid_for
from vision_cal.dataset.fields import MAX_JOINT_DEG, FieldReader
from vision_cal.errors import VisionCalError
from vision_cal.model.joint_terms import check_feature
from vision_cal.model.kinematics import ScaraParams
from vision_cal.model.robot import RobotModel, Tool, effect_from_json

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


def refuse_robot_frame(doc, path) -> None:
    """A robot-frame calibration of several placements (``calibrate --joint``'s top
    calibration.json) given where one sheet's calibration is needed (plan, design, verify,
    locate): one line pointing at the placements' own files. ``doc``: the
    :class:`CalibrationResult`, or the document as read (``placements`` is a method's
    block: a CalibrationResult keeps it in ``extra``)."""
    blocks = doc.extra if isinstance(doc, CalibrationResult) else doc
    if not isinstance(blocks, dict) or not isinstance(blocks.get("placements"), list):
        return
    names = [p.get("folder") for p in blocks["placements"] if isinstance(p, dict)]
    here = Path(path).parent
    subs = [str(here / n / "calibration.json") for n in names if isinstance(n, str)]
    raise VisionCalError("is the robot-frame calibration of several placements (calibrate "
                         "--joint): give the placement's own calibration.json, in the sheet "
                         "frame of the sheet you draw on" + (f" ({', '.join(subs)})"
                                                             if subs else ""), file=str(path))


def load_calibration(path, *, which: str = "calibrated",
                     sheet_frame: bool = True) -> tuple[RobotModel, dict]:
    """The calibrated model (base parameters and every robot effect found), or with
    ``which="nominal"`` the nominal model the calibration started from.

    Every field a reader of this file uses is checked (``params``, ``nominal``, ``std``,
    ``effects``, ``home_deg``); the first bad one raises :class:`VisionCalError` naming the
    file and the field. ``sheet_frame``: the caller needs one sheet's calibration (a
    robot-frame one of several placements is refused, :func:`refuse_robot_frame`)."""
    path = Path(path)
    doc = read_json(path, what="calibration")
    if sheet_frame:
        refuse_robot_frame(doc, path)
    r = FieldReader(str(path))
    fmt = r.get(doc, "format", "")
    if fmt != FORMAT:
        r.fail("format", f"expected {FORMAT!r}, got {fmt!r}")
    params = read_params(r, r.get(doc, "params", ""), "params")
    if "nominal" in doc or which == "nominal":
        nominal = read_params(r, r.get(doc, "nominal", ""), "nominal")
    if doc.get("std") is not None:
        _read_std(r, doc["std"], "std")
    effects = []
    for i, e in enumerate(r.list_(doc.get("effects", []), "effects")):
        eff = _read_effect(r, e, f"effects[{i}]")
        if eff is not None:
            effects.append(eff)
    if doc.get("home_deg") is not None:
        r.angles(doc["home_deg"], "home_deg")
    tool = doc["params"].get("tool_mm") if isinstance(doc["params"], dict) else None
    if tool is not None:   # contract "Joint 4 and the tool": the pen off the joint-4 axis
        effects.insert(0, Tool(tool_mm=r.point(tool, "params.tool_mm")))
    if which == "calibrated":
        return RobotModel(params, tuple(effects)), doc
    return RobotModel(nominal, ()), doc


#: calibrations of a camera alone (no robot model: no ``params``): a hand-eye's
CAMERA_ONLY_METHODS = ("handeye_photos", "pose_pairs")


def load_calibration_or_camera(path, *, sheet_frame: bool = True
                               ) -> tuple[RobotModel | None, dict]:
    """:func:`load_calibration`, or for a calibration of a camera alone (a hand-eye's:
    ``method`` in :data:`CAMERA_ONLY_METHODS`, no ``params``) no model and the document
    (its format checked; its cameras are checked by whoever reads them)."""
    path = Path(path)
    doc = read_json(path, what="calibration")
    if (isinstance(doc, dict) and doc.get("method") in CAMERA_ONLY_METHODS
            and "params" not in doc):
        r = FieldReader(str(path))
        fmt = r.get(doc, "format", "")
        if fmt != FORMAT:
            r.fail("format", f"expected {FORMAT!r}, got {fmt!r}")
        return None, doc
    return load_calibration(path, sheet_frame=sheet_frame)


def joints_covered_deg(doc: dict) -> list[tuple[float, float]] | None:
    """The commanded range ``[(lo, hi), (lo, hi)]`` (deg) of joints 1 and 2 over the marks a
    calibration fitted or held out (calibration.json ``marks[].joints_deg``; unreliable marks
    left out), or None when the document does not say. The model is measured inside it and
    extrapolated outside: an error once per turn of joint 1 looks like a gear-ratio error
    over the 135 deg one sheet spans, and a plan beyond the range meets the difference
    (``bench/tool_joint4.py --alone``: 0.16-0.21 mm where the range itself gave 0.02)."""
    vf = build_valid_for(doc)   # one owner: calibration.json valid_for.joints_deg
    return None if vf is None else [tuple(r) for r in vf["joints_deg"]]

