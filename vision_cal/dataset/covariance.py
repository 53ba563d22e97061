"""calibration.json's ``covariance`` block (docs/format.md): written from a fit's internal
covariance, read back into the internal units of a model's parameter vector.

The block is in file units (mm, degrees, unitless scale)::

    "covariance": {"params": ["L1_mm", "L2_mm", "z1_deg", "z2_deg", "base_x_mm",
                              "base_y_mm", "joint_backlash(joint 2).deg", ...],
                   "matrix": [[...], ...]}

Without it (files written before it existed) :func:`load_covariance` takes the ``std``
block's diagonal for the six base parameters, correlations ignored (said in a warning).
The calibration writes it (``pipeline``, ``estimate/``), the planner reads it
(:mod:`vision_cal.plan.uncertainty`): it lives with the file formats, so the calibration
does not import the planner for it.
"""

from __future__ import annotations

import logging

import numpy as np

from vision_cal.errors import VisionCalError

log = logging.getLogger(__name__)


def _file_labels_and_scale(labels) -> tuple[list[str], np.ndarray]:
    """File names of the model's internal parameter labels and internal->file factors."""
    out, scale = [], []
    for lab in labels:
        if lab in ("z1", "z2"):
            out.append(f"{lab}_deg")
            scale.append(np.degrees(1.0))
        elif lab.endswith(".deg") or lab.endswith("_deg"):
            out.append(lab)
            scale.append(np.degrees(1.0))
        else:
            out.append(lab)
            scale.append(1.0)
    return out, np.array(scale)


def covariance_json(labels, cov_internal) -> dict:
    """The ``covariance`` field of calibration.json from a fit's internal covariance."""
    names, s = _file_labels_and_scale(labels)
    c = np.asarray(cov_internal, dtype=float) * np.outer(s, s)
    return {"params": names, "matrix": c.tolist()}


def load_covariance(doc: dict, model, *, file: str | None = None) -> np.ndarray:
    """Internal-unit covariance (P, P) matching ``model.vector`` from a calibration doc."""
    names, s = _file_labels_and_scale(model.param_labels())
    block = doc.get("covariance")
    if block is not None:
        try:
            got = list(block["params"])
            m = np.asarray(block["matrix"], dtype=float)
        except (KeyError, TypeError, ValueError) as e:
            raise VisionCalError(f"malformed covariance: {e}", file=file,
                                 field="covariance") from e
        if m.shape != (len(got), len(got)):
            raise VisionCalError(f"expected a {len(got)}x{len(got)} matrix, got {m.shape}",
                                 file=file, field="covariance.matrix")
        idx = {n: i for i, n in enumerate(got)}
        missing = [n for n in names if n not in idx]
        if missing:
            raise VisionCalError(f"has no entry for {', '.join(missing)} (the model's "
                                 "parameters)", file=file, field="covariance.params")
        k = [idx[n] for n in names]
        return m[np.ix_(k, k)] / np.outer(s, s)
    std = doc.get("std")
    if not isinstance(std, dict):
        raise VisionCalError("missing: neither covariance nor std is given", file=file,
                             field="std")
    log.warning("%s: no covariance: predicted std from the base parameters' std only "
                "(correlations and effects ignored)", file)
    try:
        d = [std["L1_mm"], std["L2_mm"], std["joint_zero_deg"][0], std["joint_zero_deg"][1],
             std["base_mm"][0], std["base_mm"][1]]
        d = np.asarray(d, dtype=float)
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise VisionCalError(f"malformed std: {e}", file=file, field="std") from e
    cov = np.zeros((len(names), len(names)))
    cov[:6, :6] = np.diag((d / s[:6]) ** 2)
    return cov
