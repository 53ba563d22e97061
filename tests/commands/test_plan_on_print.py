"""``plan`` says which targets lie on the sheet's printed ink and what that costs (issue 18
section 1), from calibration.json's ``printed_content``."""

import json
from pathlib import Path

from vision_cal.commands.main import main
from vision_cal.measure.printed import printed_content_json
from vision_cal.dataset.session import load_sheet_file
from vision_cal.sheet import make_layout, write_sheet

ROOT = Path(__file__).resolve().parents[2]
TARGETS = ROOT / "fixtures" / "targets_origin.csv"


def test_a_target_on_printed_ink_is_named(tmp_path, capsys):
    assert main([str(ROOT / "fixtures" / "paper_sm5"), "--out", str(tmp_path / "c"), "-q"]) == 0
    write_sheet(make_layout(size="A2"), tmp_path / "sheet")
    content = printed_content_json(load_sheet_file(tmp_path / "sheet" / "sheet.json"))
    assert {"axis", "arrow", "text", "number", "scale bar", "title"} <= {c["kind"] for c in content}
    cal = tmp_path / "c" / "calibration.json"
    capsys.readouterr()
    main(["plan", str(cal), str(TARGETS), "-o", str(tmp_path / "a.csv"), "-q", "--force"])
    assert "printed ink" not in capsys.readouterr().err      # no sheet described: nothing said
    doc = json.loads(cal.read_text())
    doc["printed_content"] = content
    cal.write_text(json.dumps(doc))
    main(["plan", str(cal), str(TARGETS), "-o", str(tmp_path / "p.csv"), "-q", "--force"])
    err = [ln for ln in capsys.readouterr().err.splitlines() if "printed ink" in ln]
    assert len(err) == 1, err
    assert "1 target(s) on the sheet's printed ink: origin (x axis, y axis)" in err[0]
    assert "left out as unreliable" in err[0]
