"""tool_mm and a joint-4 gear error recovered from rendered photos (issue #21): the world
draws marks at six joint-4 angles with a pen 24 mm off the axis, one photo of the finished
sheet is measured and calibrated; each value within 4 reported std of the truth."""

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from vision_cal.estimate.paper import pilot_params
from vision_cal.design.joint4 import turn_joint4
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.world import dataset as ds
from vision_cal.world.scene import scene_from_dict
from vision_cal.world.sheet import make_sheet

pytestmark = pytest.mark.render

ROOT = Path(__file__).resolve().parents[2]
TOOL = [22.0, -9.0]
SCALE4 = 0.004


def test_tool_and_joint4_scale_from_rendered_photos(tmp_path):
    d = copy.deepcopy(yaml.safe_load((ROOT / "renders" / "small.yaml").read_text()))
    d["seed"] = 31
    d["camera"].update(size_px=[1000, 750], f_px=1084.0, n_views=1, moving=False)
    d["photos"] = {"mode": "single", "texture_px_per_mm": 4.0}
    d["plan"].update(n_calibration=20, n_validation=4)
    d["robot"].update(effects=[{"name": "joint_scale", "joint": 4, "scale": SCALE4}],
                      tool_mm=TOOL, controller="kinematic")
    d["robot"]["nominal"]["tool_mm"] = [20.0, -10.0]          # the user's rough tool
    sc = scene_from_dict(d, file="test-scene")
    s = sc.sheet
    sheet = make_sheet(size_mm=s.size_mm, bottom_left_mm=s.bottom_left_mm,
                       dictionary=s.dictionary, marker_mm=s.marker_mm, grid=s.grid,
                       margin_mm=s.margin_mm)
    plan = ds.build_plan(sc, sheet, pilot=pilot_params, rng=1)
    pilot = pilot_params(*ds.pilot_marks(sc, rng=1))          # the pilot drew at j4 = 0
    plan, j4 = turn_joint4(plan, pilot, (20.0, -10.0))
    folder = ds.render_dataset(sc, tmp_path / "data", plan=plan, joint4_deg=j4)
    doc = calibrate_dataset(folder, out_dir=tmp_path / "out").document
    assert doc["tool"]["identified"] is True
    err = np.subtract(doc["params"]["tool_mm"], TOOL)
    assert np.all(np.abs(err) < 4 * np.array(doc["std"]["tool_mm"])), (err, doc["std"])
    (e,) = doc["effects"]
    assert (e["name"], e["joint"]) == ("joint_scale", 4)
    assert abs(e["scale"] - SCALE4) < 4 * e["std"]
