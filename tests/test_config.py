"""The estimator's configuration: one documented object, read when used, recorded in
calibration.json."""

import json
from dataclasses import fields, replace

from tests.measure import synth_measure as sm
from vision_cal.config import (DEFAULT, DotConfig, EstimatorConfig, SelectionConfig,
                               SheetFitConfig)
from vision_cal.dataset.session import load_session
from vision_cal.measure import dots, grid, sheetfit
from vision_cal.measure.batch import measure_image
from vision_cal.measure.cache import session_fingerprint
from vision_cal.pipeline import calibrate_dataset


def test_no_module_copies_a_threshold_at_import():
    """The dots module has no copy of a DotConfig field (they were module globals)."""
    for f in fields(DotConfig):
        assert not hasattr(dots, f.name.upper()), f.name
    assert not hasattr(grid, "DOTS")
    for f in fields(SheetFitConfig):
        assert not hasattr(sheetfit, f.name.upper()), f.name


def test_the_recorded_config_reads_back():
    assert EstimatorConfig.from_json(DEFAULT.to_json()) == DEFAULT
    # an older file without a part or a field: the defaults
    assert EstimatorConfig.from_json({"dots": {"ink_darkening": 0.5}}).dots == \
        DotConfig(ink_darkening=0.5)


def test_calibration_json_says_how_it_was_obtained(paper_folder, tmp_path):
    calibrate_dataset(paper_folder, out_dir=tmp_path / "d")
    doc = json.loads((tmp_path / "d" / "calibration.json").read_text())
    assert doc["config"] == DEFAULT.to_json()
    assert set(doc["config"]) == {"markers", "dots", "association", "selection", "fit",
                                  "per_photo_offsets", "sheet_fit"}
    assert doc["config"]["selection"]["alpha"] == 0.01
    cfg = replace(DEFAULT, selection=SelectionConfig(alpha=1e-3, k_folds=3, max_effects=1))
    calibrate_dataset(paper_folder, out_dir=tmp_path / "c", config=cfg)
    doc = json.loads((tmp_path / "c" / "calibration.json").read_text())
    assert doc["config"]["selection"] == dict(DEFAULT.to_json()["selection"], alpha=1e-3,
                                              k_folds=3, max_effects=1)
    assert doc["diagnosis"]["heldout"] == "3-fold cross-validation"
    # a dots setting is taken (it was refused while dots.py copied it at import) and recorded
    dots = DotConfig(ink_darkening=0.4)
    calibrate_dataset(paper_folder, out_dir=tmp_path / "e", config=replace(DEFAULT, dots=dots))
    doc = json.loads((tmp_path / "e" / "calibration.json").read_text())
    assert EstimatorConfig.from_json(doc["config"]).dots == dots


def test_a_dot_threshold_passed_in_changes_the_measurement(tmp_path):
    """A non-default dots setting is used (pipeline.py refused it while dots.py copied its
    thresholds at import): blobs below 10 times a mark's area are noise, so none of the
    photo's marks is kept; the setting is part of the cache key (the cached default run
    does not answer for it), and a non-default setting is recorded."""
    sheet = sm.small_sheet()
    marks = sm.free_targets(sheet, 12, rng=3, box=(95.0, 70.0))
    K, T = sm.view(tilt_deg=10.0, azimuth_deg=-40.0)
    (tmp_path / "in").mkdir()
    sm.write_png(tmp_path / "in" / "a.png",
                 sm.photo(sheet, sm.texture(sheet, marks, rng=4), K=K, T=T, noise=2.0, rng=7))
    ids = [f"m{i:02d}" for i in range(len(marks))]
    sm.write_session(tmp_path / "in", sm.session_json(
        sheet, marks=[(i, (0.0, 0.0)) for i in ids], images=[("a.png", ids)]))
    session = load_session(tmp_path / "in")
    assert measure_image(tmp_path / "in" / "a.png", session).n_dots >= 10
    cfg = replace(DEFAULT, dots=DotConfig(min_area_ratio=10.0, max_area_ratio=20.0,
                                          huge_area_ratio=30.0))
    im = measure_image(tmp_path / "in" / "a.png", session, config=cfg)
    assert im.status == "ok" and im.n_dots == 0
    assert session_fingerprint(session, cfg) != session_fingerprint(session, DEFAULT)
    assert EstimatorConfig.from_json(json.loads(json.dumps(cfg.to_json()))) == cfg
