"""calibration.json as one typed value: what is written reads back the same."""

import json
from pathlib import Path

import pytest

from vision_cal.dataset.calibration_result import (FORMAT, METHODS_EXTRA, CalibrationResult,
                                                   ModelRms)
from vision_cal.actions.pipeline import calibrate_dataset


@pytest.mark.parametrize("method", ["paper", "lsq"])
def test_the_written_file_reads_back_unchanged(paper_folder, tmp_path, method):
    run = calibrate_dataset(paper_folder, out_dir=tmp_path, method=method)
    written = json.loads(run.out_path.read_text())
    back = CalibrationResult.from_json(written)
    assert back.to_json() == written
    assert back == CalibrationResult.from_json(run.result.to_json())
    assert isinstance(back.residual_rms_mm, ModelRms) and back.method == method
    assert back.residual_rms_mm.final_model == written["residual_rms_mm"]["final_model"]
    assert run.document == written


def test_unknown_keys_are_kept():
    d = {"method": "lsq", "config": {}, "params": {}, "std": {}, "effects": [],
         "residual_rms_mm": {"base_model": 1.0, "final_model": 0.5},
         "validation_rms_mm": {"base_model": None, "final_model": None, "kind": "none"},
         "nominal": {}, "home_deg": [0.0, 0.0], "marks": {}, "images": [],
         "from_another_program": {"x": 1}, "format": "vision-cal/calibration/1"}
    r = CalibrationResult.from_json(d)
    assert r.extra == {"from_another_program": {"x": 1}}
    assert r.to_json() == d


def test_every_field_is_written_and_read():
    """A value in every field comes back: no field is left out of to_json or from_json."""
    from dataclasses import fields

    d = {f.name: {"v": f.name} for f in fields(CalibrationResult)
         if f.name not in ("extra", "path")}
    d.update(format="vision-cal/calibration/1", method="lsq",
             residual_rms_mm={"base_model": 1.0, "final_model": 0.5},
             validation_rms_mm={"base_model": 2.0, "final_model": 1.0, "kind": "none"},
             residual_scale=1.5, noise_floor_mm=0.01)
    for name in ("effects", "images", "home_deg", "notes", "outliers", "missing_marks",
                 "targets", "printed_content", "joint_limits_deg", "cameras"):
        d[name] = [name]
    r = CalibrationResult.from_json(d)
    assert r.extra == {} and r.to_json() == d


def test_a_method_writes_only_what_it_has_and_it_reads_back():
    """Every field is optional (a placement's file, the arm camera's, the pose pairs'): a
    ``residual_rms_mm`` with only ``final_model`` stays so, the method's own blocks are in
    ``extra`` (METHODS_EXTRA) and the file round-trips."""
    d = {"format": FORMAT, "method": "lsq-placements", "params": {"L1_mm": 1.0},
         "residual_rms_mm": {"final_model": 0.02}, "placement": {"folder": "a"}}
    r = CalibrationResult.from_json(d)
    assert r.residual_rms_mm.final_model == 0.02 and r.validation_rms_mm is None
    assert r.extra == {"placement": {"folder": "a"}}
    assert set(r.extra) <= set(METHODS_EXTRA["lsq-placements"])
    assert r.to_json() == d
    assert CalibrationResult(method="pose_pairs").to_json() == {"format": FORMAT,
                                                               "method": "pose_pairs"}


def test_the_format_string_is_spelled_once():
    """``vision-cal/calibration/1`` is written out in dataset/calibration_result.py alone:
    every writer takes it from CalibrationResult, every reader checks against FORMAT."""
    root = Path(__file__).resolve().parents[2] / "vision_cal"
    spelled = [str(p.relative_to(root)) for p in root.rglob("*.py")
               if FORMAT in p.read_text(encoding="utf-8")]
    assert spelled == ["dataset/calibration_result.py"]
