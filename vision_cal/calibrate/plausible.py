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

from vision_cal.errors import VisionCalError

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


def check_plausible(doc: dict, session) -> None:
    """Raise :class:`VisionCalError` (one line naming session.json) when the fitted
    ``doc`` is implausible for ``session``'s nominal robot."""
    p = doc.get("params", {})
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
    for e in doc.get("effects", []):
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


def check_links_against(doc: dict, nominal, *, file: str, robot_file: str) -> None:
    """A calibration.json given to plan for a robot (``design --pilot/--verify``) whose link
    lengths are far from the robot file's (x0.7 .. x1.4): one line naming the likely unit
    mistake (a file in metres), not the sheet's reach."""
    p = doc.get("params") if isinstance(doc, dict) else None
    if not isinstance(p, dict):
        return
    for name in ("L1_mm", "L2_mm"):
        got, nom = p.get(name), getattr(nominal, name, None)
        if not isinstance(got, (int, float)) or not nom or nom <= 0:
            continue
        ratio = float(got) / float(nom)
        if not (LINK_RATIO[0] <= ratio <= LINK_RATIO[1]):
            cause = next((f"lengths in {what}?" for factor, what in
                          ((1000.0, "metres instead of millimetres"),
                           (25.4, "inches instead of millimetres"))
                          for r in (factor, 1.0 / factor) if abs(ratio / r - 1.0) < 0.1),
                         "is it this robot's calibration?")
            raise VisionCalError(f"{name} = {float(got):.6g} against {nom:g} mm in the robot "
                                 f"file {robot_file} ({ratio:.3g}x): {cause}", file=file,
                                 field=f"params.{name}")


def radians_given(joints_deg) -> bool:
    """Every joint angle within +-2 pi (and not all one value): joints written in radians."""
    q = np.asarray(joints_deg, float)
    return bool(q.size and float(np.abs(q).max()) <= RADIAN_RANGE
                and float(np.ptp(q.reshape(len(q), -1), axis=0).max()) > 0)
