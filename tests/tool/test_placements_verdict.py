"""`calibrate --joint` (issue 29, section 3): the contract's verdict for the joint fit and
for each placement, a placement that disagrees with the others named, the same photos or
marks given twice refused. Marks as measured_mm from the world's own truth model."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.tool.test_placements import _places
from vision_cal.commands.main import main
from vision_cal.estimate.verdict import judge_placements

ROOT = Path(__file__).resolve().parents[2]


def test_consistent_placements_each_get_a_verdict_and_none_is_named(tmp_path, capsys):
    places = _places(tmp_path)
    out = tmp_path / "X"
    assert main(["calibrate", *[str(d) for d, _ in places], "--joint", "--out", str(out)]) == 0
    doc = json.loads((out / "calibration.json").read_text())
    v = doc["verdict"]
    assert v["status"] in ("ready", "check", "not reliable")
    assert not any("disagrees" in r for r in v["reasons"]), v["reasons"]
    for pl in doc["placements"]:
        assert pl["verdict"]["status"] and not pl["agreement"]["disagrees"], pl
        sub = json.loads((out / pl["folder"] / "calibration.json").read_text())
        assert sub["verdict"] == pl["verdict"]
        m = next(iter(sub["marks"].values()))
        assert len(m["joints_deg"]) == 2 and m["role"] == "calibration"
    # measured_mm carries no noise: said, never "ready"
    assert v["status"] != "ready" and any("no measurement noise" in r for r in v["reasons"])
    assert "verdict:" in capsys.readouterr().out


def test_the_paper_fixture_as_a_placement_is_named(tmp_path, capsys):
    """Two placements of the world (10 um noise) and the seed paper's five marks of another
    SM5 (its table, mm rounded to 0.1): the paper's placement misses the shared robot by
    far more than the others and is named; the joint verdict is not ready."""
    places = _places(tmp_path)[:2]
    paper = tmp_path / "paper"
    shutil.copytree(ROOT / "fixtures" / "paper_sm5", paper)
    out = tmp_path / "X"
    rc = main(["calibrate", *[str(d) for d, _ in places], str(paper), "--joint", "--out",
               str(out), "-q"])
    assert rc == 0
    doc = json.loads((out / "calibration.json").read_text())
    v = doc["verdict"]
    assert v["status"] == "not reliable", v
    assert any(r.startswith("placement paper disagrees") for r in v["reasons"]), v["reasons"]
    by = {p["folder"]: p for p in doc["placements"]}
    assert by["paper"]["agreement"]["disagrees"]
    assert not by["place0"]["agreement"]["disagrees"]
    assert by["paper"]["verdict"]["status"] == "not reliable"
    assert any("paper" in r for r in by["place0"]["verdict"]["reasons"])


def test_the_same_marks_given_twice_are_refused(tmp_path, capsys):
    places = _places(tmp_path)[:2]
    twin = tmp_path / "twin"
    shutil.copytree(places[0][0], twin)
    rc = main(["calibrate", str(places[0][0]), str(places[1][0]), str(twin), "--joint",
               "--out", str(tmp_path / "X")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc != 0 and len(err) == 1 and "same marks" in err[0], err
    assert "place0" in err[0] and "twin" in err[0]
    assert not (tmp_path / "X" / "calibration.json").exists()


def test_the_same_photo_under_two_names_is_refused(tmp_path, capsys):
    places = _places(tmp_path)[:2]
    rng = np.random.default_rng(5)
    data = bytes(rng.integers(0, 256, 4096, dtype=np.uint8))
    (places[0][0] / "IMG_0001.png").write_bytes(data)
    (places[1][0] / "IMG_0042.png").write_bytes(data)            # the same photo, renamed
    (places[1][0] / "IMG_0043.png").write_bytes(data[::-1])
    rc = main(["calibrate", str(places[0][0]), str(places[1][0]), "--joint", "--out",
               str(tmp_path / "X")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc != 0 and len(err) == 1 and "same photo" in err[0], err
    assert "IMG_0001.png" in err[0] and "IMG_0042.png" in err[0]


def _noise(rng, n, s):
    return rng.normal(0, s, (n, 2)), np.full(n, s)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_judged_in_noise_units(seed):
    """Three placements whose residuals are their noise (different per placement: 5, 10,
    20 um): none is named. One whose residual is 3 times its noise is named and its
    verdict not ready."""
    rng = np.random.default_rng(seed)
    res, sig = zip(*[_noise(rng, 40, s) for s in (0.005, 0.01, 0.02)])
    held = [r * 1.1 for r in res]
    joint, each, agree = judge_placements(["a", "b", "c"], res, sig, held, n_params=14,
                                          repeatability_mm=0.0)
    assert not any(a.beyond for a in agree)
    assert joint.status == "ready", joint.reasons
    assert all(v.status == "ready" for v in each)
    res = list(res)
    res[1] = res[1] * 3.0
    joint, each, agree = judge_placements(["a", "b", "c"], res, sig, held, n_params=14,
                                          repeatability_mm=0.0)
    assert [a.beyond for a in agree] == [False, True, False]
    assert joint.status == "not reliable" and "placement b disagrees" in joint.reasons[0]
    assert each[1].status == "not reliable" and each[0].status == "check"
