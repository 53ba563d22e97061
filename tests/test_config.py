"""The estimator's configuration: one documented object, recorded in calibration.json."""

import json
from dataclasses import replace

import pytest

from vision_cal.config import DEFAULT, DotConfig, SelectionConfig
from vision_cal.errors import VisionCalError
from vision_cal.measure import dots
from vision_cal.pipeline import calibrate_dataset


def test_modules_read_their_knobs_from_the_config():
    assert dots.INK_DARKENING == DEFAULT.dots.ink_darkening
    assert dots.MODEL_FLOOR_PX == DEFAULT.dots.model_floor_px


def test_calibration_json_says_how_it_was_obtained(paper_folder, tmp_path):
    calibrate_dataset(paper_folder, out_dir=tmp_path / "d")
    doc = json.loads((tmp_path / "d" / "calibration.json").read_text())
    assert doc["config"] == DEFAULT.to_json()
    assert doc["config"]["selection"]["alpha"] == 0.01
    cfg = replace(DEFAULT, selection=SelectionConfig(alpha=1e-3, k_folds=3, max_effects=1))
    calibrate_dataset(paper_folder, out_dir=tmp_path / "c", config=cfg)
    doc = json.loads((tmp_path / "c" / "calibration.json").read_text())
    assert doc["config"]["selection"] == dict(DEFAULT.to_json()["selection"], alpha=1e-3,
                                              k_folds=3, max_effects=1)
    assert doc["diagnosis"]["heldout"] == "3-fold cross-validation"


def test_a_config_that_would_be_ignored_is_refused(paper_folder, tmp_path):
    cfg = replace(DEFAULT, dots=DotConfig(ink_darkening=0.5))
    with pytest.raises(VisionCalError, match="config"):
        calibrate_dataset(paper_folder, out_dir=tmp_path, config=cfg)
