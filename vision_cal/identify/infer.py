"""Which planned marks each photo shows, when ``session.json`` has no ``images`` list.

The photos are in capture order (EXIF time, else natural file name). Pen marks are only
ever added, so a dot group (one physical dot, :func:`vision_cal.identify.associate.group_dots`)
that is a pen mark stays visible in the photos after the one it first appeared in. From
the dot groups:

- *persistent* groups are the ones seen in at least half of the usable photos from their
  first one on (a dot seen once and never again is noise or a reflection, not ink);
- **finished sheet**: every usable photo sees most (config ``association.finished_fraction``) of the
  persistent groups: each photo shows every mark of the plan;
- **series**: otherwise. Photo k shows the first ``n_k`` marks of the plan, ``n_k`` the
  number of persistent groups first seen in photos up to k (capped at the plan's length),
  less the dots that were on the sheet before the series: when the last photo has more
  persistent dots than the plan has marks, that excess (at most what the first photo
  showed) is taken as earlier marks (a pilot plan drawn on the same sheet) or blemishes.

What does not fit is reported, never fatal: a photo that adds no mark in a series (a
repeated photo; one that also shows fewer dots than the photo before it was taken before
it, *out of order*, and is left out), one that adds several (a photo of the series missing, or several marks
drawn between photos), more persistent dots than planned marks, fewer (marks not drawn or
not photographed). The association (``associate.associate``) then works as with a
hand-written list, and checks the series against the robot model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vision_cal.config import DEFAULT, AssociationConfig


@dataclass(frozen=True)
class Inferred:
    """``marks``: per photo (session order) the tuple of mark ids it shows (empty for a
    photo that was not usable); ``mode``: "series" | "finished" | "none"."""

    marks: tuple[tuple[str, ...], ...]
    mode: str
    warnings: tuple[str, ...] = ()


def infer_image_marks(n_images: int, usable: list[int], groups, mark_ids, files,
                      config: AssociationConfig | None = None, *, earlier_mm=None,
                      tol_mm: float = 1.0) -> Inferred:
    """``usable``: indices of usable photos in capture order; ``groups``: DotGroups over
    them; ``mark_ids``: the plan's ids in drawing order; ``files``: names for messages;
    ``config``: the finished-sheet share (default ``DEFAULT.association``);
    ``earlier_mm`` (K, 2): marks known to be on the sheet from an earlier plan (session.json
    ``design.earlier_marks_mm``: the pilot's), extra dots within ``tol_mm`` of one named
    as such."""
    finished_fraction = (config or DEFAULT.association).finished_fraction
    mark_ids = [str(m) for m in mark_ids]
    N = len(mark_ids)
    empty = [()] * n_images
    if not usable:
        return Inferred(tuple(empty), "none", ("no usable photo of the sheet",))
    pos = {k: r for r, k in enumerate(usable)}  # image index -> rank among usable photos
    seen_by = [set(g.images) for g in groups]
    persistent = []
    for gi, s in enumerate(seen_by):
        first = min(pos[k] for k in s)
        later = len(usable) - first
        if len(s) * 2 >= later:
            persistent.append(gi)
    P = len(persistent)
    warnings: list[str] = []
    if P == 0:
        return Inferred(tuple(empty), "none", ("no pen mark found in any photo",))
    first_of = {gi: min(pos[k] for k in seen_by[gi]) for gi in persistent}
    frac = [sum(k in seen_by[gi] for gi in persistent) / P for k in usable]
    out = list(empty)
    if min(frac) >= finished_fraction:
        mode = "finished"
        for k in usable:
            out[k] = tuple(mark_ids)
        if P > N:
            warnings.append(f"{P} persistent dots in photos of the finished sheet, {N} marks "
                            "planned: " + _extra_dots(P - N, [groups[gi] for gi in persistent],
                                                      earlier_mm, tol_mm))
        elif P < N:
            warnings.append(f"{P} dots found for {N} planned marks: {N - P} mark(s) not seen "
                            "(not drawn, hidden, or too faint)")
    else:
        mode = "series"
        count = [sum(1 for gi in persistent if first_of[gi] <= r) for r in range(len(usable))]
        # more dots than planned marks by the end: the excess was on the sheet before the
        # series began (an earlier plan's marks, a blemish), seen from the first photo on
        pre = min(max(0, count[-1] - N), count[0])
        if pre:
            known = _n_known([groups[gi] for gi in persistent if first_of[gi] == 0],
                             earlier_mm, tol_mm)
            warnings.append(f"{pre} dot(s) already on the sheet in the first photo "
                            f"({files[usable[0]]}) and more dots than planned marks by the "
                            "end: taken as marks made before this series, not counted"
                            + (f" ({min(known, pre)} of them the earlier plan's marks, "
                               "session.json design.earlier_marks_mm)" if known else ""))
        sees = [sum(k in seen_by[gi] for gi in persistent) for k in usable]
        prev = 0
        for r, k in enumerate(usable):
            n = count[r] - pre
            if n > N:
                if prev < N:
                    warnings.append(f"{files[k]}: {n} persistent dots, more than the {N} "
                                    "planned marks: the series is capped at the plan")
                n = N
            if r > 0 and n == prev and sees[r] < sees[r - 1]:
                # it adds no mark and shows fewer than the photo before it: taken before
                # that photo (a wrong clock, a renamed file); which marks it shows is not
                # known, and a repeated photo adds nothing: left out either way
                warnings.append(f"{files[k]}: out of order (it shows {sees[r]} marks, "
                                f"{files[usable[r - 1]]} before it {sees[r - 1]}, and adds "
                                "none): left out")
                continue
            if r > 0 and n == prev:
                warnings.append(f"{files[k]}: a repeated photo (no mark added since "
                                f"{files[usable[r - 1]]})")
            elif r > 0 and n > prev + 1:
                warnings.append(f"{files[k]}: {n - prev} marks added since "
                                f"{files[usable[r - 1]]}: a photo of the series may be missing")
            out[k] = tuple(mark_ids[:n])
            prev = n
        if prev < N:
            warnings.append(f"the last photo shows {prev} of {N} planned marks: marks "
                            f"{', '.join(mark_ids[prev:prev + 5])}"
                            f"{' ...' if N - prev > 5 else ''} were not photographed")
    return Inferred(tuple(out), mode, tuple(warnings))


def _n_known(groups, earlier_mm, tol_mm: float) -> int:
    """How many of the dot ``groups`` lie within ``tol_mm`` of a mark of an earlier plan."""
    if earlier_mm is None or not groups:
        return 0
    try:   # session.json's hint: a value that is not a list of [x, y] says nothing
        e = np.asarray(earlier_mm, float).reshape(-1, 2)
    except (TypeError, ValueError):
        return 0
    if not len(e) or not np.all(np.isfinite(e)):
        return 0
    return sum(bool(np.min(np.hypot(*(e - g.mean_mm).T)) <= tol_mm) for g in groups)


def _extra_dots(extra: int, groups, earlier_mm, tol_mm: float) -> str:
    """The sentence on ``extra`` dots beyond the plan's marks: those that are an earlier
    plan's marks on this sheet (the pilot's) named as such, the rest left unassigned."""
    known = min(_n_known(groups, earlier_mm, tol_mm), extra)
    if not known:
        return "the extra dots are left unassigned"
    rest = extra - known
    return (f"{known} are the marks of the earlier plan on this sheet (the pilot's, session.json "
            "design.earlier_marks_mm), known and not this plan's"
            + (f"; {rest} other extra dot(s) left unassigned" if rest else ""))
