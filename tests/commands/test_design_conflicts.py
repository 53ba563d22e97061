"""``vision-cal design`` refuses options that contradict each other, naming both (issue 29)."""

from __future__ import annotations

from pathlib import Path

import pytest

from vision_cal.commands.main import main

ROOT = Path(__file__).resolve().parents[2]
ROBOT = str(ROOT / "fixtures" / "robot_sm5.yaml")


@pytest.mark.parametrize("extra, a, b", [
    (["--verify", "cal.json", "--camera-on-arm"], "--verify", "--camera-on-arm"),
    (["--verify", "cal.json", "--placements", "2"], "--verify", "--placements"),
    (["--pilot", "cal.json", "--camera-on-arm"], "--pilot", "--camera-on-arm"),
    (["--camera-on-arm", "--program", "csv"], "--camera-on-arm", "--program csv"),
])
def test_contradicting_options_are_refused_naming_both(extra, a, b, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["design", ROBOT, "--sheet", str(tmp_path / "sheet.json"), "--out", str(out),
                 "-q", *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1
    assert a in err and b in err and "contradict" in err
    assert not out.exists()                      # refused before anything is written
