"""`vision-cal verify` refuses a calibration.json it cannot check a drawn check against,
and says which field (issue 29, section 3): another method (a camera on the arm), another
frame (a joint calibration), metres or radians, a "not reliable" verdict, no promise."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import SM5, random_plan
from vision_cal.commands.main import main
from vision_cal.model.robot import RobotModel

ROOT = Path(__file__).resolve().parents[1]
CHECK = ROOT / "fixtures" / "paper_sm5"          # a session.json of the SM5 (robot block)


def _doc() -> dict:
    """A pen calibration of the SM5 as vision-cal writes it: its marks where its params
    put them, within 0.01 mm."""
    rng = np.random.default_rng(3)
    q, s = random_plan(12, rng)
    xy = RobotModel(SM5).predict(q, s) + rng.normal(0, 0.007, q.shape)
    return {"format": "vision-cal/calibration/1", "method": "lsq",
            "params": {"L1_mm": SM5.L1_mm, "L2_mm": SM5.L2_mm,
                       "joint_zero_deg": [SM5.z1_deg, SM5.z2_deg],
                       "base_mm": [SM5.base_x_mm, SM5.base_y_mm]},
            "effects": [], "residual_rms_mm": {"final_model": 0.01},
            "validation_rms_mm": {"final_model": 0.012},
            "verdict": {"status": "ready", "reasons": []},
            "marks": {f"c{i:02d}": {"joints_deg": q[i].tolist(), "approach": s[i].tolist(),
                                    "measured_mm": xy[i].tolist(), "role": "calibration"}
                      for i in range(len(q))}}


def _metres(d):
    p = d["params"]
    p["L1_mm"], p["L2_mm"] = p["L1_mm"] / 1000, p["L2_mm"] / 1000
    p["base_mm"] = [v / 1000 for v in p["base_mm"]]


def _radians(d):
    d["params"]["joint_zero_deg"] = [math.radians(v) for v in d["params"]["joint_zero_deg"]]


def _set(path, value):
    def edit(d):
        *head, last = path
        for k in head:
            d = d[k]
        d[last] = value
    return edit


def _drop_promise(d):
    del d["residual_rms_mm"], d["validation_rms_mm"]


@pytest.mark.parametrize("edit, field, says", [
    (_set(["method"], "arm_camera"), "method", "handeye"),
    (_set(["frame"], "robot"), "frame", "placement"),
    (_metres, "params.L1_mm", "metres"),
    (_radians, "params", "radians"),
    (_set(["verdict", "status"], "not reliable"), "verdict.status", "no promise to check"),
    (_set(["verdict", "status"], "fine"), "verdict.status", "expected ready"),
    (_drop_promise, "residual_rms_mm", "promises no error"),
])
def test_verify_refuses_what_it_cannot_check_naming_the_field(tmp_path, capsys, edit, field,
                                                              says):
    good = tmp_path / "good.json"
    good.write_text(json.dumps(_doc()))
    bad_doc = copy.deepcopy(_doc())
    edit(bad_doc)
    bad = tmp_path / "calibration.json"
    bad.write_text(json.dumps(bad_doc))
    out = tmp_path / "out"
    rc = main(["verify", str(bad), str(CHECK), "--out", str(out), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert f"{bad}: {field}: " in err[0] and says in err[0], err[0]
    assert not out.exists()
    # the same file unedited passes the checks (then measures: the fixture has no photos,
    # its marks are measured_mm, so it compares)
    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.dataset.session import load_session
    from vision_cal.actions.verify import check_verifiable

    model, doc = load_calibration(good)
    check_verifiable(model, doc, good, load_session(CHECK))
