"""One nominal: the robot file the user's controller runs (issue 29, one owner).

Every "nominal", "before" and "add to the controller" that vision-cal writes or prints
(calibration.json ``nominal``, the report, the console, ``export``, ``verify``) is relative
to the robot file, however many calibrations sit in between: the informative plan is
designed from a pilot's model, but the controller still runs the robot file, so its
offsets are the robot file's zeros minus the calibrated ones. The pilot's model is the
plan's *starting model* (calibration.json ``starting_model``), never "nominal".

``vision-cal design`` records the robot file's model in session.json
``design.nominal_robot`` (every stage); a session without it (written by hand, or by
another program) is its own nominal: its ``robot`` block.

The sign convention is one sentence (:data:`SIGN_CONVENTION`), used by the report, the
console, ``export`` and ``verify``; :func:`controller_offsets` and :func:`rezero_text`
are the only places that turn zeros into controller offsets.
"""

from __future__ import annotations

import math

#: the sign convention of joint angles, zeros and controller offsets (one sentence, one owner)
SIGN_CONVENTION = (
    "Joint angles are positive counter-clockwise seen from above (the pen side of the "
    "sheet). A controller joint offset c is added to every command before it reaches the "
    "joint: the joint turns to q + c. The calibrated zero z is the angle of the link at "
    "commanded zero (joint 1: from the sheet x axis, so z1 also holds the rotation "
    "between robot and sheet; joint 2: from link 1). So the offset that makes the robot "
    "file's zero true is the robot file's zero minus the calibrated zero.")

_BASE_KEYS = ("L1_mm", "L2_mm", "joint_zero_deg", "base_mm")


def _base(block: dict) -> dict:
    return {k: (list(block[k]) if isinstance(block[k], (list, tuple)) else block[k])
            for k in _BASE_KEYS}


def robot_file_params(session_raw: dict | None) -> dict | None:
    """The robot file's base parameters (``L1_mm``, ``L2_mm``, ``joint_zero_deg``,
    ``base_mm``) a designed session recorded (``design.nominal_robot``), or None when the
    session does not say (then its own ``robot`` block is the nominal)."""
    d = (session_raw or {}).get("design") if isinstance(session_raw, dict) else None
    nr = d.get("nominal_robot") if isinstance(d, dict) else None
    if not isinstance(nr, dict) or not all(k in nr for k in _BASE_KEYS):
        return None
    return _base(nr)


def nominal_blocks(session_raw: dict | None, session_params: dict) -> dict:
    """calibration.json's ``nominal`` (the robot file) and, when the session's robot block
    is another model (a pilot's calibration the informative plan was placed with),
    ``starting_model`` with ``source``: the blocks to add to the document."""
    rf = robot_file_params(session_raw)
    if rf is None or _same(rf, session_params):
        return {"nominal": dict(session_params)}
    d = session_raw.get("design") or {}
    src = d.get("pilot_calibration") or d.get("calibration")
    return {"nominal": rf,
            "starting_model": {**_base(session_params), "source": (
                f"the calibration {src}" if src else "the session.json robot block")}}


def _same(a: dict, b: dict) -> bool:
    def flat(d):
        out = []
        for k in _BASE_KEYS:
            v = d.get(k)
            out += list(v) if isinstance(v, (list, tuple)) else [v]
        return out
    fa, fb = flat(a), flat(b)
    return all(isinstance(x, (int, float)) and isinstance(y, (int, float))
               and abs(float(x) - float(y)) < 1e-9 for x, y in zip(fa, fb))


def _zero(block, j):
    z = (block or {}).get("joint_zero_deg") if isinstance(block, dict) else None
    if not isinstance(z, (list, tuple)) or len(z) < 2:
        return None
    v = z[j]
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None


def controller_offsets(doc: dict) -> list[dict]:
    """What to add to the controller's joint offsets so that the robot file's model is
    true: per joint ``{"joint", "add_to_offset_deg", "std_deg"}``, the robot file's zero
    (calibration.json ``nominal``) minus the calibrated one (:data:`SIGN_CONVENTION`)."""
    p, n, s = doc.get("params") or {}, doc.get("nominal") or {}, doc.get("std") or {}
    out = []
    for j in (0, 1):
        zc, zn = _zero(p, j), _zero(n, j)
        if zc is None or zn is None:
            continue
        out.append({"joint": j + 1, "add_to_offset_deg": zn - zc, "std_deg": _zero(s, j)})
    return out


def offsets_text(offsets: list[dict]) -> str:
    """The one sentence the report, the console and ``export`` print with the offsets."""
    return ("Either enter the calibrated model in the OLP (and leave the controller "
            "alone), or keep the robot file's model (the nominal) and add these to the "
            "controller's joint offsets so that it is true: "
            + ", ".join(f"joint {o['joint']}: {o['add_to_offset_deg']:+.4f} deg"
                        for o in offsets) + ".")


def rezero(joint: int, zero_moved_deg: float, calibrated_zero_deg: float) -> dict:
    """``verify``'s re-zeroing of a joint whose zero moved by ``zero_moved_deg`` since the
    calibration, in :data:`SIGN_CONVENTION` (the report's: what to add to the controller's
    joint offset): verify.json ``rezero`` and its two actions, one sentence each
    (``actions``: the controller's offset, or the OLP's zero)."""
    add = -float(zero_moved_deg)
    olp = float(calibrated_zero_deg) + float(zero_moved_deg)
    return {"joint": int(joint), "zero_moved_deg": float(zero_moved_deg),
            "add_to_offset_deg": add, "olp_zero_deg": olp,
            "actions": [f"on the controller: add {add:+.4f} deg to joint {joint}'s offset (an "
                        "offset is added to every command: verify.json sign_convention)",
                        f"or in the OLP: enter z{joint} = {olp:.4f} deg (the calibrated "
                        f"{calibrated_zero_deg:.4f} deg plus the move) and leave the "
                        "controller alone"]}