"""A ``calibration.json`` as the planner takes it: the model it describes and its document
(:func:`load_calibration`), read by its one reader
(:meth:`vision_cal.dataset.calibration_result.CalibrationResult.read`, strict: one line
naming the file and the field for anything wrong), a calibration of several placements
refused where one sheet's is needed (:func:`refuse_robot_frame`), a camera's calibration
without a robot model (:func:`load_calibration_or_camera`).
"""

from __future__ import annotations

from pathlib import Path

from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.errors import VisionCalError
from vision_cal.model.robot import RobotModel


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
    ``which="nominal"`` the nominal model the calibration started from, and the document
    as written.

    Read by :meth:`CalibrationResult.read` (every field a reader of this file uses checked;
    the first bad one raises :class:`VisionCalError` naming the file and the field).
    ``sheet_frame``: the caller needs one sheet's calibration (a robot-frame one of several
    placements is refused, :func:`refuse_robot_frame`)."""
    cal = CalibrationResult.read(path)
    return _model_of(cal, which, sheet_frame), cal.to_json()


def _model_of(cal: CalibrationResult, which: str, sheet_frame: bool) -> RobotModel:
    if sheet_frame:
        refuse_robot_frame(cal, cal.path)
    return cal.robot_model(which)


#: calibrations of a camera alone (no robot model: no ``params``): a hand-eye's
CAMERA_ONLY_METHODS = ("handeye_photos", "pose_pairs")


def load_calibration_or_camera(path, *, sheet_frame: bool = True
                               ) -> tuple[RobotModel | None, dict]:
    """:func:`load_calibration`, or for a calibration of a camera alone (a hand-eye's:
    ``method`` in :data:`CAMERA_ONLY_METHODS`, no ``params``) no model and the document
    (its cameras are checked by whoever reads them)."""
    cal = CalibrationResult.read(path)
    if cal.method in CAMERA_ONLY_METHODS and cal.params is None:
        return None, cal.to_json()
    return _model_of(cal, "calibrated", sheet_frame), cal.to_json()

