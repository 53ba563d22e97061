"""Inputs both sides of ``bench/compare_outputs.py`` read (its ``setup`` case): three
placements of marks (``tests/tool/test_placements._places``, seed 100), a still camera's
small rendered series (``renders/small.yaml``, seed 41, one view, tilted, as
``tests/camera/test_fixed_render.py``; and looking square down), each also without its
camera block (the focal length fitted: undetermined when square), a moving camera's
(``renders/small.yaml``, seed 12) and the real six-axis session's ChArUco board (``vision-cal sheet --charuco``).

    python bench/compare_setup.py SHARED_FOLDER
"""

from __future__ import annotations

import copy
import json
import shutil
import sys
from pathlib import Path

import yaml

from tests.tool.test_placements import _places
from vision_cal.calibrate.paper import pilot_params
from vision_cal.commands.main import main
from vision_cal.world import dataset as ds
from vision_cal.world.scene import scene_from_dict

ROOT = Path.cwd()


def setup(shared: Path) -> None:
    (shared / "places").mkdir(parents=True, exist_ok=True)
    _places(shared / "places")
    d = yaml.safe_load((ROOT / "renders" / "small.yaml").read_text())
    still = copy.deepcopy(d)
    still["seed"] = 41
    still["camera"].update(n_views=1, moving=False, tilt_deg=[5.0, 12.0])
    ds.render_dataset(scene_from_dict(still, file="still-scene"), shared / "still",
                      pilot=pilot_params)
    ds.render_dataset(scene_from_dict(copy.deepcopy(d), file="small-scene"), shared / "small",
                      pilot=pilot_params)
    square = copy.deepcopy(still)
    square["camera"].update(tilt_deg=[0.0, 0.0])
    ds.render_dataset(scene_from_dict(square, file="square-scene"), shared / "square",
                      pilot=pilot_params)
    for name in ("still", "square"):     # no camera block: the focal length is fitted
        src, dst = shared / name, shared / f"{name}_nocam"
        shutil.copytree(src, dst)
        s = json.loads((dst / "session.json").read_text())
        s.pop("camera", None)
        (dst / "session.json").write_text(json.dumps(s, indent=1))
    assert main(["sheet", "--charuco", "5x7", "--square-mm", "36.195", "--marker-mm", "18.256",
                 "--dictionary", "DICT_6X6_250", "--out", str(shared / "board"), "-q"]) == 0


if __name__ == "__main__":
    setup(Path(sys.argv[1]))
