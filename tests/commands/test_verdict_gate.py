"""A calibration's own verdict gates its use (issue 18 section 3): ``design --pilot``
refuses a pilot that is not "ready", ``plan`` and ``export`` refuse "not reliable" unless
``--force``; a file without a verdict block (older) is accepted."""

import json
from pathlib import Path

import pytest

from vision_cal.commands.main import main

ROOT = Path(__file__).resolve().parents[2]
TARGETS = ROOT / "fixtures" / "targets_origin.csv"


@pytest.fixture(scope="module")
def cal(tmp_path_factory):
    out = tmp_path_factory.mktemp("cal")
    assert main([str(ROOT / "fixtures" / "paper_sm5"), "--out", str(out), "-q"]) == 0
    return out / "calibration.json"


def _with_verdict(cal, tmp_path, status):
    doc = json.loads(cal.read_text())
    doc["verdict"] = {"status": status, "reasons": ["residual 3.2 x the noise floor"]}
    p = tmp_path / f"cal_{status.replace(' ', '_')}.json"
    p.write_text(json.dumps(doc))
    return p


def _inside(cal, tmp_path):
    """Targets where the paper's marks are (inside its valid_for: the joints they covered)."""
    marks = json.loads(cal.read_text())["marks"]
    t = tmp_path / "inside.csv"
    t.write_text("id,x_mm,y_mm\n" + "".join(f"{k},{m['measured_mm'][0]},{m['measured_mm'][1]}\n"
                                            for k, m in list(marks.items())[:2]))
    return t


def _run(argv, capsys):
    rc = main([str(a) for a in argv])
    return rc, capsys.readouterr().err


@pytest.mark.parametrize("sub", ["plan", "export"])
def test_not_reliable_is_refused_unless_forced(cal, tmp_path, capsys, sub):
    bad = _with_verdict(cal, tmp_path, "not reliable")
    args = ([_inside(cal, tmp_path), "-o", tmp_path / "p.csv"] if sub == "plan"
            else ["--yaml", tmp_path / "c.yaml"])
    rc, err = _run([sub, bad, *args, "-q"], capsys)
    assert rc == 2
    assert "verdict.status" in err and "not reliable" in err and "--force" in err
    assert "residual 3.2 x the noise floor" in err
    assert not (tmp_path / "p.csv").exists() and not (tmp_path / "c.yaml").exists()
    rc, err = _run([sub, bad, *args, "-q", "--force"], capsys)
    assert rc == 0 and "used because of --force" in err
    # "check" and no verdict at all are used as they are
    for ok in (_with_verdict(cal, tmp_path, "check"), cal):
        assert _run([sub, ok, *args, "-q"], capsys)[0] == 0


def test_design_refuses_a_pilot_that_is_not_reliable(cal, tmp_path, capsys):
    """A pilot "not reliable" would place the plan wrong: refused (a "check" one is taken:
    tests/design/test_pilot.py)."""
    sheet = tmp_path / "sheet"
    assert main(["sheet", "--size", "A2", "--out", str(sheet), "-q"]) == 0
    robot = ROOT / "fixtures" / "robot_sm5.yaml"
    for status in ("not reliable",):
        pilot = _with_verdict(cal, tmp_path, status)
        rc, err = _run(["design", robot, "--sheet", sheet / "sheet.json", "--pilot", pilot,
                        "--out", tmp_path / "plan", "-q"], capsys)
        assert rc == 2 and "verdict.status" in err and repr(status) in err, err
        assert not (tmp_path / "plan").exists()
