"""`vision-cal history`: calibrations in date order, each parameter with its std."""

from __future__ import annotations

import json

from vision_cal.commands.main import main


def _cal(folder, L1, std, date=None):
    folder.mkdir(parents=True)
    doc = {"format": "vision-cal/calibration/1",
           "params": {"L1_mm": L1, "L2_mm": 260.0, "joint_zero_deg": [1.0, 2.0],
                      "base_mm": [-400.0, -250.0]},
           "std": {"L1_mm": std, "L2_mm": 0.01, "joint_zero_deg": [0.001, 0.002],
                   "base_mm": [0.02, 0.03]},
           "effects": [{"name": "joint_backlash", "joint": 2, "deg": 0.1}],
           "validation_rms_mm": {"final_model": 0.015}}
    (folder / "calibration.json").write_text(json.dumps(doc))
    if date:
        (folder / "report.json").write_text(json.dumps({"provenance": {"created_utc": date}}))


def test_history_is_in_date_order_with_std(tmp_path, capsys):
    # folder names sort the other way round: the dates decide
    _cal(tmp_path / "a_later", 350.02, 0.004, "2026-09-01 08:00:00 UTC")
    _cal(tmp_path / "b_first", 350.00, 0.005, "2026-03-01 08:00:00 UTC")
    rc = main(["history", str(tmp_path), "-o", str(tmp_path / "h.csv"),
               "--plot", str(tmp_path / "h.png")])
    assert rc == 0
    rows = (tmp_path / "h.csv").read_text().splitlines()
    assert rows[1].startswith("2026-03-01") and rows[2].startswith("2026-09-01")
    head = rows[0].split(",")
    first = rows[1].split(",")
    assert float(first[head.index("L1_mm")]) == 350.0
    assert float(first[head.index("L1_mm_std")]) == 0.005
    assert float(first[head.index("z2_deg")]) == 2.0
    assert "joint_backlash(joint 2)" in rows[1]
    assert (tmp_path / "h.png").stat().st_size > 10_000
    out = capsys.readouterr().out
    assert "350.0000 +-0.0050" in out and "350.0200 +-0.0040" in out
    # each console row names its calibration's folder (the CSV's calibration column)
    by_row = {ln.split()[2]: ln for ln in out.splitlines() if "+-" in ln}
    assert "350.0000 +-0.0050" in by_row[str(tmp_path / "b_first")]
    assert "350.0200 +-0.0040" in by_row[str(tmp_path / "a_later")]


def test_history_names_a_bad_file(tmp_path, capsys):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "calibration.json").write_text(json.dumps({"format": "other"}))
    assert main(["history", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "calibration.json" in err[0] and "format" in err[0]
    assert main(["history", str(tmp_path / "nothing")]) == 2
