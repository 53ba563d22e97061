"""A calibration far from anything physical stops the run, naming the likely unit mistake
(issue 19): joints written in radians in session.json fit L1 = 13417 mm and a 78x
``sheet_affine``, which ``plan`` and ``export`` would then refuse. Checked before
calibration.json is written, so no such file is left behind.

Bounds (physics of a SCARA arm calibrated against its catalogue values):

- each fitted link within :data:`LINK_RATIO` (x0.7 .. x1.4) of the session's nominal
  length: a catalogue SCARA is never 30 % off its data sheet; the design tolerances are
  millimetres (robot file ``placement_tolerance.link_mm``);
- a ``sheet_affine`` scale within :data:`MAX_SHEET_SCALE` (5 %) of 1: paper shrinks by
  tenths of a per cent and printers scale by about one per cent.
"""

from __future__ import annotations

import math

import numpy as np

from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.errors import VisionCalError
from vision_cal.model.rms import rms_2d

LINK_RATIO = (0.7, 1.4)
MAX_SHEET_SCALE = 0.05
#: joints all within +-2 pi (with a small margin) look like radians
RADIAN_RANGE = 2 * math.pi + 0.01


def _likely_cause(joints_deg: np.ndarray, ratio: float) -> str:
    q = np.abs(np.asarray(joints_deg, float))
    if q.size and float(q.max()) <= RADIAN_RANGE and float(np.ptp(joints_deg, axis=0).max()) > 0:
        return (f"every joint angle is within +-{RADIAN_RANGE:.2f}: written in radians? "
                "joints_deg are degrees (multiply by 57.2958)")
    for factor, what in ((1000.0, "metres instead of millimetres"),
                         (25.4, "inches instead of millimetres")):
        for r in (factor, 1.0 / factor):
            if abs(ratio / r - 1.0) < 0.1:
                return f"lengths in {what}?"
    return "check the units of joints_deg (degrees) and of the robot block (mm)"


def check_plausible(cal: CalibrationResult, session) -> None:
    """Raise :class:`VisionCalError` (one line naming session.json) when the fitted
    calibration ``cal`` is implausible for ``session``'s nominal robot."""
    p = cal.params or {}
    nominal = session.robot
    for name, nom in (("L1_mm", nominal.L1_mm), ("L2_mm", nominal.L2_mm)):
        got = p.get(name)
        if got is None or nom <= 0:
            continue
        ratio = float(got) / float(nom)
        if not (LINK_RATIO[0] <= ratio <= LINK_RATIO[1]):
            raise VisionCalError(
                f"implausible calibration: {name[:2]} = {float(got):.6g} mm against the "
                f"nominal {nom:g} mm ({ratio:.3g}x); {_likely_cause(session.joints_deg, ratio)}",
                file=str(session.path), field="marks")
    for e in cal.effects or ():
        if e.get("name") != "sheet_affine":
            continue
        m = np.asarray(e.get("matrix", [[1, 0], [0, 1]]), float)
        scale = np.linalg.svd(m, compute_uv=False)
        worst = float(scale[np.argmax(np.abs(scale - 1.0))])
        if abs(worst - 1.0) > MAX_SHEET_SCALE:
            raise VisionCalError(
                f"implausible calibration: the sheet appears scaled {worst:.3g}x (paper and "
                f"printers stay within {100 * MAX_SHEET_SCALE:g} %); "
                f"{_likely_cause(session.joints_deg, worst)}",
                file=str(session.path), field="marks")


def check_links_against(cal: CalibrationResult, nominal, *, file: str,
                        robot_file: str) -> None:
    """A calibration.json given to plan for a robot (``design --pilot/--verify``) whose link
    lengths are far from the robot file's (x0.7 .. x1.4): one line naming the likely unit
    mistake (a file in metres), not the sheet's reach."""
    p = cal.params
    if not isinstance(p, dict):
        return
    for name in ("L1_mm", "L2_mm"):
        got, nom = p.get(name), getattr(nominal, name, None)
        if not isinstance(got, (int, float)) or not nom or nom <= 0:
            continue
        ratio = float(got) / float(nom)
        if not (LINK_RATIO[0] <= ratio <= LINK_RATIO[1]):
            cause = _unit_cause(ratio, "is it this robot's calibration?")
            raise VisionCalError(f"{name} = {float(got):.6g} against {nom:g} mm in the robot "
                                 f"file {robot_file} ({ratio:.3g}x): {cause}", file=file,
                                 field=f"params.{name}")


def _unit_cause(ratio: float, otherwise: str) -> str:
    """Why a link length is ``ratio`` times the robot file's: metres or inches where
    millimetres were meant (either way), else ``otherwise``."""
    return next((f"lengths in {what}?" for factor, what in
                 ((1000.0, "metres instead of millimetres"),
                  (25.4, "inches instead of millimetres"))
                 for r in (factor, 1.0 / factor) if abs(ratio / r - 1.0) < 0.1), otherwise)


def radians_given(joints_deg) -> bool:
    """Every joint angle within +-2 pi (and not all one value): joints written in radians."""
    q = np.asarray(joints_deg, float)
    return bool(q.size and float(np.abs(q).max()) <= RADIAN_RANGE
                and float(np.ptp(q.reshape(len(q), -1), axis=0).max()) > 0)


#: a calibration's own marks lie where its parameters put them within this (mm) plus
#: ``SELF_RMS_FACTOR`` x its residual RMS: a file in metres or radians is hundreds or tens
#: of mm off (L1 0.344 puts every mark near the base; z2 in radians turns link 2 by 8 deg,
#: 36 mm at 260 mm), a drift the model does not hold a fraction of a mm
SELF_TOLERANCE_MM = 1.0
SELF_RMS_FACTOR = 10.0


def own_marks_offset(model, doc: dict) -> tuple[float, float, str] | None:
    """(RMS mm, its fitted RMS mm, likely cause) of a calibration document's own marks
    (``measured_mm`` at ``joints_deg``) against where ``model`` puts them, when they lie
    beyond ``SELF_TOLERANCE_MM`` + ``SELF_RMS_FACTOR`` x its residual RMS (its units are
    not the marks' mm and degrees); None when they agree or there are fewer than 3."""
    marks = doc.get("marks") if isinstance(doc, dict) else None
    if not isinstance(marks, dict):
        return None
    q, s, xy = [], [], []
    for m in marks.values():
        if not (isinstance(m, dict) and m.get("status", "ok") == "ok" and m.get("role")
                in ("calibration", "validation", None)):
            continue
        try:
            qq = [float(x) for x in m["joints_deg"][:2]] + [float(m.get("j4_deg") or 0.0)]
            ss = [float(x) for x in (m.get("approach") or [1, 1])[:2]] + [1.0]
            pt = [float(x) for x in m["measured_mm"][:2]]
        except (KeyError, TypeError, ValueError, IndexError):
            continue
        if len(qq) == 3 and len(ss) == 3 and len(pt) == 2:
            q.append(qq), s.append(ss), xy.append(pt)
    if len(q) < 3:
        return None
    q, s, xy = np.array(q), np.array(s), np.array(xy)
    d = xy - model.predict(q if model.tool is not None else q[:, :2],
                           s if model.tool is not None else s[:, :2])
    off = rms_2d(d)
    res = (doc.get("residual_rms_mm") or {}).get("final_model")
    res = float(res) if isinstance(res, (int, float)) else 0.0
    bound = SELF_TOLERANCE_MM + SELF_RMS_FACTOR * res
    if off <= bound:
        return None
    jz = model.params.z1_deg, model.params.z2_deg
    hint = ("lengths in metres?" if max(model.params.L1_mm, model.params.L2_mm) < 10.0
            else "joint_zero_deg in radians?" if 0 < max(map(abs, jz)) <= 2 * np.pi
            else "params not in mm and degrees?")
    return off, res, hint


def check_units(model, doc: dict, *, file: str, nominal=None, nominal_of: str = "") -> None:
    """A calibration.json whose units are implausible (lengths in metres, angles in
    radians) refused before anything is written from it (``export``): one line naming the
    file and the field. Its links against ``nominal`` (the robot file's, else the file's
    own ``nominal`` block; x0.7 .. x1.4, :data:`LINK_RATIO`), its own marks against its
    parameters (:func:`own_marks_offset`), and ``joint_limits_deg`` that all lie within
    +-2 pi (a SCARA's joints travel hundreds of degrees: radians)."""
    p = model.params
    if nominal is not None:
        noms = {k: getattr(nominal, k, None) for k in ("L1_mm", "L2_mm")}
    else:
        noms = doc.get("nominal") if isinstance(doc.get("nominal"), dict) else {}
        nominal_of = "its nominal block"
    for name in ("L1_mm", "L2_mm"):
        got, nom = getattr(p, name), noms.get(name)
        if not isinstance(nom, (int, float)) or not nom > 0:
            continue
        ratio = float(got) / float(nom)
        if not LINK_RATIO[0] <= ratio <= LINK_RATIO[1]:
            cause = _unit_cause(ratio, "not this robot's calibration, or not in mm?")
            raise VisionCalError(f"implausible units: {float(got):.6g} against {nom:g} mm "
                                 f"({nominal_of}, {ratio:.3g}x): {cause}", file=file,
                                 field=f"params.{name}")
    off = own_marks_offset(model, doc)
    if off is not None:
        raise VisionCalError(f"implausible units: its own marks lie {off[0]:.3g} mm RMS from "
                             f"where its parameters put them (it fitted {off[1]:.3g} mm): "
                             f"{off[2]} calibration.json is in mm and degrees", file=file,
                             field="params")
    lim = doc.get("joint_limits_deg")
    try:
        a = np.asarray(lim, float)
    except (TypeError, ValueError):
        a = None
    if lim is not None and (a is None or a.shape != (2, 2) or not np.all(np.isfinite(a))):
        raise VisionCalError(f"expected [[lo, hi], [lo, hi]] in degrees, got {lim!r}",
                             file=file, field="joint_limits_deg")
    if a is not None and lim is not None and float(np.abs(a).max()) <= RADIAN_RANGE:
        raise VisionCalError(f"implausible units: every limit within +-{RADIAN_RANGE:.2f} "
                             f"({lim}): written in radians? joint_limits_deg are degrees "
                             "(multiply by 57.2958)", file=file, field="joint_limits_deg")
