"""The synthetic world shares no code with the estimator but the JSON reading.

If the world computed an effect with the estimator's own function (``RobotModel.predict``,
the kinematics, a calibrator), a convention error there would cancel between the data and
the fit and no test could see it. render/ and simulate/ may read the format's blocks with
the estimator's readers (scene.py: ``effect_from_json``, ``ScaraParams``, ``RobotModel``
for tests that compare the two codes); nothing else from it (the sheet geometry,
vision_cal.dataset.marker_geometry, belongs to the sheet description, not the estimator).
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2] / "vision_cal"
ESTIMATOR = ("vision_cal.model.robot", "vision_cal.model.kinematics", "vision_cal.calibrate",
             "vision_cal.diagnose", "vision_cal.measure", "vision_cal.workflows.pipeline",
             "vision_cal.model.joint_terms", "vision_cal.camera", "vision_cal.workflows.verify")
#: (file, module) -> names allowed: reading the format's JSON blocks
JSON_READING = {("scene.py", "vision_cal.model.robot"): {"Effect", "RobotModel", "effect_from_json"},
                ("scene.py", "vision_cal.model.kinematics"): {"ScaraParams"}}


def _imports(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            yield node.module, {a.name for a in node.names}
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, {a.name}


def test_world_imports_nothing_of_the_estimator():
    bad = []
    for sub in ("render", "simulate", "world"):
        for path in sorted((ROOT / sub).glob("*.py")):
            for module, names in _imports(path):
                if not module.startswith(ESTIMATOR):
                    continue
                allowed = JSON_READING.get((path.name, module), set())
                if not names <= allowed:
                    bad.append(f"{sub}/{path.name}: from {module} import "
                               f"{', '.join(sorted(names - allowed))}")
    assert not bad, bad
