"""Stage 3: the dots grouped across photos and the groups matched to the plan's marks
(:mod:`vision_cal.identify.associate`; which marks a photo shows listed or inferred,
:mod:`vision_cal.identify.infer`), predicted with the robot file's tool and then with the
tool's first guess fitted to the marks the first pass matched (:func:`_with_fitted_tool`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from vision_cal.config import AssociationConfig, PlanMatchConfig
from vision_cal.dataset.session import Session
from vision_cal.identify import associate as assoc
from vision_cal.identify.infer import infer_image_marks
from vision_cal.identify.plan_match import check_plan_match
from vision_cal.measure.listing import Photo
from vision_cal.measure.types import ImageResult
from vision_cal.model.equivalent import equivalent_joints
from vision_cal.model.tool_fit import fit_tool


def _tool_joints(params, tool_mm, session):
    """(joints (N, 2), the tool-less model they are for): the association predicts with a
    tool-less model, so each mark gets the joints that put it where ``params`` with
    ``tool_mm`` puts the pen. That model is ``params`` with L2 lengthened by |tool|, which
    reaches every pen position (``params`` itself does not reach a mark the tool puts
    beyond L1 + L2); the commanded joints where no such pose exists."""
    model = replace(params, L2_mm=params.L2_mm + float(np.hypot(*tool_mm)))
    q = session.joints_deg
    eq = equivalent_joints(params, tool_mm, q, session.j4_deg, solve_with=model)
    return np.where(np.isfinite(eq), eq, q), model


def _with_fitted_tool(a, session, mark_ids, mark_images, groups, ac):
    """The association again, predicted from the base model and tool fitted to the marks
    the first pass matched (robustly: a swapped pair is left out), when that matches at
    least as many marks. The robot file's rough ``tool_mm`` (millimetres off) turns with
    joint 4, which a tool-less model cannot follow: its residual widens the gates until
    marks a dozen millimetres apart are refused or swapped."""
    k = [list(mark_ids).index(mid) for mid in a.mark_to_group]
    if len(k) < 8:
        return a
    xy = np.array([groups[g].mean_mm for g in a.mark_to_group.values()])
    tf = fit_tool(session.joints_deg[k], session.j4_deg[k], xy)
    if not tf:
        return a
    q, model = _tool_joints(tf.fit.params, tf.tool_mm, session)
    b = assoc.associate(q, mark_ids, mark_images, groups, model,
                        max_zero_deg=ac.max_zero_deg, max_base_mm=ac.max_base_mm)
    return b if len(b.mark_to_group) >= len(a.mark_to_group) else a


@dataclass(frozen=True)
class AssociatedDots:
    """Stage 3's result: the dot groups across photos, which mark each group is
    (``assoc``: :class:`vision_cal.identify.associate` result), which marks each photo
    shows, and how they were inferred (None when session.json lists them)."""

    groups: list
    assoc: object
    image_marks: list
    inferred: object | None
    warnings: list
    #: the groups with their refined dots only (the dots only seen left out,
    #: :mod:`vision_cal.measure.views`): what the marks are measured from
    measured: list = field(default_factory=list)

    def measured_group(self, gi: int):
        """Group ``gi`` with its refined dots only (all of it when not split)."""
        return self.measured[gi] if self.measured else self.groups[gi]

    def unassigned(self, files: list[str]) -> list[dict]:
        """The dot groups no mark took: mean position and the photos they are on."""
        used = set(self.assoc.mark_to_group.values())
        return [{"xy_mm": g.mean_mm.tolist(), "files": [files[k] for k in g.images]}
                for gi, g in enumerate(self.groups) if gi not in used]


def associate_dots(session: Session, items: list[Photo], images: list[ImageResult],
                   ac: AssociationConfig, default_diameter_mm: float,
                   plan_match: PlanMatchConfig | None = None) -> AssociatedDots:
    """Stage 3: dots grouped across photos and the groups matched to the planned marks
    (which marks a photo shows: listed, or inferred); photos that do not match the plan
    stop the run (:mod:`vision_cal.identify.plan_match`). Each photo's ``dots_mark`` is set
    in ``images``."""
    warnings: list[str] = []
    files = [ph.file for ph in items]
    idx_ok = [i for i, r in enumerate(images) if r.status == "ok"]
    # the dots only seen group with their refined views: which marks a photo shows
    per_image = [(i, np.concatenate([images[i].dots_xy_mm, images[i].seen_xy_mm]),
                  np.concatenate([images[i].dots_cov_mm2,
                                  np.full((len(images[i].seen_xy_mm), 2, 2), np.nan)]))
                 for i in idx_ok]
    dia = session.pen_mark_diameter_mm or default_diameter_mm
    groups = assoc.group_dots(per_image, tol_mm=max(ac.group_tol_diameters * dia,
                                                    ac.group_tol_min_mm))
    mark_ids = [m.id for m in session.marks]
    if session.images_listed:
        image_marks = [tuple(ph.listed_marks) for ph in items]
        inferred = None
    else:
        design = session.raw.get("design") if isinstance(session.raw, dict) else None
        inferred = infer_image_marks(
            len(items), idx_ok, groups, mark_ids, files, ac,
            earlier_mm=(design or {}).get("earlier_marks_mm") if isinstance(design, dict)
            else None, tol_mm=dia)
        image_marks = list(inferred.marks)
        warnings.extend(inferred.warnings)
        n_off = sum(1 for r in images if r.status != "ok")
        if n_off:
            warnings.append(f"{n_off} photo(s) in the folder not used (not of the sheet, "
                            "repeated or unreadable): see images[].reason")
    mark_images = [{i for i in idx_ok if m.id in image_marks[i]} for m in session.marks]
    q_assoc, assoc_model = session.joints_deg, session.robot.params
    with_tool = session.uses_joint4 and session.robot.tool_mm is not None   # #21
    if with_tool:
        q_assoc, assoc_model = _tool_joints(session.robot.params, session.robot.tool_mm,
                                            session)
    a = assoc.associate(q_assoc, mark_ids, mark_images, groups,
                        assoc_model, max_zero_deg=ac.max_zero_deg,
                        max_base_mm=ac.max_base_mm)
    if with_tool:
        a = _with_fitted_tool(a, session, mark_ids, mark_images, groups, ac)
    warnings.extend(a.warnings)
    check_plan_match(session.path, files, images, image_marks, len(groups), len(a.mark_to_group),
                     plan_match)
    measured = [_refined_only(g, images) for g in groups]
    dot_mark = [[""] * len(im.dots_xy_mm) for im in images]
    for mid, gi in a.mark_to_group.items():
        for k, j in zip(measured[gi].images, measured[gi].dot_index):
            dot_mark[k][j] = mid
    for k, im in enumerate(images):
        if im.status == "ok":
            images[k] = replace(im, dots_mark=tuple(dot_mark[k]))
    return AssociatedDots(groups, a, image_marks, inferred, warnings, measured)


def _refined_only(g, images: list[ImageResult]):
    """The group without the dots only seen (their index is past the photo's refined
    dots, :mod:`vision_cal.measure.views`)."""
    keep = [i for i, (k, j) in enumerate(zip(g.images, g.dot_index)) if j < images[k].n_dots]
    if len(keep) == len(g.images):
        return g
    return assoc.DotGroup(g.xy_mm[keep].reshape(-1, 2), g.cov_mm2[keep].reshape(-1, 2, 2),
                          tuple(g.images[i] for i in keep), tuple(g.dot_index[i] for i in keep))
