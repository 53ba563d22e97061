"""A new user's wrong inputs, found by running each command once on them (the sweep after
issue 31's moves): each is one line naming the file, exit 2, and nothing written, not even
the empty default out/ folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.commands.test_trust import TARGETS, assert_one_line, calibration  # noqa: F401
from vision_cal.commands.main import main
from vision_cal.dataset.out_folder import writing_into
from vision_cal.errors import VisionCalError
from vision_cal.world.rehearse import _earlier_marks

ROOT = Path(__file__).resolve().parents[2]
PDF = b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n1 0 obj<<>>endobj\n"


def _run(argv, capsys):
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:   # an option out of its range: argparse's one line
        rc = e.code
    return rc, capsys.readouterr().err


def test_calibrate_a_missing_folder_leaves_no_empty_out_folder(tmp_path, monkeypatch, capsys):
    """Without --out the results go to out/<name>: both folders were made before the input
    was found missing, and only out/<name> was removed again."""
    monkeypatch.chdir(tmp_path)
    rc, err = _run(["calibrate", "nodir"], capsys)
    assert rc == 2
    assert "folder not found" in assert_one_line(err, "nodir")
    assert list(tmp_path.iterdir()) == []


def test_a_failed_write_removes_the_parents_it_made_and_keeps_the_others(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "kept.txt").write_text("x")
    try:
        with writing_into(tmp_path / "a" / "b" / "c", command="test"):
            raise KeyboardInterrupt
    except KeyboardInterrupt:
        pass
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["kept.txt"]


def test_a_pdf_given_for_a_calibration_or_a_robot_file_is_called_a_pdf(tmp_path, capsys,
                                                                       calibration):  # noqa: F811
    """Only the sheet's own PDF (beside its sheet.json, or given for the sheet) gets the
    hint to pass sheet.json; a calibration or robot file saved as PDF is called a PDF."""
    (tmp_path / "calibration.pdf").write_bytes(PDF)
    for argv, name in ((["plan", tmp_path / "calibration.pdf", TARGETS, "-o",
                         tmp_path / "p.csv"], "calibration.pdf"),
                       (["plan", calibration, TARGETS, "-o", tmp_path / "p.csv",
                         "--robot", tmp_path / "calibration.pdf"], "calibration.pdf"),
                       (["export", tmp_path / "calibration.pdf", "--yaml",
                         tmp_path / "e.yaml"], "calibration.pdf")):
        rc, err = _run(argv, capsys)
        assert rc == 2
        line = assert_one_line(err, tmp_path / name)
        assert "is a PDF" in line and "sheet" not in line, line
    (tmp_path / "print.pdf").write_bytes(PDF)   # the sheet's PDF renamed: still the hint
    (tmp_path / "photos").mkdir()
    rc, err = _run(["survey", tmp_path / "photos", "--sheet", tmp_path / "print.pdf", "-o",
                    tmp_path / "o"], capsys)
    assert rc == 2 and "pass the sheet.json" in assert_one_line(err, tmp_path / "print.pdf")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calibration.pdf", "photos",
                                                          "print.pdf"]


def test_init_plan_missing_or_a_pdf_names_the_file_given(tmp_path, capsys):
    """--plan SESSION.json names a file: a missing one is 'file not found' (not the advice
    for a folder without session.json), a PDF is called a PDF (not PDF/session.json)."""
    (tmp_path / "photos").mkdir()
    (tmp_path / "plan.pdf").write_bytes(PDF)
    rc, err = _run(["init", tmp_path / "photos", "--plan", tmp_path / "nope.json"], capsys)
    assert rc == 2 and "file not found" in assert_one_line(err, tmp_path / "nope.json")
    rc, err = _run(["init", tmp_path / "photos", "--plan", tmp_path / "plan.pdf"], capsys)
    assert rc == 2
    line = assert_one_line(err, tmp_path / "plan.pdf")
    assert "is a PDF" in line and "plan.pdf/session.json" not in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["photos", "plan.pdf"]
    assert list((tmp_path / "photos").iterdir()) == []


def test_simulate_a_program_without_its_plan_csv_says_what_to_give(tmp_path, capsys):
    """A targets program (plan --program) is read with the plan CSV beside it; given a
    designed plan's program.prg instead of its folder, the line said 'program.csv: file not
    found', a file the user never had: it now names the program and what to give."""
    assert main(["robot-template", "-o", str(tmp_path / "robot.yaml"), "-q"]) == 0
    assert main(["robot-template", "--simulated", "-o", str(tmp_path / "true.yaml"),
                 "-q"]) == 0
    (tmp_path / "plan").mkdir()
    (tmp_path / "plan" / "session.json").write_text("{}")
    (tmp_path / "plan" / "program.prg").write_text("Function main\nFend\n")
    (tmp_path / "lone.prg").write_text("Function main\nFend\n")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    for prg, words in ((tmp_path / "plan" / "program.prg", "give its folder"),
                       (tmp_path / "lone.prg", "no lone.csv beside it")):
        rc, err = _run(["simulate", prg, "--truth", tmp_path / "true.yaml", "--sheet",
                        tmp_path / "sheet.json", "-o", tmp_path / "out"], capsys)
        assert rc == 2
        assert words in assert_one_line(err, prg)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_jobs_below_one_names_the_option_as_every_command_does(tmp_path, capsys):
    """calibrate and init said '--jobs must be ...' without the field; render, loop, verify
    and handeye name it ('--jobs: must be at least 1')."""
    (tmp_path / "photos").mkdir()
    paper = ROOT / "fixtures" / "paper_sm5"
    for argv in (["calibrate", paper, "-o", tmp_path / "o", "-j", "0"],
                 ["init", tmp_path / "photos", "--plan", paper / "session.json", "-j", "0"]):
        rc, err = _run(argv, capsys)
        assert rc == 2
        line = assert_one_line(err, "--jobs")
        assert "at least 1" in line and "got 0" in line
    assert [p.name for p in tmp_path.iterdir()] == ["photos"]


def test_a_bad_option_is_one_line_naming_it(tmp_path, capsys):
    """argparse printed the whole usage (eight lines for plan) before its error line."""
    with pytest.raises(SystemExit) as e:
        main(["plan", "cal.json", "t.csv", "-o", str(tmp_path / "p.csv"), "--home", "1"])
    assert e.value.code == 2
    line = assert_one_line(capsys.readouterr().err)
    assert line.startswith("vision-cal plan: error: --home: expected 2 arguments")
    assert "vision-cal plan --help" in line
    assert list(tmp_path.iterdir()) == []


def test_simulate_after_a_file_names_the_option(tmp_path):
    """--after X.pdf said 'X.pdf/truth.json: cannot read: Not a directory'."""
    (tmp_path / "x.pdf").write_bytes(PDF)
    with pytest.raises(VisionCalError) as e:
        _earlier_marks([tmp_path / "x.pdf"], "sheet-id")
    assert str(e.value).startswith(f"{tmp_path / 'x.pdf'}: --after: expected a folder")
