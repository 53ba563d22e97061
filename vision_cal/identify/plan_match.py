"""Photos that do not belong to the session (issue 18): refused, not calibrated.

After the association (``associate.associate``) the dots seen are compared with the plan:

- a photo showing far more dots than the marks it should show (more than
  ``max_dots_per_mark`` times as many, plus ``spare_dots`` for blemishes and an
  earlier pilot's marks), in most of the usable photos: another, finished sheet;
- fewer than ``min_matched_fraction`` of the marks the photos should show matched to a
  dot, while at least as many dots as those marks were seen and the photos should show
  at least ``min_marks_judged`` marks (fewer say little: a reversed series of three
  photos is a wrong order, reported by the inference): the dots are not where the plan and
  the robot model put them (another session's photos, another robot).

Either stops the run with a :class:`vision_cal.errors.CalibrationError` (exit 1) naming the
photos and what was seen, instead of calibrating with marks assigned to the wrong places.
The thresholds are config ``plan_match`` (:class:`vision_cal.config.PlanMatchConfig`).
"""

from __future__ import annotations

from vision_cal.config import DEFAULT, PlanMatchConfig
from vision_cal.errors import CalibrationError


def _names(files) -> str:
    files = list(files)
    return ", ".join(files[:4]) + (f" and {len(files) - 4} more" if len(files) > 4 else "")


def _dots_seen(im) -> int:
    """Dots found in a photo: refined, and seen but not refined."""
    return int(im.n_dots) + len(getattr(im, "seen_xy_mm", ()))


def check_plan_match(session_path, files, images, image_marks, n_groups: int,
                     matched: int, config: PlanMatchConfig | None = None) -> None:
    """Raise when the photos do not match the plan (see the module docstring).

    ``images``: per photo an ``ImageResult`` (``status``, ``n_dots`` and the dots only seen,
    ``seen_xy_mm``: :mod:`vision_cal.measure.views`); ``image_marks``: per
    photo the marks it should show; ``n_groups``: physical dots found over the photos;
    ``matched``: marks assigned to a dot; ``config`` the thresholds (default
    ``DEFAULT.plan_match``)."""
    cfg = config or DEFAULT.plan_match
    ok = [k for k, im in enumerate(images) if im.status == "ok"]
    if not ok:
        return
    n_dots = {k: _dots_seen(images[k]) for k in ok}
    crowded = [k for k in ok
               if n_dots[k] > cfg.max_dots_per_mark * len(image_marks[k]) + cfg.spare_dots]
    expected = {m for k in ok for m in image_marks[k]}
    if 2 * len(crowded) > len(ok):
        k = crowded[0]
        raise CalibrationError(
            f"the photos do not match the plan: {_names(files[i] for i in crowded)} show "
            f"{n_dots[k]} dots where {len(image_marks[k])} planned marks should be "
            f"({matched} of {len(expected)} marks could be matched): photos of another "
            "sheet or another session? Put the photos of this plan in the folder",
            file=str(session_path), field="images")
    if (len(expected) >= cfg.min_marks_judged and n_groups >= len(expected)
            and matched < cfg.min_matched_fraction * len(expected)):
        raise CalibrationError(
            f"the photos do not match the plan: only {matched} of {len(expected)} planned "
            f"marks could be matched to the {n_groups} dots seen on "
            f"{_names(files[i] for i in ok)} (the dots are not where the plan and the robot "
            "file put them: photos of another session, or another robot file?)",
            file=str(session_path), field="images")
