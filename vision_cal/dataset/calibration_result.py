"""calibration.json as one typed value: :class:`CalibrationResult` (docs/format.md).

The pipeline builds it once (:func:`vision_cal.estimate.document.document`), writes it once
(:meth:`CalibrationResult.write`) and whoever reads a calibration back without planning
with it (the report, history, verify, design's ``--pilot`` and ``--verify``) takes
:meth:`CalibrationResult.from_json`; the planner's strict reader of the model is :func:`vision_cal.dataset.calibration.load_calibration`.

The top level is typed field by field; the blocks the contract describes as free JSON
(``params``, ``effects`` entries, ``diagnosis``, ``marks`` entries, ...) stay JSON values,
as written. A method's own blocks (:data:`METHODS_EXTRA`) and keys this version does not
know are kept in ``extra`` and written back, so a file round-trips unchanged:
``CalibrationResult.from_json(d).to_json() == d`` (same keys and values). Every field but
``format`` is optional: a placement calibration, the arm camera's and the pose pairs' write
what they have. Every writer of calibration.json builds one (the pipeline,
``estimate/placements``, ``camera/arm_session``, ``actions/handeye``); :data:`FORMAT` is
the one spelling of the format string.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from vision_cal.dataset.io import atomic_write_json, read_json

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
    def from_json(cls, d: dict) -> "CalibrationResult":
        known = {f.name for f in fields(cls)} - {"extra"}
        kw = {name: d[name] for name in known & set(d)}
        return cls(**kw, extra={k: v for k, v in d.items() if k not in known})

    def write(self, path) -> Path:
        """calibration.json, atomically (nothing half-written)."""
        return atomic_write_json(Path(path), self.to_json())

    @classmethod
    def read(cls, path) -> "CalibrationResult":
        return cls.from_json(read_json(Path(path), what="calibration"))


_TUPLES = ("effects", "images", "home_deg", "notes", "outliers", "missing_marks", "targets")
