"""A synthetic dataset from a scene file (``vision-cal render``): the scene read with the
command's overrides and rendered (:func:`vision_cal.world.dataset.render_dataset`), its
pilot plan given by the estimator's side (the synthetic world imports none of it)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from vision_cal.estimate.paper import pilot_params
from vision_cal.dataset.out_folder import writing_into
from vision_cal.errors import VisionCalError
from vision_cal.world.dataset import render_dataset
from vision_cal.world.scene import load_scene


@dataclass(frozen=True)
class RenderRequest:
    """What ``vision-cal render`` was asked (see its ``--help``)."""

    scene: str                    # SCENE.yaml
    out: str
    seed: int | None = None       # overrides the scene's seed
    mode: str | None = None       # overrides photos.mode (series | single)
    jobs: int | None = None       # render processes (default: every core)
    quiet: bool = False


@dataclass(frozen=True)
class RenderOutcome:
    """The dataset folder written."""

    folder: Path

    def show(self, quiet: bool = False) -> int:
        print(self.folder)   # even when quiet: the folder to calibrate next
        return 0


def render(req: RenderRequest) -> RenderOutcome:
    """Render the scene of ``req.scene`` into ``req.out``."""
    if req.seed is not None and req.seed < 0:
        raise VisionCalError(f"expected a non-negative integer, got {req.seed}", field="--seed")
    scene = load_scene(req.scene).with_overrides(seed=req.seed, mode=req.mode)
    if req.jobs is not None and req.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {req.jobs}", field="--jobs")
    # OUT holds one dataset: an earlier render's goes to previous/render/ whole, files of
    # anything else are refused (dataset/out_folder.py); locked while written
    with writing_into(req.out, command="render", reads=[req.scene], alone=True, displace=False,
                      quiet=req.quiet):
        out = render_dataset(scene, req.out, progress=not req.quiet, pilot=pilot_params,
                             jobs=req.jobs or os.cpu_count())
    return RenderOutcome(Path(out))
