"""calibration.json as one typed value: what is written reads back the same."""

import json

import pytest

from vision_cal.dataset.calibration_result import CalibrationResult, ModelRms
from vision_cal.pipeline import calibrate_dataset


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
