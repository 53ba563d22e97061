"""Rendered photographs with an effect nobody declared: measured, calibrated, diagnosed.

Small and fast versions (one 1000 x 750 photo of the finished sheet, 24 marks); the full
grid of effects, sizes and seeds runs in bench/diagnose.py.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from vision_cal.dataset.io import read_json
from vision_cal.pipeline import calibrate_dataset
from vision_cal.calibrate.paper import pilot_params
from vision_cal.render import dataset as ds
from vision_cal.render.scene import scene_from_dict

ROOT = Path(__file__).resolve().parents[1]
BASE = yaml.safe_load((ROOT / "renders" / "small.yaml").read_text())
BASE["camera"].update(size_px=[1000, 750], f_px=1084.0, n_views=1, moving=False)
BASE["photos"] = {"mode": "single", "texture_px_per_mm": 4.0}
BASE["plan"].update(n_calibration=20, n_validation=4)
BASE["robot"]["effects"] = []
# The 0.015 mm target is for 0.25 mm per pixel; these photos are about 0.6 mm per
# pixel, so the mark accuracy bound scales with the pixel: 0.015 * 0.6 / 0.25 = 0.036 mm.
MARK_RMS_MM = 0.036


def scene(effects=(), seed=12, dist=None):
    d = copy.deepcopy(BASE)
    d["seed"] = seed
    d["robot"]["effects"] = list(effects)
    if dist is not None:
        d["camera"]["dist"] = dist
        d["camera"]["declared"] = False
    return scene_from_dict(d, file="test-scene")


@pytest.fixture(scope="session")
def photographer():
    from vision_cal.render.photo import Photographer

    s = scene()
    return Photographer(size_px=s.camera.size_px, K=ds.photographer_K(s))


def calibrate(tmp_path, sc, photographer=None):
    folder = ds.render_dataset(sc, tmp_path / "data", pilot=pilot_params, photographer=photographer)
    run = calibrate_dataset(folder, out_dir=tmp_path / "out", truth=True)
    return run.document, read_json(folder / "truth.json")


def robot_effects(doc):
    return [e for e in doc["effects"] if e["name"] not in ("lens_distortion", "unexplained")]


def check_base(doc):
    t = doc["truth_comparison"]
    assert abs(t["L1_mm"]) < 0.05 and abs(t["L2_mm"]) < 0.05, t
    assert max(abs(v) for v in t["joint_zero_deg"]) < 0.01, t
    assert max(abs(v) for v in t["base_mm"]) < 0.05, t


@pytest.mark.parametrize("seed", [12, 13])
def test_clean_render_claims_nothing(tmp_path, photographer, seed):
    doc, _ = calibrate(tmp_path, scene(seed=seed), photographer)
    assert robot_effects(doc) == []
    assert not any(e["name"] == "lens_distortion" for e in doc["effects"])
    check_base(doc)
    assert doc["truth_comparison"]["mark_rms_mm"] < MARK_RMS_MM


@pytest.mark.parametrize("effect,key", [
    ({"name": "joint_backlash", "joint": 1, "deg": 0.1}, "deg"),
    ({"name": "joint_scale", "joint": 2, "scale": 0.003}, "scale"),
    ({"name": "joint_cyclic", "joint": 2, "harmonic": 2, "deg": 0.1, "phase_deg": 30.0}, "deg"),
], ids=["backlash-j1", "scale-j2", "cyclic-j2-h2"])
def test_undeclared_joint_effect_is_named_and_sized(tmp_path, photographer, effect, key):
    doc, truth = calibrate(tmp_path, scene([effect]), photographer)
    (found,) = robot_effects(doc)
    assert (found["name"], found["joint"]) == (effect["name"], effect["joint"])
    assert found[key] == pytest.approx(effect[key], rel=0.2)
    check_base(doc)
    v = doc["validation_rms_mm"]
    assert v["final_model"] < v["base_model"]


def test_sheet_shrink_is_named(tmp_path, photographer):
    doc, _ = calibrate(tmp_path, scene([{"name": "sheet_affine",
                                         "matrix": [[1.003, 0.0], [0.0, 1.0]]}]), photographer)
    (found,) = robot_effects(doc)
    assert found["name"] == "sheet_affine"
    assert found["matrix"][0][0] - 1 == pytest.approx(0.003, rel=0.2)
    check_base(doc)


def test_undeclared_barrel_lens_is_reported_and_measured_through(tmp_path):
    doc, _ = calibrate(tmp_path, scene(dist=[-0.12, 0.05, 0.0, 0.0, 0.0]))
    lens = [e for e in doc["effects"] if e["name"] == "lens_distortion"]
    assert lens and lens[0]["coefficients"][0] < 0
    assert robot_effects(doc) == []
    check_base(doc)
    assert doc["truth_comparison"]["mark_rms_mm"] < MARK_RMS_MM
