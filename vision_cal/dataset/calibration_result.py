"""calibration.json as one typed value: :class:`CalibrationResult` (docs/format.md).

The pipeline builds it once (:func:`vision_cal.workflows.pipeline.document`), writes it once
(:meth:`CalibrationResult.write`) and whoever reads a calibration back without planning
with it (the report, history, verify) takes :meth:`CalibrationResult.from_json`; the
planner's strict reader of the model is :func:`vision_cal.dataset.calibration.load_calibration`.

The top level is typed field by field; the blocks the contract describes as free JSON
(``params``, ``effects`` entries, ``diagnosis``, ``marks`` entries, ...) stay JSON values,
as written. Keys this version does not know are kept in ``extra`` and written back, so a
file round-trips unchanged: ``CalibrationResult.from_json(d).to_json() == d``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from vision_cal.dataset.io import atomic_write_json, read_json

FORMAT = "vision-cal/calibration/1"


@dataclass(frozen=True)
class ModelRms:
    """``residual_rms_mm`` / ``validation_rms_mm``: RMS (mm) under the base and the final
    model; ``kind`` (validation only) how the held-out marks were chosen."""

    base_model: float | None
    final_model: float | None
    kind: str | None = None

    def to_json(self) -> dict:
        d = {"base_model": self.base_model, "final_model": self.final_model}
        if self.kind is not None:
            d["kind"] = self.kind
        return d

    @classmethod
    def from_json(cls, d: dict) -> "ModelRms":
        return cls(d.get("base_model"), d.get("final_model"), d.get("kind"))


@dataclass(frozen=True)
class CalibrationResult:
    """Everything calibration.json holds, in the order it is written. Optional blocks are
    None when absent (not written)."""

    method: str                               # "lsq" or "paper"
    config: dict                              # vision_cal.config.EstimatorConfig.to_json()
    params: dict                              # the calibrated base parameters
    std: dict                                 # their one-sigma std
    effects: tuple[dict, ...]                 # the contract's effect entries
    residual_rms_mm: ModelRms
    validation_rms_mm: ModelRms
    nominal: dict                             # the model the OLP had (robot file)
    home_deg: tuple[float, float]             # where plans start
    marks: dict                               # id -> mark entry
    images: tuple[dict, ...]                  # per photo: status, reason, counts
    verdict: dict | None = None               # diagnose/verdict.judge's block
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
    dataset: str | None = None                # the input folder (report_data, for the report)
    starting_model: dict | None = None        # the model the plan was placed with (a pilot's)
    valid_for: dict | None = None             # what it was calibrated for (dataset/valid_for)
    extra: dict = field(default_factory=dict)  # keys this version does not know
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
        return cls.from_json(read_json(Path(path)))


_TUPLES = ("effects", "images", "home_deg", "notes", "outliers", "missing_marks", "targets")
