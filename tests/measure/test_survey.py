"""vision-cal survey: the sheet as printed from photos of it taken from several places."""

import json

import numpy as np
import pytest

from tests.measure import synth_measure as sm
from vision_cal.commands.main import main
from vision_cal.errors import VisionCalError
from tests.measure.similarity import similarity as _similarity
from vision_cal.measure.survey import load_survey
from vision_cal.world.print_deviation import PrintScene

#: (tilt, azimuth): one nearly straight down, five tilted round the sheet
PLACES = [(3, 0), (22, 0), (22, 72), (22, 144), (22, 216), (22, 288)]


@pytest.fixture(scope="module")
def surveyed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("survey")
    sheet = sm.small_sheet()
    corners = np.array([m.corners_mm for m in sheet.markers])
    field = PrintScene(0.25, 0.0).field(sheet.extent_mm, corners, seed=7)
    tex = sm.texture(sheet, [], print_field=field)
    photos = tmp / "photos"
    photos.mkdir()
    for k, (tilt, az) in enumerate(PLACES):
        K, T = sm.view(tilt_deg=tilt, azimuth_deg=az, dist_mm=520.0)
        sm.write_png(photos / f"s{k}.png", sm.photo(sheet, tex, K=K, T=T, rng=k, noise=1.0))
    (tmp / "sheet.json").write_text(json.dumps(sheet.to_json()))
    code = main(["survey", str(photos), "--sheet", str(tmp / "sheet.json"),
                 "--out", str(tmp / "out"), "-q"])
    truth = field.printed_at(corners.reshape(-1, 2)) - corners.reshape(-1, 2)
    return code, tmp, sheet, truth


def test_survey_measures_the_print(surveyed):
    code, tmp, sheet, truth = surveyed
    assert code == 0
    doc = json.loads((tmp / "out" / "survey.json").read_text())
    ap = doc["as_printed"]
    got = np.array([m["corners_mm"] for m in ap["markers"]]).reshape(-1, 2) - \
        np.array([m["declared_mm"] for m in ap["markers"]]).reshape(-1, 2)
    # the truth in the survey's gauge: no similarity to the declared corners
    dec = np.array([m["declared_mm"] for m in ap["markers"]]).reshape(-1, 2)
    tx, ty, a, b = _similarity(dec, truth)
    t = truth - np.column_stack([tx + a * dec[:, 0] - b * dec[:, 1],
                                 ty + b * dec[:, 0] + a * dec[:, 1]])
    rms_true = float(np.sqrt(np.mean(np.sum(truth**2, axis=1))))
    assert abs(doc["print"]["rms_mm"] - rms_true) < 0.2 * rms_true
    err = got - t
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < max(3 * ap["unresolved_mm"], 0.02)
    after = [p["corner_rms_px_after"] for p in doc["photos"]]
    before = [p["corner_rms_px_before"] for p in doc["photos"]]
    assert max(after) < min(before)
    assert doc["verdict"]["status"] in ("good", "limited") and doc["verdict"]["text"]


def test_survey_is_checked_against_the_sheet(surveyed):
    _, tmp, sheet, _ = surveyed
    ap = load_survey(tmp / "out" / "survey.json", sheet)
    assert ap.source == "survey"
    d = sheet.to_json()
    d["markers"][2]["corners_mm"] = (np.array(d["markers"][2]["corners_mm"]) + 1.0).tolist()
    other = type(sheet)(**{**sheet.__dict__, "markers": tuple(
        type(m)(m.id, np.asarray(c["corners_mm"], float)) for m, c in
        zip(sheet.markers, d["markers"]))})
    with pytest.raises(VisionCalError, match=r"as_printed.markers\[2\].declared_mm"):
        load_survey(tmp / "out" / "survey.json", other)


def test_survey_from_one_place_is_refused(tmp_path):
    sheet = sm.small_sheet()
    tex = sm.texture(sheet, [])
    (tmp_path / "p").mkdir()
    K, T = sm.view(tilt_deg=10, azimuth_deg=0, dist_mm=520.0)
    for k in range(3):
        sm.write_png(tmp_path / "p" / f"s{k}.png", sm.photo(sheet, tex, K=K, T=T, rng=k))
    (tmp_path / "sheet.json").write_text(json.dumps(sheet.to_json()))
    assert main(["survey", str(tmp_path / "p"), "--sheet", str(tmp_path / "sheet.json"),
                 "--out", str(tmp_path / "o"), "-q"]) == 2
    assert not (tmp_path / "o" / "survey.json").exists()


def test_survey_never_writes_over_its_sheet(tmp_path):
    sheet = sm.small_sheet()
    (tmp_path / "p").mkdir()
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "survey.json").write_text(json.dumps(sheet.to_json()))
    before = (tmp_path / "o" / "survey.json").read_text()
    assert main(["survey", str(tmp_path / "p"), "--sheet", str(tmp_path / "o" / "survey.json"),
                 "--out", str(tmp_path / "o"), "-q"]) == 2
    assert (tmp_path / "o" / "survey.json").read_text() == before


def test_a_second_survey_keeps_the_first_in_previous(surveyed, capsys):
    """The output folders' one owner: a survey into a folder holding an earlier survey moves
    that one to previous/ (byte for byte), and the sheet beside it stays where it is."""
    code, tmp, _, _ = surveyed
    first = (tmp / "out" / "survey.json").read_bytes()
    assert main(["survey", str(tmp / "photos"), "--sheet", str(tmp / "sheet.json"),
                 "--out", str(tmp / "out"), "-q"]) == 0
    assert (tmp / "out" / "previous" / "survey" / "survey.json").read_bytes() == first
    assert (tmp / "out" / "survey.json").is_file()

