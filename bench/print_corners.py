"""A sheet printed off its layout: the measured marker corners against the world's two
readings of a printed marker's corners (the points, and where its straight-fitted sides
meet: world/print_deviation.py).

Usage: .venv/bin/python bench/print_corners.py DATASET OUT [DATASET OUT ...]

For each calibrated folder (OUT holds measurement.json): every photo's ``markers_px``
back-projected onto the sheet with truth.json's pose and K, minus truth.json's corners,
fitted per photo by ``e_x = a + b x + c y`` (mm); then the corners' error averaged over
the photos (RMS per axis), and measurement.json ``as_printed`` corners against truth. Each
against ``print.markers`` (the points) and ``print.markers_straight_sides`` (recomputed
from ``print.params`` for a truth.json written before that field).

Seed 2871 of renders/printed_off_six.yaml (feed wave 153 mm): ``c`` is -1.44e-4 against
the points (what looked like a shear of the print), -0.8e-5 against the straight sides.
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from vision_cal.world.print_deviation import PrintField  # noqa: E402


def truth_corners(folder: Path) -> dict:
    """{"points": {id: (4, 2)}, "straight_sides": {id: (4, 2)}} from truth.json."""
    truth = json.loads((folder / "truth.json").read_text())
    pr = truth["print"]
    pts = {int(k): np.asarray(v, float) for k, v in pr["markers"].items()}
    if "markers_straight_sides" in pr:
        st = {int(k): np.asarray(v, float) for k, v in pr["markers_straight_sides"].items()}
    else:
        sheet = json.loads((folder / "session.json").read_text())["sheet"]
        x0, y0 = sheet["bottom_left_mm"]
        w, h = sheet["size_mm"]
        f = PrintField((x0, y0, x0 + w, y0 + h), pr["params"],
                       np.asarray(pr["removed_similarity"], float), float(pr["scale"]),
                       float(pr["toner_mm"]))
        ids = sorted(pts)
        # the layout's grown corners: the printed points carried back through the field
        P = np.array([pts[i] for i in ids])
        lx, ly = f.layout_at(P[..., 0], P[..., 1])
        grown = np.stack([lx, ly], axis=-1)
        c = grown - f.toner_mm * np.sign(grown - grown.mean(axis=1, keepdims=True))
        st = dict(zip(ids, f.straight_side_corners(c)))
    return {"points": pts, "straight_sides": st}


def evaluate(folder: Path, out: Path) -> dict:
    truth = json.loads((folder / "truth.json").read_text())
    meas = json.loads((out / "measurement.json").read_text())
    K = np.asarray(truth["camera"]["K"], float)
    poses = truth["camera"]["T_cam_sheet"]
    ref = truth_corners(folder)
    res = {}
    for name, tc in ref.items():
        coef, acc = [], defaultdict(list)
        for im in meas["images"]:
            if im["status"] != "ok" or not im["marker_ids"]:
                continue
            M = np.asarray(poses[im["file"]], float)
            H = K @ np.column_stack([M[:3, 0], M[:3, 1], M[:3, 3]])
            px = np.asarray(im["markers_px"], float).reshape(-1, 2)
            q = np.column_stack([px, np.ones(len(px))]) @ np.linalg.inv(H).T
            q = q[:, :2] / q[:, 2:]
            ids = [int(i) for i in im["marker_ids"]]
            L = np.concatenate([tc[i] for i in ids])
            e = q - L
            B = np.column_stack([np.ones(len(L)), L])
            coef.append(np.linalg.lstsq(B, e[:, 0], rcond=None)[0])
            for i, ee in zip(ids, e.reshape(-1, 4, 2)):
                acc[i].append(ee)
        coef = np.array(coef)
        mean = np.concatenate([np.mean(v, axis=0) for v in acc.values()])
        r = {"n_photos": len(coef), "ex_per_y_mean": float(coef[:, 2].mean()),
             "ex_per_y_std": float(coef[:, 2].std()), "ex_per_x_mean": float(coef[:, 1].mean()),
             "corner_mean_rms_x_mm": float(np.sqrt(np.mean(mean[:, 0] ** 2))),
             "corner_mean_rms_y_mm": float(np.sqrt(np.mean(mean[:, 1] ** 2)))}
        ap = (meas.get("as_printed") or {}).get("markers") or []
        if ap:
            e = np.concatenate([np.asarray(m["corners_mm"], float) - tc[int(m["id"])]
                                for m in ap])
            r["as_printed_rms2d_mm"] = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
        res[name] = r
    return res


def main() -> int:
    a = sys.argv[1:]
    if not a or len(a) % 2:
        print(__doc__.splitlines()[3].strip(), file=sys.stderr)
        return 2
    for folder, out in zip(a[0::2], a[1::2]):
        print(Path(folder).name, json.dumps(evaluate(Path(folder), Path(out))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
