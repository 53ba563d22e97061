"""docs/format.md's JSON Schemas (shipped in the package) against the files we read and
write: fixtures, a rendered session, calibration.json of a run with photos, sheet.json and
the robot file; and the schema refuses what the readers refuse."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import jsonschema
import pytest
import yaml

from vision_cal.dataset.session import load_session
from vision_cal import sheet as sheet_pkg
from vision_cal.errors import VisionCalError
from vision_cal.schema import NAMES, load_schema, validate

ROOT = Path(__file__).resolve().parents[2]


def test_every_fixture_session_validates():
    found = sorted(ROOT.glob("fixtures/**/session.json"))
    assert found
    for p in found:
        validate(json.loads(p.read_text()), "session")


def test_robot_fixtures_validate():
    found = sorted(ROOT.glob("fixtures/robot*.yaml"))
    for p in found:
        validate(yaml.safe_load(p.read_text()), "robot")
    if not found:
        pytest.skip("no robot file fixture in this tree")


@pytest.fixture(scope="module")
def rendered_run(tmp_path_factory):
    """A one-photo rendered session and its calibration."""
    from dataclasses import replace

    from vision_cal.actions.pipeline import calibrate_dataset
    from vision_cal.world.dataset import render_dataset
    from vision_cal.world.scene import load_scene

    tmp = tmp_path_factory.mktemp("schema")
    sc = load_scene(ROOT / "renders" / "small.yaml").with_overrides(mode="single")
    sc = replace(sc, plan=replace(sc.plan, n_calibration=12, n_validation=3))
    from vision_cal.estimate.paper import pilot_params

    folder = render_dataset(sc, tmp / "data", pilot=pilot_params)
    run = calibrate_dataset(folder, out_dir=tmp / "out", jobs=1)
    return folder, run


@pytest.mark.render
def test_rendered_session_and_its_calibration_validate(rendered_run):
    folder, run = rendered_run
    validate(json.loads((folder / "session.json").read_text()), "session")
    doc = json.loads(run.out_path.read_text())
    assert doc["images"] and doc["marks"]
    validate(doc, "calibration")


def test_paper_calibration_validates(tmp_path, paper_folder):
    from vision_cal.actions.pipeline import calibrate_dataset

    for method in ("lsq", "paper"):
        run = calibrate_dataset(paper_folder, out_dir=tmp_path / method, method=method)
        validate(json.loads(run.out_path.read_text()), "calibration")


def test_sheet_json_from_the_sheet_command_validates(tmp_path):
    paths = sheet_pkg.write_sheet(sheet_pkg.make_layout(), tmp_path)
    doc = json.loads(Path(paths["json"]).read_text())
    validate(doc, "sheet")
    validate(doc, "sheet")


SESSION_BREAKS = [
    ("format", lambda d: d.pop("format")),
    ("marks[0].joints_deg", lambda d: d["marks"][0].__setitem__("joints_deg", [1.0, 2.0, 3.0])),
    ("marks[0].role", lambda d: d["marks"][0].__setitem__("role", "training")),
    ("marks[0].approach", lambda d: d["marks"][0].__setitem__("approach", [1, 0])),
    ("robot.L1_mm", lambda d: d["robot"].__setitem__("L1_mm", "350")),
    ("robot.base_mm", lambda d: d["robot"].pop("base_mm")),
    ("marks", lambda d: d.__setitem__("marks", [])),
]


@pytest.mark.parametrize("where,brk", SESSION_BREAKS, ids=[b[0] for b in SESSION_BREAKS])
def test_schema_and_reader_refuse_the_same_session(tmp_path, paper_folder, where, brk):
    d = json.loads((paper_folder / "session.json").read_text())
    brk(d)
    with pytest.raises(jsonschema.ValidationError):
        validate(d, "session")
    (tmp_path / "session.json").write_text(json.dumps(d))
    with pytest.raises(VisionCalError):
        load_session(tmp_path)


def test_added_fields_are_allowed(paper_folder):
    d = json.loads((paper_folder / "session.json").read_text())
    d["written_by"] = {"tool": "another program"}
    d["marks"][0]["pressure_n"] = 2.0
    validate(d, "session")


def test_calibration_schema_refuses_a_broken_document(tmp_path, paper_folder):
    from vision_cal.actions.pipeline import calibrate_dataset

    doc = json.loads(calibrate_dataset(paper_folder, out_dir=tmp_path).out_path.read_text())
    for brk in (lambda d: d.pop("std"), lambda d: d["residual_rms_mm"].pop("final_model"),
                lambda d: d.__setitem__("effects", [{"name": "joint_wobble"}]),
                lambda d: d.__setitem__("effects", [{"name": "joint_backlash", "joint": 2}]),
                lambda d: d["images"].append({"file": "x.png", "status": "skipped"}),
                lambda d: d.__setitem__("format", "vision-cal/1")):
        bad = copy.deepcopy(doc)
        brk(bad)
        with pytest.raises(jsonschema.ValidationError):
            validate(bad, "calibration")


def test_format_md_documents_every_schema_field():
    """docs/format.md names every property the schemas know (the schema is not a second,
    undocumented contract)."""
    text = (ROOT / "docs" / "format.md").read_text()

    def props(s, out):
        if isinstance(s, dict):
            for k, v in (s.get("properties") or {}).items():
                out.add(k)
                props(v, out)
            for key in ("items", "additionalProperties"):
                props(s.get(key), out)
            for sub in s.get("allOf", []):
                props(sub.get("then"), out)
        return out

    for name in NAMES:
        for field in props(load_schema(name), set()):
            assert re.search(rf"\b{re.escape(field)}\b", text), (name, field)
