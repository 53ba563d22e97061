"""Every block of the README is typed by a test, or says which one covers it (issue 38).

``COVERED`` names, for each shell block of README.md (its heading and first line), the test
that types it: here, the rehearsal's folder (tests/test_rehearsal.py: the rehearsal, the
hidden change, the survey, as written), or, for a block that needs a real robot, a camera or
photos, the test that runs the same commands on the simulated robot. A new README block
without an entry fails here, and so does an entry whose block is gone. The "Commands"
block lists every subcommand, and each of its lines parses with the command line's own
parser (every option it shows exists).
"""

from __future__ import annotations

import re
import shlex

import pytest

from tests.readme import blocks, blocks_under
from vision_cal.commands.main import SUBCOMMANDS, main

#: (heading, first line) -> what types it
COVERED = {
    ("Quick start", "make demo"): "CI (.ci/run runs make test); make demo: tests/test_loop.py",
    ("Quick start", ". .venv/bin/activate"): "test_the_quick_start_help_runs (here)",
    ("Calibrate your robot", "vision-cal sheet --size A2 --out sheet/"):
        "tests/test_rehearsal.py (the rehearsal block types it)",
    ("Calibrate your robot", "vision-cal survey photos/ --sheet sheet/sheet.json --out sheet/"):
        "tests/test_rehearsal.py::test_a_survey_rehearsed_measures_the_print",
    ("Calibrate your robot", "vision-cal design robot.yaml --sheet sheet/sheet.json --out pilot/"):
        "tests/test_rehearsal.py (the rehearsal block types it)",
    ("Calibrate your robot", "vision-cal design robot.yaml --sheet sheet/sheet.json --pilot "
                             "pilot_cal/calibration.json --out plan/"):
        "tests/test_rehearsal.py (the rehearsal block types it)",
    ("Calibrate your robot", "vision-cal plan cal/calibration.json targets.csv -o "
                             "targets_plan.csv --program spel --robot robot.yaml"):
        "tests/test_rehearsal.py (the rehearsal block types it)",
    ("Rehearse it first (no robot)", "vision-cal robot-template -o robot.yaml"):
        "tests/test_rehearsal.py (typed as written)",
    ("Rehearse it first (no robot)", "perl -pe 's/-8\\.13\\]/-8.09]/' true_robot.yaml > "
                                     "moved_robot.yaml"):
        "tests/test_rehearsal.py::test_verify_finds_a_moved_joint_2_zero (typed as written)",
    ("Rehearse a survey (a printer that is off)",
     "perl -pe 's/deviation_rms_mm: 0\\.0 /deviation_rms_mm: 0.15/' true_robot.yaml > "
     "printer_off.yaml"):
        "tests/test_rehearsal.py::test_a_survey_rehearsed_measures_the_print (as written)",
    ("Calibrate your camera", "vision-cal plan/ --out cal/"):
        "tests/camera/test_camera_rehearsal.py (a fixed camera: the same commands, small photos)",
    ("Calibrate your camera", "vision-cal sheet --size A2 --field --out field/"):
        "tests/camera/test_camera_rehearsal.py (the arm camera: the same commands, 10 poses)",
    ("Calibrate your camera", "vision-cal handeye --poses pairs.json --z-mm 0 --out he/"):
        "tests/camera/test_pose_pairs.py (pose pairs from another tool's files)",
    ("Calibrate your camera", "vision-cal calibrate marks.csv --robot robot.yaml --sigma-mm "
                              "0.02 --out cal/"):
        "tests/dataset/test_marks_csv.py (fixtures/tracker_example)",
    ("Calibrate your camera", "vision-cal sheet --charuco 5x7 --square-mm 36.195 --marker-mm "
                              "18.256 --dictionary DICT_6X6_250 --out board/"):
        "tests/camera/test_handeye6_real.py (the real session's board and photos, the same "
        "requests)",
    ("Calibrate your camera", "vision-cal handeye photos/ --robot-poses poses/ --sheet "
                              "board/sheet.json --mount arm --out arm_he/"):
        "tests/camera/test_handeye6_use.py (the same locate and export requests on a six-axis "
        "world's calibration)",
    ("Commands", "vision-cal images/ --report"): "test_the_commands_block_is_complete_and_parses",
}


def _key(b) -> tuple[str, str]:
    first = re.split(r" {3,}", b.commands[0])[0].strip()
    return b.heading, first


def test_every_readme_block_is_typed_or_says_what_covers_it():
    keys = [_key(b) for b in blocks()]
    missing = [k for k in keys if k not in COVERED]
    assert not missing, f"README blocks no test types (add them to COVERED): {missing}"
    stale = [k for k in COVERED if k not in keys]
    assert not stale, f"COVERED names blocks the README no longer has: {stale}"


def test_the_quick_start_help_runs(capsys):
    (block,) = [b for b in blocks_under("Quick start") if b.commands[0].startswith(". ")]
    assert block.commands[1] == "vision-cal --help"
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0 and "usage: vision-cal" in capsys.readouterr().out


def _parse(argv):
    """The parser's namespace for ``argv`` (SystemExit: an option it does not know)."""
    from vision_cal.commands.main import build_parser

    return build_parser().parse_args(argv)


def test_the_commands_block_is_complete_and_parses(capsys):
    """Every subcommand is listed (survey, handeye, locate, simulate, verify and
    robot-template were missing) and every line parses: its options exist."""
    (block,) = blocks_under("Commands")
    listed = set()
    for line in block.commands:
        if not line.startswith("vision-cal "):
            continue
        cmd = re.split(r" {3,}", line)[0]
        cmd = re.sub(r"\[[^\]]*\]", " ", cmd)        # optional parts shown in brackets
        argv = shlex.split(cmd)[1:]
        if argv[0] not in SUBCOMMANDS:   # calibrate is the default (main does the same)
            argv.insert(0, "calibrate")
        listed.add(argv[0])
        try:
            _parse(argv)
        except SystemExit as e:
            pytest.fail(f"{line!r} does not parse: {capsys.readouterr().err} ({e})")
    assert listed == set(SUBCOMMANDS), set(SUBCOMMANDS) - listed


def test_the_headline_figures_are_generated_not_typed():
    """The README's headline table is exactly docs/figures.json rendered (bench/figures.py
    readme), and every row names the command whose output it is."""
    import importlib.util
    import json

    from tests.conftest import ROOT

    spec = importlib.util.spec_from_file_location("figures", ROOT / "bench" / "figures.py")
    figures = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(figures)
    doc = json.loads((ROOT / "docs" / "figures.json").read_text())
    assert figures.readme_block(doc) in (ROOT / "README.md").read_text()
    assert all(r.get("source") for r in doc["rows"]), doc["rows"]
    assert {"paper", "demo_loop", "demo_backlash"} <= {r["key"] for r in doc["rows"]}


def test_the_demo_rows_read_a_demo_run_in_another_folder(tmp_path):
    """`bench/figures.py demo OTHER/out` (a fresh clone's demo): loop.json names its
    calibration relative to where the demo ran, OUT's parent, not this repository."""
    import importlib.util
    import json

    from tests.conftest import ROOT

    spec = importlib.util.spec_from_file_location("figures", ROOT / "bench" / "figures.py")
    figures = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(figures)
    out = tmp_path / "out"
    for rel, doc in {
            "paper_sm5/calibration.json": {"params": {"L1_mm": 344.0, "L2_mm": 259.9,
                                                      "joint_zero_deg": [-2.6, -8.1]}},
            "demo/loop.json": {"calibration": "out/demo/calibration/calibration.json",
                               "summary": {"n_targets": 3, "before": {"rms_mm": 9.0},
                                           "after": {"rms_mm": 0.0123, "max_mm": 0.02}}},
            "demo/calibration/calibration.json": {
                "effects": [{"name": "joint_backlash", "deg": 0.0987, "std": 0.0007}],
                "verdict": {"text": "ready to use: elsewhere"}}}.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_text(json.dumps(doc))
    doc = json.loads((ROOT / "docs" / "figures.json").read_text())
    figures.from_demo(doc, out)
    row = next(r for r in doc["rows"] if r["key"] == "demo_backlash")
    assert row["figure"].startswith("found 0.0987") and "elsewhere" in row["figure"], row
