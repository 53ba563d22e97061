"""The renderer photographs a printed sheet's own raster (``vision-cal sheet --png-dpi``)."""

import json
from pathlib import Path

import numpy as np
import pytest

from vision_cal.estimate.paper import pilot_params
from vision_cal.commands.main import main
from vision_cal.errors import VisionCalError
from vision_cal.world.printed import load_printed_sheet, printed_texture
from vision_cal.world.scene import load_scene

RENDERS = Path(__file__).resolve().parents[2] / "renders"
SMALL = load_scene(RENDERS / "small.yaml")   # an A2 sheet, textures at 2 px/mm


@pytest.fixture(scope="module")
def sheet_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("printed")
    assert main(["sheet", "--size", "A2", "--png-dpi", str(2 * 25.4), "--out", str(d), "-q"]) == 0
    return d


def test_texture_is_the_print_with_paper_and_ink(sheet_dir):
    pr = load_printed_sheet(sheet_dir / "sheet.json")
    assert pr.px_per_mm == pytest.approx(2.0) and pr.rgb.shape == (840, 1188, 3)
    tex = printed_texture(pr, marks_xy_mm=[[0.0, 0.0]], mark_diameters_mm=4.0, rng=1,
                          paper_grain=False)
    # print and texture share the pixel grid: ink stays ink, white becomes the paper colour
    black = pr.rgb.sum(axis=2) == 0
    assert black.sum() > 0 and tex[black].max() == 0
    white = (pr.rgb.min(axis=2) == 255)
    white[400:440, 574:614] = False                     # the dot at the origin
    assert np.all(tex[white] == np.rint(np.array([247.0, 245.0, 238.0])).astype(np.uint8))
    # the dot at the sheet origin: pixel (row 419.5, col 593.5) is the paper centre
    assert tex[419:421, 593:595].max() < 100


def test_rasters_that_do_not_fit_are_refused(sheet_dir, tmp_path):
    with pytest.raises(VisionCalError, match="sheet.png: not found"):
        load_printed_sheet(sheet_dir / "sheet.json", png=tmp_path / "sheet.png")
    doc = json.loads((sheet_dir / "sheet.json").read_text())
    doc["printed"]["png_dpi"] = 300.0
    (tmp_path / "sheet.json").write_text(json.dumps(doc))
    (tmp_path / "sheet.png").write_bytes((sheet_dir / "sheet.png").read_bytes())
    with pytest.raises(VisionCalError, match="whole number of pixels"):
        load_printed_sheet(tmp_path / "sheet.json")


@pytest.mark.render
def test_rendered_photos_of_the_print_measure_where_truth_is(sheet_dir, tmp_path):
    from vision_cal.dataset.session import load_session
    from vision_cal.actions.measure_folder import measure_folder
    from vision_cal.world.dataset import render_dataset

    pr = load_printed_sheet(sheet_dir / "sheet.json")
    scene = SMALL.with_overrides(mode="single")
    out = render_dataset(scene, tmp_path / "data", pilot=pilot_params, printed=pr)
    session = json.loads((out / "session.json").read_text())
    sheet_json = json.loads((sheet_dir / "sheet.json").read_text())
    assert session["sheet"]["markers"] == sheet_json["markers"]
    assert session["sheet"]["printed"] == sheet_json["printed"]
    # the photo shows the print itself: its blue scale bars, which no analytic sheet has
    import cv2

    photo = cv2.imread(str(out / session["images"][0]["file"])).astype(int)
    blue = (photo[:, :, 0] - photo[:, :, 2]) > 80           # BGR: blue minus red
    print(f"blue pixels {blue.sum()}")
    assert blue.sum() > 200
    truth = json.loads((out / "truth.json").read_text())["marks"]
    meas = measure_folder(load_session(out), out_dir=tmp_path / "m", jobs=1)
    assert [im.status for im in meas.images] == ["ok"]
    on_paper = [k for k in truth if k in meas.marks]
    assert len(on_paper) >= 8
    z = np.array([(meas.marks[k].xy_mm - truth[k]) / np.sqrt(np.diag(meas.marks[k].cov_mm2))
                  for k in on_paper])
    print(f"{len(on_paper)} marks, max |z| {np.abs(z).max():.2f}")
    assert np.abs(z).max() < 4.5


def test_a_scene_can_name_a_printed_sheet(sheet_dir, tmp_path):
    from vision_cal.world.scene import load_scene

    scene_yaml = (RENDERS / "small.yaml").read_text()
    (tmp_path / "s.yaml").write_text(scene_yaml + f"sheet:\n  printed: {sheet_dir}/sheet.json\n")
    sc = load_scene(tmp_path / "s.yaml")
    assert sc.sheet.printed == str(sheet_dir / "sheet.json")
    assert sc.sheet.size_mm == (594.0, 420.0)
    (tmp_path / "bad.yaml").write_text(scene_yaml + f"sheet:\n  printed: {sheet_dir}/sheet.json"
                                       "\n  marker_mm: 20\n")
    with pytest.raises(VisionCalError, match="sheet.printed: a printed sheet brings its own"):
        load_scene(tmp_path / "bad.yaml")
    (tmp_path / "missing.yaml").write_text(scene_yaml + "sheet:\n  printed: nowhere/sheet.json\n")
    with pytest.raises(VisionCalError, match="sheet.printed: .*not found"):
        load_scene(tmp_path / "missing.yaml")
