import json
import os

import numpy as np
import pytest

from vision_cal.dataset.io import atomic_write_json


def test_atomic_write_leaves_old_file_on_failure(tmp_path):
    p = tmp_path / "calibration.json"
    atomic_write_json(p, {"a": np.float64(1.5), "b": np.arange(3)})
    assert json.loads(p.read_text()) == {"a": 1.5, "b": [0, 1, 2]}
    with pytest.raises(TypeError):
        atomic_write_json(p, {"bad": object()})
    assert json.loads(p.read_text())["a"] == 1.5
    assert [f for f in os.listdir(tmp_path) if f != "calibration.json"] == []


def test_non_finite_numbers_become_null(tmp_path):
    p = atomic_write_json(tmp_path / "x.json", {"v": float("nan"), "w": [1.0, float("inf")]})
    assert json.loads(p.read_text()) == {"v": None, "w": [1.0, None]}
