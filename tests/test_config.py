"""The estimator's configuration: one documented object, read when used, recorded in
calibration.json."""

import ast
import inspect
import json
from dataclasses import fields, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import vision_cal
from tests.estimate.test_discover import _world
from tests.estimate.test_verdict import REP, _fit_doc
from tests.measure import synth_measure as sm
from tests.measure.test_measure_grid import _mapping_shifted
from tests.measure.test_measure_no_images import _groups
from tests.tool.test_placements import _kinematic_places
from tests.measure.synth_measure import measure_image
from vision_cal.estimate import joint4, placements
from vision_cal.camera import pose_pairs
from vision_cal.config import (DEFAULT, AssociationConfig, DiscoveryConfig, DotConfig,
                               EstimatorConfig, GridConfig, GridDeclarationConfig, Joint4Config,
                               PhotoAgreementConfig, PlanMatchConfig, SelectionConfig,
                               SheetHeightConfig, SmoothResidualConfig, VerdictConfig)
from vision_cal.dataset.session import SheetGrid, load_session
from vision_cal.estimate import discover, sheet, verdict
from vision_cal.estimate import verify as check
from vision_cal.estimate.select import diagnose
from vision_cal.errors import CalibrationError
from vision_cal.identify import associate, infer, plan_match
from vision_cal.measure import (asprinted, dots, grid, grid_declaration, height,
                                photo_agreement, replicate, sheetfit, survey)
from vision_cal.measure.cache import session_fingerprint
from vision_cal.estimate.marks import MarkData
from vision_cal.actions.pipeline import calibrate_dataset
from vision_cal.world.camera import project
from vision_cal.world.truth_model import TrueRobot
from vision_cal.report.headline import configuration

#: the modules whose thresholds moved into config.py, and the module-level numbers they may
#: still keep (physical, format or statistical constants, not thresholds)
CONFIGURED = {dots: (), grid: (), sheetfit: (), discover: (), joint4: (),
              verdict: ("R95_PER_RMS",), check: (), associate: (), height: (), plan_match: (),
              photo_agreement: (), grid_declaration: (), placements: (), infer: (),
              pose_pairs: ("_TINY",),   # a numerical guard (exact synthetic pairs)
              asprinted: (), survey: (), replicate: (),
              # the smoother's cost bounds (not judgements: the test stays exact)
              sheet: ("EXACT_MAX_MARKS", "GRID_PER_LENGTH", "MAX_GRID_CELLS")}


def _module_numbers(module) -> set[str]:
    """UPPER_CASE module-level names bound to a number or to a read of ``DEFAULT``."""
    out = set()
    for node in ast.parse(inspect.getsource(module)).body:
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AnnAssign) and node.value else [])
        for t in targets:
            if not (isinstance(t, ast.Name) and t.id.isupper()):
                continue
            src = ast.unparse(node.value)
            if (isinstance(node.value, ast.Constant) and isinstance(node.value.value, (int, float))
                    or "DEFAULT" in src):
                out.add(t.id)
    return out


def test_no_default_argument_reads_the_config_at_import():
    """A default argument is evaluated once, at import: none reads a field of ``DEFAULT``
    (``None`` there, the config read in the body)."""
    root = Path(vision_cal.__file__).parent
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for d in node.args.defaults + [d for d in node.args.kw_defaults if d]:
                    if "DEFAULT." in ast.unparse(d):
                        found.append(f"{path.relative_to(root)}:{node.lineno} {node.name}")
    assert not found, found


def test_no_module_copies_a_threshold_at_import():
    """No configured module keeps a module-level number or a copy of ``DEFAULT`` (they were
    module globals, frozen at import), nor a global named after a config field."""
    names = {f.name.upper() for part in fields(EstimatorConfig)
             for f in fields(part.default_factory)}
    for module, allowed in CONFIGURED.items():
        assert _module_numbers(module) <= set(allowed), module.__name__
        assert not names & set(vars(module)), module.__name__
    assert not hasattr(grid, "DOTS")


def test_the_recorded_config_reads_back():
    assert EstimatorConfig.from_json(DEFAULT.to_json()) == DEFAULT
    # an older file without a part or a field: the defaults
    assert EstimatorConfig.from_json({"dots": {"ink_darkening": 0.5}}).dots == \
        DotConfig(ink_darkening=0.5)


def test_calibration_json_says_how_it_was_obtained(paper_folder, tmp_path):
    calibrate_dataset(paper_folder, out_dir=tmp_path / "d")
    doc = json.loads((tmp_path / "d" / "calibration.json").read_text())
    assert doc["config"] == DEFAULT.to_json()
    assert set(doc["config"]) == {"markers", "dots", "association", "selection", "fit",
                                  "per_photo_offsets", "sheet_fit", "grid", "sheet_height",
                                  "plan_match", "photo_agreement", "grid_declaration",
                                  "smooth_residual", "discovery", "joint4", "verdict",
                                  "verify", "handeye", "handeye_photos", "as_printed", "uncertainty"}
    assert doc["config"]["selection"]["alpha"] == 0.01
    cfg = replace(DEFAULT, selection=SelectionConfig(alpha=1e-3, k_folds=3, max_effects=1))
    calibrate_dataset(paper_folder, out_dir=tmp_path / "c", config=cfg)
    doc = json.loads((tmp_path / "c" / "calibration.json").read_text())
    assert doc["config"]["selection"] == dict(DEFAULT.to_json()["selection"], alpha=1e-3,
                                              k_folds=3, max_effects=1)
    assert doc["diagnosis"]["heldout"] == "3-fold cross-validation"
    # a dots setting is taken (it was refused while dots.py copied it at import) and recorded
    dots = DotConfig(ink_darkening=0.4)
    calibrate_dataset(paper_folder, out_dir=tmp_path / "e", config=replace(DEFAULT, dots=dots))
    doc = json.loads((tmp_path / "e" / "calibration.json").read_text())
    assert EstimatorConfig.from_json(doc["config"]).dots == dots


def test_a_dot_threshold_passed_in_changes_the_measurement(tmp_path):
    """A non-default dots setting is used (pipeline.py refused it while dots.py copied its
    thresholds at import): blobs below 10 times a mark's area are noise, so none of the
    photo's marks is kept; the setting is part of the cache key (the cached default run
    does not answer for it), and a non-default setting is recorded."""
    sheet = sm.small_sheet()
    marks = sm.free_targets(sheet, 12, rng=3, box=(95.0, 70.0))
    K, T = sm.view(tilt_deg=10.0, azimuth_deg=-40.0)
    (tmp_path / "in").mkdir()
    sm.write_png(tmp_path / "in" / "a.png",
                 sm.photo(sheet, sm.texture(sheet, marks, rng=4), K=K, T=T, noise=2.0, rng=7))
    ids = [f"m{i:02d}" for i in range(len(marks))]
    sm.write_session(tmp_path / "in", sm.session_json(
        sheet, marks=[(i, (0.0, 0.0)) for i in ids], images=[("a.png", ids)]))
    session = load_session(tmp_path / "in")
    assert measure_image(tmp_path / "in" / "a.png", session).n_dots >= 10
    cfg = replace(DEFAULT, dots=DotConfig(min_area_ratio=10.0, max_area_ratio=20.0,
                                          huge_area_ratio=30.0))
    im = measure_image(tmp_path / "in" / "a.png", session, config=cfg)
    assert im.status == "ok" and im.n_dots == 0
    assert session_fingerprint(session, cfg) != session_fingerprint(session, DEFAULT)
    assert EstimatorConfig.from_json(json.loads(json.dumps(cfg.to_json()))) == cfg


def test_the_verdict_judges_by_the_thresholds_the_file_recorded():
    """A missing coupling leaves ~6x the floor: "not reliable" by the default thresholds;
    the same document recording a larger ``not_reliable_ratio`` is "check", one recording a
    tolerance beyond its ratio passes the gate (judge reads ``doc["config"]``)."""
    eff = [{"name": "joint_terms", "joint": 2, "terms": [{"feature": "q1*q2", "coef": 2e-5}]}]
    doc = _fit_doc(eff, seed=11)
    v = verdict.judge(doc, repeatability_mm=REP)
    assert v.status == "not reliable" and 2 < v.residual_over_floor < 50
    doc["config"] = replace(DEFAULT, verdict=VerdictConfig(not_reliable_ratio=100.0)).to_json()
    assert verdict.judge(doc, repeatability_mm=REP).status == "check"
    doc["config"] = replace(DEFAULT, verdict=VerdictConfig(floor_ratio_tol=100.0)).to_json()
    assert not verdict.judge(doc, repeatability_mm=REP).floor["beyond"]


def test_a_discovery_setting_passed_in_changes_the_search():
    """A coupling discovery names by default (tests/estimate/test_discover.py) is not
    searched for with ``max_terms = 0``, and the scans' level follows ``scan_level``."""
    _, q, s, t, xy = _world([{"name": "joint_terms", "joint": 2,
                              "terms": [{"feature": "q1", "coef": 0.003}]}], seed=7)
    sig = np.full(len(q), 0.0104)
    d = diagnose(q, xy, s, sigma_mm=sig)
    assert discover.trace(d, q, xy, s, t, sigma_mm=sig).report["steps"]
    cfg = replace(DEFAULT, discovery=DiscoveryConfig(max_terms=0, scan_level=0.25))
    tr = discover.trace(d, q, xy, s, t, sigma_mm=sig, alpha=0.01, config=cfg)
    assert not tr.report.get("steps") and tr.report["alpha"] == 0.0025


def test_a_joint4_setting_passed_in_changes_what_is_kept():
    """A 0.4 % joint-4 gear-ratio error is kept at the default 4 std, not at 1e6 std, and
    the threshold used is what ``diagnosis.joint4`` records."""
    rng = np.random.default_rng(11)
    n = 36
    q = np.column_stack([rng.uniform(10, 100, n), rng.uniform(-110, -40, n)])
    j4 = rng.uniform(-160, 160, n)
    truth = TrueRobot.from_json({"L1_mm": 344.05, "L2_mm": 259.87,
                                 "joint_zero_deg": [-2.57, -8.13], "base_mm": [-424.26, -230.35],
                                 "tool_mm": [-18.7, 22.4]},
                                [{"name": "joint_scale", "joint": 4, "scale": 0.004}])
    s = np.ones((n, 3))
    xy = truth.pen_mm(np.column_stack([q, j4]), s) + rng.normal(0, 0.01, (n, 2))
    cal = MarkData(tuple(f"c{i:02d}" for i in range(n)), q, np.ones((n, 2)), xy, None,
                   ("calibration",) * n, np.column_stack([j4, np.ones(n)]))
    assert [e for e, _ in joint4.joint4_stage(cal).accepted] != []
    st = joint4.joint4_stage(cal, replace(DEFAULT, joint4=Joint4Config(accept_sigma=1e6)))
    assert not st.accepted and st.rejected and st.to_json()["accept_sigma"] == 1e6


def test_a_grid_setting_passed_in_changes_what_is_read():
    """The printed lines around a dot are read at the default contrast; demanding twice the
    contrast they show, or more pitches than the window holds, refuses them."""
    sheet = sm.small_sheet()
    marks = sm.free_targets(sheet, 12, rng=5)
    K, T = sm.view(tilt_deg=15.0)
    img = sm.photo(sheet, sm.texture(sheet, marks, rng=3), K=K, T=T, noise=2.0, rng=4)
    m = _mapping_shifted(K, T, np.zeros(2))
    (u, v), = project(marks[:1], K=K, T_cam_sheet=T)
    u0, v0 = int(round(u)) - 60, int(round(v)) - 60
    patch = img[v0:v0 + 121, u0:u0 + 121]
    go = grid.grid_offset(patch, (u0, v0), m, marks[0], sheet.grid_spec, exclude_r_mm=1.2)
    assert go is not None
    for cfg in (GridConfig(min_contrast=2 * float(np.min(go.snr))), GridConfig(min_periods=40.0)):
        assert grid.grid_offset(patch, (u0, v0), m, marks[0], sheet.grid_spec,
                                exclude_r_mm=1.2, config=cfg) is None, cfg


def test_a_sheet_height_setting_passed_in_changes_the_claim():
    """A 0.5 mm bump is claimed by default, not when the claim needs 1 mm; the grid step
    of the map follows ``map_step_mm``; the offset floor widens a height's std."""
    rng = np.random.default_rng(2)
    xy = rng.uniform([-250, -180], [250, 180], (40, 2))
    bump = 0.5 * np.exp(-np.sum((xy - [50, 20]) ** 2, axis=1) / (2 * 60.0**2))
    z, sd, ext = bump + rng.normal(0, 0.02, 40), np.full(40, 0.02), (-297, -210, 297, 210)
    hm = height.HeightMap.from_estimate(xy, z, sd, ext)
    assert hm.claimed and np.allclose(np.diff(hm.x_mm), 20.0)
    cfg = replace(DEFAULT, sheet_height=SheetHeightConfig(min_claim_mm=1.0, map_step_mm=50.0))
    hm = height.HeightMap.from_estimate(xy, z, sd, ext, config=cfg)
    assert not hm.claimed and np.allclose(np.diff(hm.x_mm), 50.0)
    C, p = np.array([60.0, -150.0, 700.0]), np.array([120.0, 80.0])
    obs = [(C, p, 0.4 * (p - C[:2]) / C[2], np.eye(2) * 1e-6)]
    h0 = height.height_from_grid(obs)
    h1 = height.height_from_grid(obs, replace(DEFAULT, sheet_height=SheetHeightConfig(
        offset_floor_mm=0.08)))
    assert h1.std_mm == pytest.approx(10 * h0.std_mm, rel=0.01)


def _photos(n_dots, shift_mm=(0.0, 0.0), grid_offset_mm=None):
    """Three photos of the same 6 dots (the last shifted by ``shift_mm``)."""
    xy = np.array([[10.0 * i, 5.0 * i] for i in range(6)])
    out = []
    for k in range(3):
        d = xy + (np.asarray(shift_mm) if k == 2 else 0.0)
        off = np.full((6, 2), np.nan) if grid_offset_mm is None else np.tile(grid_offset_mm, (6, 1))
        out.append(SimpleNamespace(status="ok", n_dots=n_dots, dots_xy_mm=d,
                                   dots_grid_offset_mm=off))
    return out


def test_a_plan_match_setting_passed_in_changes_what_is_refused():
    """Photos showing 20 dots where 2 marks should be are another sheet (refused); allowed
    20 dots per mark they are not."""
    images, marks = _photos(20), [["a", "b"]] * 3
    with pytest.raises(CalibrationError, match="do not match the plan"):
        plan_match.check_plan_match("s.json", ["1", "2", "3"], images, marks, 2, 2)
    plan_match.check_plan_match("s.json", ["1", "2", "3"], images, marks, 2, 2,
                                PlanMatchConfig(max_dots_per_mark=20.0))


def test_a_photo_agreement_setting_passed_in_changes_what_is_left_out():
    """A photo whose dots all sit 0.5 mm off is left out; allowed 1 mm it stays."""
    images = _photos(6, shift_mm=(0.5, 0.0))
    assert list(photo_agreement.disagreeing_photos(images)) == [2]
    assert photo_agreement.disagreeing_photos(
        images, PhotoAgreementConfig(max_offset_mm=1.0)) == {}


def test_a_grid_declaration_setting_passed_in_changes_the_finding():
    """Lines 0.2 mm off everywhere are a misdeclared grid; demanding 0.3 mm they are not."""
    images, g = _photos(6, grid_offset_mm=(0.2, -0.2)), SheetGrid(1.0, 10, (0.0, 0.0))
    found = grid_declaration.misdeclared_grid(images, g)
    assert found is not None and np.allclose(found.offset_mm, (0.2, -0.2))
    assert grid_declaration.misdeclared_grid(
        images, g, GridDeclarationConfig(min_offset_mm=0.3)) is None


def test_a_smooth_residual_setting_passed_in_changes_the_test():
    """A smooth field is reported at the default level, on a map of the configured step;
    below the smallest p its permutations resolve (1 / 2000) it cannot be."""
    rng = np.random.default_rng(0)
    xy = rng.uniform([-260, -180], [260, 180], (38, 2))
    z = 0.6 * np.exp(-np.sum((xy - [60, 40]) ** 2, axis=1) / (2 * 70.0**2))
    r = z[:, None] * (xy - [100.0, -150.0]) / 700.0 + rng.normal(0, 0.01, xy.shape)
    ext = (-297.0, -210.0, 297.0, 210.0)
    out = sheet.smooth_residual(xy, r, ext, config=SmoothResidualConfig(map_step_mm=100.0))
    assert out is not None and np.allclose(np.diff(out["map"]["x_mm"]), 100.0)
    assert sheet.smooth_residual(xy, r, ext, config=SmoothResidualConfig(alpha=1e-4)) is None


def test_a_selection_setting_passed_in_changes_the_placements_fit():
    """The joint fit of several placements reads ``selection`` from the config passed in:
    a once-per-turn error it names by default is not added with ``max_effects = 0``."""
    def cyclic(rng):
        return rng, {"name": "joint_cyclic", "joint": 1, "harmonic": 1, "deg": 0.003,
                     "phase_deg": float(rng.uniform(-180, 180))}

    places = _kinematic_places(1502, cyclic)
    assert placements.fit_placements(places)[0].effects
    cfg = replace(DEFAULT, selection=SelectionConfig(max_effects=0))
    assert not placements.fit_placements(places, config=cfg)[0].effects


def test_the_report_shows_the_recorded_verdict_thresholds():
    """The report's configuration is the file's: a recorded non-default gate level is
    shown, a file without the part shows none (not today's defaults)."""
    cfg = replace(DEFAULT, verdict=VerdictConfig(floor_alpha=1e-4)).to_json()
    assert configuration({"config": cfg})["verdict"]["floor_alpha"] == 1e-4
    assert configuration({"config": {"dots": {}}})["verdict"] == {}


def test_an_association_setting_passed_in_changes_the_inferred_photos():
    """Two photos, the second seeing 3 of the 4 dots (75 %): the finished sheet twice by
    default (>= 70 %), a series when the finished sheet needs 80 %."""
    ids, files = ["a", "b", "c", "d"], ["p0", "p1"]
    seen = [{0, 1}, {0, 1}, {0, 1}, {0}]
    assert infer.infer_image_marks(2, [0, 1], _groups(seen), ids, files).mode == "finished"
    got = infer.infer_image_marks(2, [0, 1], _groups(seen), ids, files,
                                  AssociationConfig(finished_fraction=0.8))
    assert got.mode == "series"
