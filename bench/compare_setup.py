"""Inputs both sides of ``bench/compare_outputs.py`` read (its ``setup`` case): three
placements of marks (``tests/tool/test_placements._places``, seed 100), a still camera's
small rendered series (``renders/small.yaml``, seed 41, one view, tilted, as
``tests/camera/test_fixed_render.py``; and looking square down), each also without its
camera block (the focal length fitted: undetermined when square), a moving camera's
(``renders/small.yaml``, seed 12) and the real six-axis session's ChArUco board (``vision-cal sheet --charuco``).
With ``--arm`` (its ``setup_arm`` case) instead: four sessions of the arm's camera rendered
by the world (``tests/camera/test_arm_render.py``'s robot and sizes): the lens declared
(seed 23, a photo listed that is missing), declared with a barrel distortion (seed 5, k1
-0.045), left out and tilted 20-25 deg so the views estimate it (seed 29), left out and
square to the sheet so they cannot (seed 31); and three files of pose pairs from the
world's own controller and detector (a fixed camera, 30 pairs; an arm camera, 300 pairs
with 0.1 px of corner noise; an arm camera, 20 pairs, 1 mm / 0.5 deg of board pose noise).

    python bench/compare_setup.py SHARED_FOLDER [--arm]

It runs with the first side's package, so it finds the world where that version keeps it
(:func:`world`).
"""

from __future__ import annotations

import copy
import importlib
import json
import shutil
import sys
from pathlib import Path

import yaml

from tests.tool.test_placements import _places
from vision_cal.estimate.paper import pilot_params
from vision_cal.commands.main import main

ROOT = Path.cwd()


def world(name: str):
    """The world's module ``name`` where this version keeps it: ``vision_cal.world`` since
    issue 39's move, ``vision_cal.render`` (or ``vision_cal.simulate``) before; the worlds
    only tests and benches use (``pose_pairs``) in the root's ``worlds/`` since issue 39's
    third step, in ``vision_cal.world`` (or before) until then."""
    for package in ("worlds", "vision_cal.world", "vision_cal.render", "vision_cal.simulate"):
        try:
            return importlib.import_module(f"{package}.{name}")
        except ModuleNotFoundError:
            continue
    raise ModuleNotFoundError(f"no world module {name!r}")


def setup(shared: Path) -> None:
    (shared / "places").mkdir(parents=True, exist_ok=True)
    _places(shared / "places")
    ds, scene_from_dict = world("dataset"), world("scene").scene_from_dict
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


TRUTH = {"L1_mm": 344.05, "L2_mm": 259.87, "joint_zero_deg": [-2.57, -8.13],
         "base_mm": [-424.26, -230.35]}
NOMINAL = {"L1_mm": 350.0, "L2_mm": 260.0, "joint_zero_deg": [0.0, 0.0],
           "base_mm": [-410.0, -240.0]}
ARM = {"truth": TRUTH, "nominal": NOMINAL, "size_px": (640, 480), "f_px": 720.0}


def arm_sessions(shared: Path) -> None:
    render_arm_dataset = world("arm_camera").render_arm_dataset
    folder = render_arm_dataset(shared / "arm", n_poses=12, seed=23, **ARM)
    s = json.loads((folder / "session.json").read_text())
    s["poses"].append({"image": "missing.png", "joints_deg": [0.0, 90.0], "j4_deg": 0.0})
    (folder / "session.json").write_text(json.dumps(s))
    render_arm_dataset(shared / "arm_dist", n_poses=12, seed=5,
                       dist=[-0.045, 0.0, 0.0, 0.0, 0.0], **ARM)
    render_arm_dataset(shared / "arm_nocam", n_poses=10, seed=29, tilt_deg=(20.0, 25.0),
                       declare_lens=False, **ARM)
    render_arm_dataset(shared / "arm_square", n_poses=8, seed=31, tilt_deg=0.5,
                       declare_lens=False, **ARM)


def pairs_files(shared: Path) -> None:
    robot = world("truth_model").TrueRobot(344.05, 259.87, (-2.57, -8.13), (-424.26, -230.35))
    for name, n, seed, mount, noise in (
            ("pairs_fixed", 30, 3901, "fixed", {"noise_px": 0.1}),
            ("pairs_many", 300, 3902, "arm", {"noise_px": 0.1}),
            ("pairs_pose", 20, 3903, "arm", {"noise_px": None, "noise_mm": 1.0,
                                              "noise_deg": 0.5})):
        w = world("pose_pairs").simulate_pairs(robot, n, seed=seed, mount=mount, **noise)
        doc = {"format": "vision-cal/poses/1", "mount": mount,
               "target_z_mm": float(w["Y"][2, 3]),
               "pairs": [{"id": f"p{i:03d}", "T_robot_flange": a.tolist(),
                          "T_camera_target": b.tolist()}
                         for i, (a, b) in enumerate(zip(w["A"], w["B"]))]}
        (shared / f"{name}.json").write_text(json.dumps(doc))


if __name__ == "__main__":
    out = Path(sys.argv[1])
    if sys.argv[2:] == ["--arm"]:
        out.mkdir(parents=True, exist_ok=True)
        arm_sessions(out)
        pairs_files(out)
    else:
        setup(out)
