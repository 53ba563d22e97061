import importlib
import json
import re
import subprocess
import sys

import pytest

from vision_cal.commands.main import SUBCOMMANDS, main


def test_paper_method_writes_table2(paper_folder, tmp_path, capsys):
    rc = main([str(paper_folder), "--method", "paper", "--out", str(tmp_path)])
    assert rc == 0
    doc = json.loads((tmp_path / "calibration.json").read_text())
    p = doc["params"]
    assert round(p["L1_mm"], 1) == 344.1 and round(p["L2_mm"], 1) == 259.9
    assert [round(z, 1) for z in p["joint_zero_deg"]] == [-2.6, -8.1]
    assert doc["format"] == "vision-cal/calibration/1"
    assert set(doc["marks"]) == {"c00", "j1p", "j1n", "j2p", "j2n"}
    assert all(v is not None for v in doc["std"]["joint_zero_deg"])
    out = capsys.readouterr().out
    assert "paper Table 2" in out and "344.052" in out


def test_lsq_default_has_std_and_residuals(paper_folder, tmp_path):
    assert main(["calibrate", str(paper_folder), "-o", str(tmp_path), "-q"]) == 0
    doc = json.loads((tmp_path / "calibration.json").read_text())
    assert doc["method"] == "lsq" and doc["std"]["L1_mm"] > 0
    assert doc["residual_rms_mm"]["final_model"] < 1.0
    r = doc["marks"]["c00"]["residual_mm"]
    assert len(r) == 2


def test_bad_dataset_exits_2_with_one_line(tmp_path, capsys):
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "session.json").write_text('{"format": "vision-cal/1"}')
    assert main([str(tmp_path / "d"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "robot: missing required field" in err
    assert not (tmp_path / "o" / "calibration.json").exists()


def test_uncalibratable_exits_1(tmp_path, capsys):
    d = json.loads((__import__("pathlib").Path(__file__).parents[2] / "fixtures" / "paper_sm5"
                    / "session.json").read_text())
    d["marks"] = d["marks"][:2]
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "session.json").write_text(json.dumps(d))
    assert main([str(tmp_path / "d"), "--out", str(tmp_path / "o")]) == 1
    assert "at least 3" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--help"], ["calibrate", "--help"]])
def test_help_shows_examples(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 0
    assert "vision-cal" in capsys.readouterr().out


def test_console_script_version():
    out = subprocess.run([sys.executable, "-m", "vision_cal.commands.main", "--version"],
                         capture_output=True, text=True, check=True).stdout
    assert out.startswith("vision-cal ")


def test_plan_command_writes_plan_and_trajectory(paper_folder, tmp_path, capsys):
    from pathlib import Path

    from vision_cal.dataset.csvio import read_plan

    targets = Path(__file__).parents[2] / "fixtures" / "targets_origin.csv"
    assert main([str(paper_folder), "--method", "paper", "--out", str(tmp_path), "-q"]) == 0
    cal = tmp_path / "calibration.json"
    assert main(["plan", str(cal), str(targets), "-o", str(tmp_path / "plan.csv"),
                 "--trajectory", str(tmp_path / "traj.csv"), "--force"]) == 3   # far: partial
    err = capsys.readouterr().err
    assert "target far" in err and "out of reach" in err
    ids, q, s = read_plan(tmp_path / "plan.csv")
    assert ids == ["origin", "p1"] and (s == 1).all()
    # consistency (FK of the planned IK, not a paper figure; the paper's Table 3 is checked
    # against its measured numbers in tests/estimate/test_paper.py): the calibrated
    # model puts the planned command on the sheet origin
    doc = json.loads(cal.read_text())
    from vision_cal.model.kinematics import ScaraParams, forward

    assert abs(forward(ScaraParams.from_json(doc["params"]), q[:1])[0]).max() < 1e-4
    traj = (tmp_path / "traj.csv").read_text().splitlines()
    assert traj[0] == "t_s,q1_deg,q2_deg,qd1_deg_s,qd2_deg_s,pen"
    t = [float(r.split(",")[0]) for r in traj[1:]]
    assert abs(t[1] - t[0] - 0.016) < 1e-9
    assert sum(int(r.split(",")[-1]) for r in traj[1:]) >= 2
    # nominal model: a different plan
    assert main(["plan", str(cal), str(targets), "-o", str(tmp_path / "before.csv"),
                 "--model", "nominal", "-q"]) == 3   # far: partial
    _, qn, _ = read_plan(tmp_path / "before.csv")
    assert abs(qn - q).max() > 1.0


def test_many_folders_one_failing(paper_folder, tmp_path, capsys):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "session.json").write_text("{broken")
    rc = main(["calibrate", str(paper_folder), str(bad), "--out", str(tmp_path / "res")])
    assert rc == 1
    out = capsys.readouterr()
    assert "not valid JSON" in out.err
    assert (tmp_path / "res" / "paper_sm5" / "calibration.json").exists()
    summary = json.loads((tmp_path / "res" / "summary.json").read_text())
    assert [r["status"] for r in summary["folders"]] == ["ok", "failed"]
    assert "paper_sm5" in out.out and "failed" in out.out


@pytest.mark.parametrize("sub", ["calibrate", "render", "plan", "loop", "export", "design"])
def test_every_subcommand_help_has_an_example(sub, capsys):
    with pytest.raises(SystemExit) as e:
        main([sub, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "examples:" in out and f"vision-cal {sub if sub != 'calibrate' else ''}".strip() in out


def test_plan_trajectory_starts_at_home(paper_folder, tmp_path):
    """The session's home_deg reaches the trajectory through calibration.json; --home wins."""
    from pathlib import Path

    session = json.loads((Path(paper_folder) / "session.json").read_text())
    session["robot"]["home_deg"] = [10.0, -20.0]
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "session.json").write_text(json.dumps(session))
    targets = Path(__file__).parents[2] / "fixtures" / "targets_origin.csv"
    assert main([str(tmp_path / "ds"), "--out", str(tmp_path / "cal"), "-q"]) == 0
    cal = tmp_path / "cal" / "calibration.json"
    assert json.loads(cal.read_text())["home_deg"] == [10.0, -20.0]

    def first_pose(*extra):
        traj = tmp_path / "traj.csv"
        assert main(["plan", str(cal), str(targets), "-o", str(tmp_path / "plan.csv"), "-q",
                     "--trajectory", str(traj), "--force", *extra]) == 3   # far: partial
        row = traj.read_text().splitlines()[1].split(",")
        return float(row[1]), float(row[2])

    assert first_pose() == (10.0, -20.0)
    assert first_pose("--home", "5", "-7") == (5.0, -7.0)


def test_calibration_run_keeps_the_model_calibration_json_holds(paper_folder, tmp_path):
    """run_loop plans with CalibrationRun.model instead of re-reading calibration.json:
    both must be the same robot."""
    import numpy as np

    from vision_cal.dataset.calibration import load_calibration
    from vision_cal.actions.pipeline import calibrate_dataset

    for method in ("lsq", "paper"):
        run = calibrate_dataset(paper_folder, out_dir=tmp_path / method, method=method)
        back, _ = load_calibration(run.out_path)
        q = np.array([[10.0, 20.0], [-30.0, 80.0], [45.0, -60.0]])
        s = np.array([[1, -1], [-1, 1], [1, 1]])
        np.testing.assert_allclose(run.model.predict(q, s), back.predict(q, s), atol=1e-9)


def test_help_examples_keep_their_line_breaks():
    """A ``\\`` ending an example line inside a help string joins it to the next (the
    continuation's indent left inside the command): type ``\\\\``. ``simulate --help``
    showed ``--sheet sheet/sheet.json       --targets ...`` on one line."""
    for sub in SUBCOMMANDS:
        mod = importlib.import_module(f"vision_cal.commands.{sub.replace('-', '_')}")
        for line in (getattr(mod, "EXAMPLES", "") or "").splitlines():
            assert not re.search(r"\S {3,}--\w", line), (sub, line)
