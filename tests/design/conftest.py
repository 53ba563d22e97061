"""A printed sheet with ArUco markers along its border (as `vision-cal sheet` prints), and
designed plans on it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import ROOT
from vision_cal.dataset.session import Sheet, SheetMarker

ROBOT = ROOT / "fixtures" / "robot_sm5.yaml"


def border_sheet(size_mm=(594.0, 420.0), marker_mm=30.0, margin_mm=15.0, n=(7, 5)) -> Sheet:
    w, h = size_mm
    x0, y0 = -w / 2, -h / 2
    xs = np.linspace(x0 + margin_mm, x0 + w - margin_mm - marker_mm, n[0])
    ys = np.linspace(y0 + margin_mm, y0 + h - margin_mm - marker_mm, n[1])
    pts = ([(x, ys[0]) for x in xs] + [(x, ys[-1]) for x in xs]
           + [(xs[0], y) for y in ys[1:-1]] + [(xs[-1], y) for y in ys[1:-1]])
    s = marker_mm
    ms = [SheetMarker(k, np.array([[x, y + s], [x + s, y + s], [x + s, y], [x, y]]))
          for k, (x, y) in enumerate(pts)]
    return Sheet("DICT_5X5_100", tuple(ms), (w, h), (x0, y0))


@pytest.fixture(scope="session")
def sheet_json(tmp_path_factory):
    p = tmp_path_factory.mktemp("sheet") / "sheet.json"
    p.write_text(json.dumps(border_sheet().to_json()))
    return p


@pytest.fixture(scope="session")
def pilot_dir(tmp_path_factory, sheet_json):
    from vision_cal.design.stage import design_stage

    out = tmp_path_factory.mktemp("pilot")
    design_stage(ROBOT, sheet_json, out, program="spel")
    return out


@pytest.fixture(scope="session")
def informative_dir(tmp_path_factory, pilot_dir, sheet_json):
    """The informative stage from a pilot calibration (a true robot's pilot marks with
    0.02 mm of noise: the plan's structure, not its accuracy, is under test here)."""
    from vision_cal.design.stage import design_stage
    from vision_cal.actions.pipeline import calibrate_dataset
    from vision_cal.world.truth_model import TrueRobot

    s = json.loads((pilot_dir / "session.json").read_text())
    truth = TrueRobot(344.05, 259.87, (-2.57, -8.13), (-420.0, -230.0))
    q = np.array([m["joints_deg"] for m in s["marks"]])
    noise = np.random.default_rng(5).normal(0, 0.02, q.shape)
    for m, p in zip(s["marks"], truth.pen_mm(q) + noise):
        m["measured_mm"] = p.tolist()
    d = tmp_path_factory.mktemp("pilot_cal")
    (d / "session.json").write_text(json.dumps(s))
    cal = calibrate_dataset(d, out_dir=d / "out").out_path
    out = tmp_path_factory.mktemp("informative")
    design_stage(ROBOT, sheet_json, out, pilot=cal, program="spel")
    return out
