"""design's preview.png, its reach warning, and a robot file without pen heights."""

from __future__ import annotations


import numpy as np
import pytest
import yaml

from tests.design.conftest import ROBOT, border_sheet
from vision_cal.commands.main import main
from vision_cal.design.preview import reach_fraction
from vision_cal.model.kinematics import ScaraParams


def robot_file(tmp_path, **edit) -> str:
    doc = yaml.safe_load(ROBOT.read_text())
    for k, v in edit.items():
        if v is None:
            doc.pop(k, None)
        else:
            doc[k] = v
    p = tmp_path / "robot.yaml"
    p.write_text(yaml.safe_dump(doc))
    return str(p)


def test_without_pen_heights_design_writes_the_plan_and_says_why_no_program(
        tmp_path, sheet_json, capsys):
    robot = robot_file(tmp_path, pen_up_mm=None, pen_down_mm=None)
    rc = main(["design", robot, "--sheet", str(sheet_json), "--out", str(tmp_path / "p")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 0
    assert {f.name for f in (tmp_path / "p").iterdir()
            if not f.name.startswith(".")} == {"session.json", "trajectory.csv", "preview.png"}
    assert len(err) == 1 and "pen_up_mm" in err[0] and "robot.yaml" in err[0], err


def test_preview_png_is_written_and_is_never_taken_for_a_photo(pilot_dir):
    from PIL import Image

    from vision_cal.dataset.photos import list_photos

    with Image.open(pilot_dir / "preview.png") as im:
        assert im.size[0] >= 600 and im.size[1] >= 400
    assert "preview.png" not in list_photos(pilot_dir)


def test_reach_fraction_from_geometry():
    """Bounds from geometry: an arm whose base stands at the sheet's centre with a reach
    longer than the half diagonal and no limits reaches all of it but the hole of radius
    |L1 - L2| around the base; the same arm 2 m away reaches none."""
    sheet = border_sheet()                                 # 594 x 420 mm, centred
    free = ((-180.0, 180.0), (-180.0, 180.0))
    p = ScaraParams(250.0, 200.0, 0.0, 0.0, 0.0, 0.0)      # reach 450 > 364 mm half diagonal
    hole = np.pi * 50.0**2 / (594.0 * 420.0)
    assert reach_fraction(p, sheet, joint_limits_deg=free, n=200) == pytest.approx(
        1 - hole, abs=0.01)
    far = ScaraParams(250.0, 200.0, 0.0, 0.0, 2000.0, 0.0)
    assert reach_fraction(far, sheet, joint_limits_deg=free) == 0.0
    # joint 1 limited to +-30 deg about z1: turning z1 by 180 deg turns the arm away
    lim = ((-30.0, 30.0), (-150.0, 150.0))
    side = ScaraParams(350.0, 260.0, 0.0, 0.0, -500.0, 0.0)
    away = ScaraParams(350.0, 260.0, 180.0, 0.0, -500.0, 0.0)
    assert reach_fraction(side, sheet, joint_limits_deg=lim) > 0.5
    assert reach_fraction(away, sheet, joint_limits_deg=lim) == 0.0


def test_a_robot_file_that_forgets_the_rotation_is_warned(tmp_path, sheet_json, capsys):
    """z1 without the robot's rotation to the sheet (here 180 deg off) with tight joint-1
    limits: the reach is off the sheet; the one-line error says so and names z1."""
    robot = robot_file(tmp_path, joint_zero_deg=[180.0, 0.0],
                       joint_limits_deg=[[-60.0, 60.0], [-150.0, 150.0]])
    rc = main(["design", robot, "--sheet", str(sheet_json), "--out", str(tmp_path / "p")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert any("within the arm's reach" in e and "z1" in e for e in err), err
    assert not (tmp_path / "p").exists() or not any((tmp_path / "p").iterdir())
