import json

import numpy as np
import pytest

from vision_cal.dataset.session import Mark, load_session, resolve_approach
from vision_cal.errors import VisionCalError


def _valid() -> dict:
    return {
        "format": "vision-cal/1",
        "sheet": {"aruco_dictionary": "DICT_5X5_100", "size_mm": [594, 420],
                  "markers": [{"id": 7, "corners_mm": [[0, 20], [20, 20], [20, 0], [0, 0]]},
                              {"id": 8, "corners_mm": [[50, 20], [70, 20], [70, 0], [50, 0]]}]},
        "robot": {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
                  "base_mm": [-250.0, 210.0], "home_deg": [0.0, 0.0]},
        "pen": {"mark_diameter_mm": 1.2},
        "marks": [{"id": "c00", "joints_deg": [0.0, 0.0], "role": "calibration"},
                  {"id": "v00", "joints_deg": [12.3, -40.1], "approach": [1, -1],
                   "role": "validation", "target_mm": [100.0, 150.0]}],
        "images": [{"file": "img_000.png", "marks": ["c00"]},
                   {"file": "img_001.png", "marks": ["c00", "v00"]}],
        "camera": {"size_px": [2400, 1800], "K": [[2000, 0, 1200], [0, 2000, 900], [0, 0, 1]],
                   "dist": [0.0, 0.0, 0.0, 0.0, 0.0]},
    }


def _write(tmp_path, d):
    (tmp_path / "session.json").write_text(json.dumps(d))
    return tmp_path


def test_reads_the_format_example(tmp_path):
    s = load_session(_write(tmp_path, _valid()))
    assert [m.id for m in s.marks] == ["c00", "v00"]
    assert s.marks[1].approach == (1, -1) and s.marks[1].target_mm == (100.0, 150.0)
    assert s.sheet.corners_by_id()[8].shape == (4, 2)
    assert s.camera.K[0, 0] == 2000 and s.images[1].marks == ("c00", "v00")
    assert s.robot.params.base_mm == (-250.0, 210.0)


def test_reads_the_paper_fixture_without_images(paper_folder):
    s = load_session(paper_folder)
    assert len(s.marks) == 5 and not s.images and s.sheet is None
    assert all(m.measured_mm is not None for m in s.marks)


def _mutate(path, value):
    d = _valid()
    obj = d
    for k in path[:-1]:
        obj = obj[k]
    if value is KeyError:
        del obj[path[-1]]
    else:
        obj[path[-1]] = value
    return d


@pytest.mark.parametrize("path,value,field,words", [
    (("robot", "L1_mm"), KeyError, "robot.L1_mm", "missing"),
    (("robot", "L1_mm"), "350", "robot.L1_mm", "expected a number"),
    (("marks", 1, "joints_deg"), ["12.3", -40.1], "marks[1].joints_deg[0]", "expected a number"),
    (("marks", 0, "joints_deg"), [float("nan"), 0.0], "marks[0].joints_deg[0]", "finite"),
    (("marks",), [], "marks", "non-empty"),
    (("marks", 1, "id"), "c00", "marks[1].id", "duplicate mark id"),
    (("sheet", "aruco_dictionary"), "DICT_9X9_7", "sheet.aruco_dictionary", "unknown ArUco"),
    (("sheet", "markers", 1, "id"), 7, "sheet.markers[1].id", "duplicate marker id"),
    (("images", 0, "marks"), ["c99"], "images[0].marks[0]", "not in marks"),
    (("format",), "vision-cal/2", "format", "expected 'vision-cal/1'"),
    (("marks", 1, "approach"), [1, 0], "marks[1].approach", "+1 or -1"),
    (("marks", 0, "role"), "training", "marks[0].role", "expected one of"),
    (("sheet", "markers", 0, "corners_mm"), [[0, 0]] * 3, "sheet.markers[0].corners_mm", "4 corners"),
    (("camera", "K"), [[1, 0, 0]], "camera.K", "3x3"),
    (("images", 0, "file"), "../x.png", "images[0].file", "inside the dataset folder"),
])
def test_each_malformed_field_is_named(tmp_path, path, value, field, words):
    folder = _write(tmp_path, _mutate(path, value))
    with pytest.raises(VisionCalError) as e:
        load_session(folder)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(str(folder / "session.json")), msg
    assert f": {field}: " in msg, msg
    assert words in msg, msg


def test_nan_literal_in_json_is_refused(tmp_path):
    text = json.dumps(_valid()).replace('"L2_mm": 260.0', '"L2_mm": NaN')
    (tmp_path / "session.json").write_text(text)
    with pytest.raises(VisionCalError, match=r"robot\.L2_mm: expected a finite number"):
        load_session(tmp_path)


def test_missing_file_and_bad_json(tmp_path):
    with pytest.raises(VisionCalError, match="session.json: missing"):
        load_session(tmp_path)
    (tmp_path / "session.json").write_text("{not json")
    with pytest.raises(VisionCalError, match="not valid JSON"):
        load_session(tmp_path)


def test_marks_without_position_need_images(tmp_path):
    d = _valid()
    d["images"] = []
    with pytest.raises(VisionCalError, match="images: no images, and mark 'c00'"):
        load_session(_write(tmp_path, d))


def test_approach_resolution_follows_the_format():
    marks = [Mark("a", (10.0, -5.0)), Mark("b", (10.0, 5.0)), Mark("c", (0.0, 5.0)),
             Mark("d", (0.0, 5.0), approach=(1, -1)), Mark("e", (0.0, 5.0))]
    s = resolve_approach(marks, (0.0, 0.0))
    # a: +q1 -q2; b: q1 still keeps +, q2 +; c: q1 -, q2 keeps +; d: given; e: keeps d's
    np.testing.assert_array_equal(s, [[1, -1], [1, 1], [-1, 1], [1, -1], [1, -1]])
