"""Export a calibration to the forms ROS and OLP tools import.

URDF (metres and radians, as URDF wants): ``sheet -> joint1 -> link1 -> joint2 -> link2 ->
pen``. ``joint1``'s origin is the calibrated base in the sheet frame, rotated by ``z1``
about z; ``joint2``'s origin is ``L1`` along link 1, rotated by ``z2``; the pen is ``L2``
along link 2. So a URDF consumer commanding ``q`` reproduces the calibrated base model
exactly. Each joint carries a ``<calibration rising="0"/>`` element: the commanded zero is
where the calibrated origin puts it.

With a tool (``params.tool_mm``, contract "Joint 4 and the tool") the chain goes on past
link 2 as a SCARA's does: ``link2 -> joint3 (prismatic, z, at L2 along link 2) -> quill ->
joint4 (revolute about z) -> flange -> tool (fixed, at tool_mm in the flange frame) ->
pen``, so ``pen`` is the calibrated pen tip for any ``q1, q2, q3, q4`` (joint 3 moves the
pen vertically only). Joint 3's travel and joint 4's range are the robot file's
``joint3_limits_mm`` and ``joint4_limits_deg`` (``export --robot``), else the defaults of
:mod:`vision_cal.model.motion`. Without a tool the chain ends at ``pen_tip`` as before.

Effects a URDF cannot hold (backlash, gear-ratio and cyclic errors, sheet scale) go in a
side file ``<name>.effects.yaml``: the format's effect names and parameters, in degrees and
the format's units, with the model they act on documented in its header.
"""

from __future__ import annotations

import math
from pathlib import Path
from xml.sax.saxutils import quoteattr

import yaml

from vision_cal.dataset.io import atomic_write_text
from vision_cal.dataset.nominal import SIGN_CONVENTION, controller_offsets, offsets_text
# the defaults live in vision_cal.model.motion; report/ reads them through dataset/ (its rule)
from vision_cal.dataset.robot import JOINT3_LIMITS_MM, JOINT4_LIMITS_DEG, JOINT_LIMITS_DEG

EFFECTS_HEADER = """\
# Effects found by vision-cal that URDF cannot express (see docs/conventions.md).
# Joint effects add to the angle joint J really turns to, at the commanded angle q:
#   joint_backlash  -s * deg / 2     (s: approach sign, the joint's last motion)
#   joint_scale     scale * q
#   joint_cyclic    deg * sin(harmonic * q + phase_deg)
# sheet_affine: printed sheet coordinates = matrix @ arm position (about the sheet origin).
"""




def _tool_chain(L2: float, tool_mm, limits3_mm, limits4_deg) -> str:
    """Joints 3 and 4 and the tool frame (metres, radians), ending at link ``pen``."""
    tx, ty = (v / 1000.0 for v in tool_mm)
    lo3, hi3 = (v / 1000.0 for v in limits3_mm)
    lo4, hi4 = (math.radians(v) for v in limits4_deg)
    return f"""  <joint name="joint3" type="prismatic">
    <parent link="link2"/>
    <child link="quill"/>
    <origin xyz="{L2:.9f} 0 0" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="{lo3:.6f}" upper="{hi3:.6f}" effort="100" velocity="1"/>
  </joint>
  <joint name="joint4" type="revolute">
    <parent link="quill"/>
    <child link="flange"/>
    <origin xyz="0 0 0" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="{lo4:.9f}" upper="{hi4:.9f}" effort="100" velocity="6"/>
    <calibration rising="0.0"/>
  </joint>
  <joint name="tool" type="fixed">
    <parent link="flange"/>
    <child link="pen"/>
    <origin xyz="{tx:.9f} {ty:.9f} 0" rpy="0 0 0"/>
  </joint>
"""


def urdf_text(doc: dict, *, name: str = "scara_calibrated",
              limits_deg=JOINT_LIMITS_DEG, limits3_mm=JOINT3_LIMITS_MM,
              limits4_deg=JOINT4_LIMITS_DEG) -> str:
    p = doc["params"]
    bx, by = (v / 1000.0 for v in p["base_mm"])
    z1, z2 = (math.radians(v) for v in p["joint_zero_deg"])
    L1, L2 = p["L1_mm"] / 1000.0, p["L2_mm"] / 1000.0

    def revolute(name, parent, child, x, y, yaw, j):
        lo, hi = (math.radians(v) for v in limits_deg[j])
        return f"""  <joint name="{name}" type="revolute">
    <parent link="{parent}"/>
    <child link="{child}"/>
    <origin xyz="{x:.9f} {y:.9f} 0" rpy="0 0 {yaw:.12f}"/>
    <axis xyz="0 0 1"/>
    <limit lower="{lo:.9f}" upper="{hi:.9f}" effort="100" velocity="3"/>
    <calibration rising="0.0"/>
  </joint>
"""

    if p.get("tool_mm") is not None:
        extra_links = '  <link name="quill"/>\n  <link name="flange"/>\n'
        tip = _tool_chain(L2, p["tool_mm"], limits3_mm, limits4_deg)
    else:
        extra_links = ""
        tip = f"""  <joint name="pen_tip" type="fixed">
    <parent link="link2"/>
    <child link="pen"/>
    <origin xyz="{L2:.9f} 0 0" rpy="0 0 0"/>
  </joint>
"""
    return f"""<?xml version="1.0"?>
<!-- written by vision-cal from a calibration ({doc.get('method', 'lsq')}); lengths in m -->
<robot name={quoteattr(name)}>
  <link name="sheet"/>
  <link name="link1"/>
  <link name="link2"/>
  <link name="pen"/>
{extra_links}{revolute("joint1", "sheet", "link1", bx, by, z1, 0)}{revolute("joint2", "link1", "link2", L1, 0.0, z2, 1)}{tip}</robot>
"""


def _effects(doc: dict) -> list[dict]:
    """The effects with their parameters and std (the evidence stays in the report)."""
    return [{k: v for k, v in e.items() if k != "evidence"} for e in doc.get("effects", [])]


def _where(doc: dict, extrapolated=()) -> dict:
    """Where the model holds (calibration.json ``valid_for``) and, written with --force,
    the extrapolation the export was asked for (``extrapolated``)."""
    out = {}
    if isinstance(doc.get("valid_for"), dict):
        out["valid_for"] = doc["valid_for"]
    if extrapolated:
        out["extrapolated"] = list(extrapolated)
    return out


def effects_yaml(doc: dict, extrapolated=()) -> str:
    return EFFECTS_HEADER + yaml.safe_dump({"effects": _effects(doc),
                                            **_where(doc, extrapolated)}, sort_keys=False)


def calibration_yaml(doc: dict, extrapolated=()) -> str:
    """The controller's YAML: the model, and the offsets relative to the robot file (the
    nominal: vision_cal.dataset.nominal, its one sign convention)."""
    out = {"params": doc["params"], "std": doc.get("std"),
           "effects": _effects(doc),
           "residual_rms_mm": doc.get("residual_rms_mm"),
           "validation_rms_mm": doc.get("validation_rms_mm")}
    offsets = controller_offsets(doc)
    if offsets:
        out["nominal"] = doc.get("nominal")   # the robot file the controller runs
        out["controller_offsets"] = {"add_to_offset_deg": {
            f"joint{o['joint']}": o["add_to_offset_deg"] for o in offsets},
            "text": offsets_text(offsets), "sign_convention": SIGN_CONVENTION}
    out.update(_where(doc, extrapolated))
    return EFFECTS_HEADER + yaml.safe_dump(out, sort_keys=False)


def effects_path(urdf) -> Path:
    """The effects side file written beside a URDF: ``ROBOT.effects.yaml``."""
    urdf = Path(urdf)
    return urdf.with_name(urdf.stem + ".effects.yaml")


def export(doc: dict, *, urdf=None, yaml_path=None, limits_deg=None,
           limits4_deg=None, limits3_mm=None, extrapolated=()) -> list[Path]:
    """``limits_deg``: the URDF's joint limits [[lo, hi], [lo, hi]] (default: the
    calibration's ``joint_limits_deg``, else :data:`vision_cal.model.motion.JOINT_LIMITS_DEG`);
    ``limits4_deg`` and ``limits3_mm``: joint 4's [lo, hi] (deg) and joint 3's travel
    (mm) when the URDF has a tool (defaults :data:`vision_cal.model.motion.JOINT4_LIMITS_DEG`,
    :data:`vision_cal.model.motion.JOINT3_LIMITS_MM`; the robot file's ``joint4_limits_deg`` and
    ``joint3_limits_mm`` via ``export --robot``); ``extrapolated``: the lines saying what
    the export goes beyond calibration.json ``valid_for`` with (``--force``), written into
    the effects file and the YAML."""
    written = []
    if limits_deg is None:
        limits_deg = doc.get("joint_limits_deg") or JOINT_LIMITS_DEG
    if urdf:
        urdf = Path(urdf)
        written.append(atomic_write_text(urdf, urdf_text(
            doc, name=urdf.stem, limits_deg=limits_deg,
            limits4_deg=JOINT4_LIMITS_DEG if limits4_deg is None else limits4_deg,
            limits3_mm=JOINT3_LIMITS_MM if limits3_mm is None else limits3_mm)))
        side = effects_path(urdf)
        written.append(atomic_write_text(side, effects_yaml(doc, extrapolated)))
    if yaml_path:
        written.append(atomic_write_text(yaml_path, calibration_yaml(doc, extrapolated)))
    return written
