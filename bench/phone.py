"""Bench: phone cameras. Principal point off the image centre, focal length per photo.

Renders the end-to-end test's small scene (1000 x 750 photos, 24 marks) as a phone would
take it and calibrates from the photographs; prints the marks' RMS error against the truth
and the principal point the lens estimate found. Baseline in the same process: the same
photos measured with the lens model's principal point fixed at the image centre (OpenCV's
usual ``CALIB_FIX_PRINCIPAL_POINT``), which is what the measurer did before.

    .venv/bin/python bench/phone.py
"""

from __future__ import annotations

import copy
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> int:
    import yaml

    from vision_cal.calibrate.paper import pilot_params
    from vision_cal.measure import mapping
    from vision_cal.pipeline import calibrate_dataset
    from vision_cal.render.dataset import render_dataset
    from vision_cal.render.scene import scene_from_dict

    base = yaml.safe_load((ROOT / "renders" / "small.yaml").read_text())
    base["camera"].update(size_px=[1000, 750], f_px=1084.0, n_views=1, moving=False)
    base["photos"] = {"mode": "single", "texture_px_per_mm": 4.0}
    base["plan"].update(n_calibration=20, n_validation=4)
    base["robot"]["effects"] = []
    cases = {
        "centred pinhole, declared": {},
        "pp (+60, -45) px, focal +-6 % per photo, series": dict(
            principal_px=[559.5, 329.5], f_scatter=0.06, declared=False, n_views=3,
            moving=True),
        "barrel lens, centred, undeclared": dict(dist=[-0.12, 0.05, 0, 0, 0], declared=False),
        "barrel lens, pp (+60, -45) px, undeclared": dict(
            dist=[-0.12, 0.05, 0, 0, 0], declared=False, principal_px=[559.5, 329.5]),
        "barrel lens, pp off, focal +-6 % per photo, series": dict(
            dist=[-0.12, 0.05, 0, 0, 0], declared=False, principal_px=[559.5, 329.5],
            f_scatter=0.06, n_views=3, moving=True),
    }
    all_models = mapping.LENS_MODELS
    centred = tuple(m for m in all_models if m[0] != "k1k2_pp")
    print("mark RMS against truth (mm); principal point found (px); the lens estimate shares "
          "one K over the photos (a focal length per photo is not modelled)")
    for name, cam in cases.items():
        d = copy.deepcopy(base)
        d["seed"] = 12
        d["camera"].update(cam)
        if cam.get("f_scatter"):
            d["photos"]["mode"] = "series"
        sc = scene_from_dict(d, file="bench-phone")
        with tempfile.TemporaryDirectory() as tmp:
            folder = render_dataset(sc, Path(tmp) / "d", pilot=pilot_params)
            out = {}
            for label, models in (("measurer", all_models), ("centre fixed", centred)):
                mapping.LENS_MODELS = models
                try:
                    run = calibrate_dataset(folder, out_dir=Path(tmp) / label, truth=True)
                finally:
                    mapping.LENS_MODELS = all_models
                doc = run.document
                lens = [e for e in doc["effects"] if e["name"] == "lens_distortion"]
                pp = (f"({lens[0]['K'][0][2]:.1f}, {lens[0]['K'][1][2]:.1f})" if lens
                      else "no lens")
                out[label] = (doc["truth_comparison"]["mark_rms_mm"], pp)
        (a, pa), (b, pb) = out["measurer"], out["centre fixed"]
        print(f"  {name:<52} {a:.4f} mm {pa:<16} | centre fixed: {b:.4f} mm {pb:<16} "
              f"ratio {b / a:.1f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
