"""Reading ``calibration.json`` back into a model (the planner's input)."""

from __future__ import annotations

from pathlib import Path

from vision_cal.dataset.io import read_json
from vision_cal.errors import VisionCalError
from vision_cal.kinematics import ScaraParams
from vision_cal.model import RobotModel, effect_from_json

ROBOT_EFFECTS = ("joint_backlash", "joint_scale", "joint_cyclic", "sheet_affine")


def load_calibration(path, *, which: str = "calibrated") -> tuple[RobotModel, dict]:
    """The calibrated model (base parameters and every robot effect found), or with
    ``which="nominal"`` the nominal model the calibration started from."""
    path = Path(path)
    doc = read_json(path)
    fmt = doc.get("format")
    if fmt != "vision-cal/calibration/1":
        raise VisionCalError(f"expected 'vision-cal/calibration/1', got {fmt!r}", file=str(path),
                             field="format")
    key = "params" if which == "calibrated" else "nominal"
    if key not in doc:
        raise VisionCalError("missing required field", file=str(path), field=key)
    try:
        params = ScaraParams.from_json(doc[key])
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise VisionCalError(f"malformed parameters: {e}", file=str(path), field=key) from e
    effects = []
    if which == "calibrated":
        for i, e in enumerate(doc.get("effects", [])):
            if isinstance(e, dict) and e.get("name") in ROBOT_EFFECTS:
                try:
                    effects.append(effect_from_json(e, where=f"effects[{i}]"))
                except VisionCalError as err:
                    raise VisionCalError(err.reason, file=str(path), field=err.field) from err
    return RobotModel(params, tuple(effects)), doc
