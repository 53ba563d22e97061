"""What a calibration was calibrated for: calibration.json ``valid_for`` (issue 29, one owner).

A calibration is measured where its marks (or an arm camera's poses) were: the joint ranges
they covered, the approach sides each joint was reached from, the joint-4 angles (and so
whether the tool was identified), the heights positions were seen at, and a camera's own
height. Outside that the model is extrapolated, and an effect the plan could not identify
(a backlash with one approach side seen, a tool never turned) is simply absent from it: a
target that excites it misses by as much as the effect is large (a pilot "ready ... 0.027
mm" landed targets approached from the other side 0.43-0.46 mm off).

:func:`build` writes the block from a calibration document; :func:`verdict_reasons` is
what the verdict (``estimate/verdict.judge``, its owner) adds for it; :func:`check` is the
one check every consumer runs on its request before it writes anything (``plan``,
``locate``, ``export``, ``verify``, ``design --pilot``), and :func:`enforce` refuses
(exit 2, one line with the reason and the command that would cover it) or, with
``--force``, returns the lines stating the extrapolation for the console and the output
file. The block's fields: docs/format.md, "valid_for".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.errors import VisionCalError

#: a request within this of a covered joint range (deg) is inside it; further, inside
#: as far as the calibration's own expected error holds there (``check``'s ``beyond_deg``,
#: ``std_mm`` and ``std_limit_mm``: ``plan/extrapolation``)
RANGE_SLACK_DEG = 1.0
#: the fields of ``valid_for`` a request's items are checked against one by one (``plan``
#: and ``locate`` plan the rest: :func:`per_item`); the others are the whole request's
PER_ITEM = ("joints", "approach1", "approach2", "approach4", "joint4", "heights",
            "flange_pose")     # a six-axis arm's camera: camera/handeye_valid
#: a requested height within this of the heights seen (mm) is inside them
HEIGHT_SLACK_MM = 0.5
#: a joint-4 angle within this of one seen (deg) is that angle
J4_SLACK_DEG = 0.5

INFORMATIVE = ("vision-cal design ROBOT.yaml --sheet SHEET.json --pilot {cal} --out plan/ "
               "(both approach sides per joint{tool}), draw and photograph it, then "
               "vision-cal plan/ --out cal/")


def _num(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _usable(m) -> bool:
    q = m.get("joints_deg") if isinstance(m, dict) else None
    return (isinstance(q, (list, tuple)) and len(q) >= 2 and all(_num(v) for v in q[:2])
            and m.get("status", "ok") == "ok")


def _entries(doc: dict) -> list[dict]:
    """The marks (or an arm camera's poses) the calibration measured: joints, approach, j4
    (entries without usable joints left out: the file's reader names those)."""
    marks = doc.get("marks")
    poses = doc.get("poses")
    return ([m for m in (marks.values() if isinstance(marks, dict) else []) if _usable(m)]
            + [p for p in (poses if isinstance(poses, list) else []) if _usable(p)])


def _fields(cal: CalibrationResult) -> dict:
    """The fields of a calibration :func:`build` reads, by their names in the file."""
    return {"marks": cal.marks, "poses": cal.extra.get("poses"), "tool": cal.tool,
            "method": cal.method, "identifiability": cal.identifiability,
            "effects": list(cal.effects or ()), "cameras": cal.cameras}


def build(doc, *, pen_down_mm: float | None = None) -> dict | None:
    """calibration.json's ``valid_for`` from a calibration's marks (or poses), ``tool``,
    ``identifiability``, ``effects`` and ``cameras`` (``doc``: its
    :class:`~vision_cal.dataset.calibration_result.CalibrationResult`, or the document);
    None when it has no joints to say it from (marks given without ``joints_deg``)."""
    if isinstance(doc, CalibrationResult):
        doc = _fields(doc)
    if not isinstance(doc, dict):
        return None
    ms = _entries(doc)
    q = [m["joints_deg"] for m in ms]
    if not q:
        return None
    joints = [[float(min(v[j] for v in q)), float(max(v[j] for v in q))] for j in range(2)]
    j4 = sorted({round(float(m["j4_deg"]), 6) for m in ms if _num(m.get("j4_deg"))})
    tool = doc.get("tool") if isinstance(doc.get("tool"), dict) else None
    nominal_tool = (tool or {}).get("tool_mm_nominal")
    if not (isinstance(nominal_tool, list) and all(_num(v) for v in nominal_tool)):
        nominal_tool = [0.0, 0.0]
    tool_identified = None if tool is None else bool(tool.get("identified"))
    if doc.get("method") == "arm_camera":   # the camera's mount is the tool: turned or not
        tool_identified = len(j4) >= 2
    if not j4:   # the format's default: the robot block's j4_deg, else 0
        j4 = [float(tool["j4_deg"]) if tool is not None and _num(tool.get("j4_deg")) else 0.0]
    sides: dict[str, list[int]] = {}
    for j, name in ((0, "1"), (1, "2"), (2, "4")):
        if j == 2 and len(j4) < 2:
            continue   # joint 4 never turned: its approach does not matter while it stays
        seen = sorted({int(m["approach"][j]) for m in ms
                       if isinstance(m.get("approach"), list) and len(m["approach"]) > j
                       and m["approach"][j] in (1, -1)})
        if seen:
            sides[name] = seen
    not_identified = []
    for name, seen in sides.items():
        if len(seen) == 1:
            other = -seen[0]
            not_identified.append({
                "effect": "joint_backlash", "joint": int(name),
                "label": f"joint_backlash(joint {name})",
                "reason": f"joint {name} was reached from the {_side(seen[0])} side only "
                          f"(approach {seen[0]:+d}): its backlash is folded into its zero and "
                          "holds for that side only",
                "excited_by": f"approach {other:+d} on joint {name}",
                "fix": f"draw marks reaching joint {name} from both directions (overshoot "
                       "via points)"})
    if tool_identified is False and any(abs(float(v)) > 0 for v in nominal_tool):
        not_identified.append({
            "effect": "tool", "label": "tool_mm",
            "reason": f"every mark was drawn at joint 4 = {j4[0] if j4 else 0:g} deg: the "
                      f"tool ({tool.get('tool_mm_nominal')} mm in the robot file) is folded "
                      "into L2 and z2, which hold for that joint-4 angle only",
            "excited_by": "joint 4 turned (targets with theta_deg)",
            "fix": "turn joint 4 between marks (the robot file's tool_mm set, the "
                   "informative plan adds joint-4 circles)"})
    labels = {d["label"] for d in not_identified}
    ident = doc.get("identifiability") if isinstance(doc.get("identifiability"), dict) else {}
    ni = ident.get("not_identifiable") if isinstance(ident.get("not_identifiable"), list) else []
    for d in ni:
        if isinstance(d, dict) and isinstance(d.get("label"), str) and d["label"] not in labels:
            not_identified.append({"effect": str(d["label"]).split("(")[0],
                                   "label": d["label"], "reason": d.get("reason", ""),
                                   "excited_by": "targets where it acts",
                                   "fix": d.get("fix", "")})
    heights = [0.0, 0.0]
    effects = doc.get("effects") if isinstance(doc.get("effects"), list) else []
    for e in effects:
        if isinstance(e, dict) and e.get("name") == "sheet_height":
            h = e.get("max_abs_mark_height_mm")
            if _num(h):   # the paper is not flat: marks were seen this far off its plane
                heights = [-abs(float(h)), abs(float(h))]
    out = {"joints_deg": joints, "approach_sides": sides,
           "joint4_deg": j4 or None, "tool_identified": tool_identified,
           "heights_mm": heights, "pen_down_mm": pen_down_mm,
           "not_identified": not_identified}
    cams = []
    for c in doc.get("cameras") if isinstance(doc.get("cameras"), list) else []:
        if not isinstance(c, dict):
            continue
        T = c.get("T_robot_camera") or c.get("T_flange_camera")   # still, or on the arm
        h = (float(T[2][3]) if isinstance(T, list) and len(T) == 4 and isinstance(T[2], list)
             and len(T[2]) == 4 and _num(T[2][3]) else None)
        how = c.get("intrinsics", "declared")
        if how == "focal length undetermined" or h is None:
            loc = [0.0, 0.0]
        else:   # between the sheet and the camera: the ray's model, its std holding f
            loc = sorted([0.0, h])
        cams.append({"camera_height_mm": h, "heights_seen_mm": list(heights),
                     "locate_heights_mm": loc, "intrinsics": how})
    if cams:
        out["cameras"] = cams
    return out


def of(doc: dict, *, file: str | None = None) -> dict | None:
    """A calibration document's ``valid_for``, every field a check reads validated (a bad
    one raises :class:`VisionCalError` naming ``file`` and ``valid_for.<field>``); built
    from its marks for a file written before the block existed."""
    if not isinstance(doc, dict):
        return None
    if "valid_for" not in doc:
        return build(doc)
    vf = doc["valid_for"]
    if vf is None:
        return None

    def bad(field, why):
        raise VisionCalError(why, file=file, field=f"valid_for{field}")

    if not isinstance(vf, dict):
        bad("", f"expected an object, got {type(vf).__name__}")

    def pair(v, field, *, nullable=False):
        if v is None and nullable:
            return
        if not (isinstance(v, list) and len(v) == 2 and all(_num(x) for x in v)
                and v[0] <= v[1]):
            bad(field, f"expected [lo, hi], two finite numbers, got {v!r}")

    j = vf.get("joints_deg")
    if j is not None:
        if not (isinstance(j, list) and len(j) == 2):
            bad(".joints_deg", f"expected [[lo, hi], [lo, hi]], got {j!r}")
        for k, r in enumerate(j):
            pair(r, f".joints_deg[{k}]")
    sides = vf.get("approach_sides")
    if sides is not None:
        if not isinstance(sides, dict):
            bad(".approach_sides", f"expected an object, got {sides!r}")
        for k, v in sides.items():
            if k not in ("1", "2", "4") or not (isinstance(v, list) and v and all(
                    x in (1, -1) and not isinstance(x, bool) for x in v)):
                bad(f".approach_sides.{k}", f"expected a list of +1/-1, got {v!r}")
    j4 = vf.get("joint4_deg")
    if j4 is not None and not (isinstance(j4, list) and j4 and all(_num(x) for x in j4)):
        bad(".joint4_deg", f"expected a list of angles in degrees, got {j4!r}")
    if vf.get("tool_identified") not in (None, True, False):
        bad(".tool_identified", f"expected true, false or null, got {vf['tool_identified']!r}")
    pair(vf.get("heights_mm"), ".heights_mm", nullable=True)
    pd = vf.get("pen_down_mm")
    if pd is not None and not _num(pd):
        bad(".pen_down_mm", f"expected a number of mm or null, got {pd!r}")
    ni = vf.get("not_identified")
    if ni is not None:
        if not isinstance(ni, list):
            bad(".not_identified", f"expected a list, got {ni!r}")
        for k, d in enumerate(ni):
            if not (isinstance(d, dict) and isinstance(d.get("label"), str)):
                bad(f".not_identified[{k}]", f"expected an object with a label, got {d!r}")
    cams = vf.get("cameras")
    if cams is not None:
        if not isinstance(cams, list):
            bad(".cameras", f"expected a list, got {cams!r}")
        for k, c in enumerate(cams):
            if not isinstance(c, dict):
                bad(f".cameras[{k}]", f"expected an object, got {c!r}")
            pair(c.get("locate_heights_mm"), f".cameras[{k}].locate_heights_mm")
    return vf


def _side(s: int) -> str:
    return "positive" if s > 0 else "negative"


def verdict_reasons(vf: dict | None, *, skip_labels=()) -> list[tuple[str, str]]:
    """(status, sentence) the verdict adds for what the calibration could not identify: each
    ``not_identified`` effect a user's targets may excite is a ``check``, with what excites
    it and what to draw to identify it."""
    out = []
    for d in (vf or {}).get("not_identified") or []:
        if d.get("label") in skip_labels:
            continue
        out.append(("check", f"not identified: {d['label']}: {d.get('reason', '')}; "
                             f"targets with {d.get('excited_by', 'it')} are outside what was "
                             f"calibrated (plan leaves them out); to identify it, "
                             f"{d.get('fix', 'draw the informative plan')}: the informative "
                             "plan does (vision-cal design ROBOT.yaml --sheet SHEET.json "
                             "--pilot CAL.json)"))
    return out


@dataclass(frozen=True)
class Outside:
    """One part of a request outside ``valid_for``: which ``field`` of the request, why,
    and the command (or plan change) that would cover it."""

    field: str
    reason: str
    cover: str
    ids: tuple = ()          # the request's items outside (targets, pixels, marks)
    each: tuple = ()         # (id, why that item is outside) for each of ``ids``

    def line(self) -> str:
        return f"{self.reason}; to cover it: {self.cover}"

    def to_json(self) -> dict:
        return {"field": self.field, "reason": self.reason, "cover": self.cover}


def _names(ids, first: int = 3) -> str:
    ids = list(ids)
    return ", ".join(map(str, ids[:first])) + (f" and {len(ids) - first} more"
                                                if len(ids) > first else "")


def check(vf: dict | None, *, cal: str = "CAL.json", ids=(), joints_deg=None,
          approach=None, joint4_deg=None, heights_mm=None, pen_down_mm=None,
          camera: int | None = None, whole_model: bool = False, std_mm=None,
          std_limit_mm: float | None = None, beyond_deg=None) -> list[Outside]:
    """What of a request lies outside ``vf`` (empty: all inside, or ``vf`` None: an old file
    that does not say). ``ids`` names the request's items; per item ``joints_deg`` (q1, q2),
    ``approach`` (s1, s2[, s4]), ``joint4_deg``; ``heights_mm`` the heights asked (locate's
    ``--z-mm``) of ``camera`` (else the marks' heights); ``pen_down_mm`` the program's;
    ``whole_model`` (``export``: the model for every pose) each effect not identified.
    ``beyond_deg`` (per joint) how far beyond the covered range the calibration's stated
    expected error holds, ``std_mm`` (per item) its predicted std (per axis) at each item's
    joints and ``std_limit_mm`` the largest that keeps that error (``plan/extrapolation``):
    an item up to ``beyond_deg`` beyond (never less than :data:`RANGE_SLACK_DEG`) is inside
    while its std is within the limit (how far the model extrapolates is the calibration's
    own figure, not the last mark)."""
    if not vf:
        return []
    ids = list(ids)
    out: list[Outside] = []
    tool_note = (", joint 4 turned" if any(d.get("effect") == "tool"
                                           for d in vf.get("not_identified") or []) else "")
    informative = INFORMATIVE.format(cal=cal, tool=tool_note)
    if whole_model:
        for d in vf.get("not_identified") or []:
            out.append(Outside(
                "not_identified", f"{d['label']} is not identified ({d.get('reason', '')}): "
                f"the exported model is wrong for {d.get('excited_by', 'where it acts')}",
                f"{d.get('fix', '')}: {informative}"))
    rng = vf.get("joints_deg")
    if joints_deg is not None and rng:
        out += _joints_outside(rng, ids, joints_deg, std_mm, std_limit_mm, beyond_deg)
    sides = vf.get("approach_sides") or {}
    if approach is not None and sides:
        for j, name in ((0, "1"), (1, "2"), (2, "4")):
            seen = sides.get(name)
            if not seen:
                continue
            bad = [i for i, a in zip(ids, approach)
                   if len(a) > j and int(a[j]) not in seen]
            if bad:
                s = -seen[0]
                out.append(Outside(
                    f"approach{name}", f"{len(bad)} of {len(ids)} approach joint {name} from "
                    f"the {_side(s)} side ({s:+d}), which the calibration never saw (its marks "
                    f"reached joint {name} from {seen[0]:+d} only, so its backlash is not "
                    f"identified): {_names(bad)}",
                    f"plan with approach {seen[0]:+d} on joint {name}, or draw the informative "
                    f"plan: {informative}", tuple(bad),
                    tuple((i, f"approaches joint {name} from {s:+d}, a side the marks never "
                              f"reached it from (its backlash is not identified)")
                          for i in bad)))
    seen4 = vf.get("joint4_deg")
    if joint4_deg is not None and seen4 and vf.get("tool_identified") is not True:
        bad = [(i, q4) for i, q4 in zip(ids, joint4_deg)
               if q4 is not None and min(abs(q4 - s) for s in seen4) > J4_SLACK_DEG]
        each = tuple((i, f"turns joint 4 to {q4:g} deg, every mark was drawn at "
                         f"{_names(seen4)} deg (the tool is not identified)") for i, q4 in bad)
        bad = [i for i, _ in bad]
        if bad:
            out.append(Outside(
                "joint4", f"{len(bad)} of {len(ids)} turn joint 4 away from the "
                f"{_names(seen4)} deg every mark was drawn at, so the tool was never "
                f"identified (it is folded into L2 and z2, which hold at that joint-4 angle "
                f"only; a tool r mm off the axis moves 1.41 r mm per 90 deg): {_names(bad)}",
                "give the robot file's tool_mm (a ruler's guess) and draw the informative "
                f"plan, which turns joint 4: {informative}", tuple(bad), each))
    if heights_mm is not None:
        if camera is not None:
            cams = vf.get("cameras") or []
            lo, hi = (cams[camera]["locate_heights_mm"] if camera < len(cams)
                      else vf.get("heights_mm") or [0.0, 0.0])
            what = f"camera {camera}"
        else:
            lo, hi = vf.get("heights_mm") or [0.0, 0.0]
            what = "the marks"
        bad = [(i, z) for i, z in zip(ids, heights_mm)
               if not lo - HEIGHT_SLACK_MM <= z <= hi + HEIGHT_SLACK_MM]
        if bad:
            out.append(Outside(
                "heights", f"{len(bad)} of {len(ids)} at heights outside {lo:g}..{hi:g} mm, "
                f"where {what} can locate ({_names(f'{i} at {z:g} mm' for i, z in bad)})",
                "photograph the sheet (or a plate) at that height, or declare the camera's "
                "lens (camera K in session.json) and calibrate again",
                tuple(i for i, _ in bad),
                tuple((i, f"at {z:g} mm, outside {lo:g}..{hi:g} mm where {what} can locate")
                      for i, z in bad)))
    pd = vf.get("pen_down_mm")
    if pen_down_mm is not None and _num(pd) and abs(pen_down_mm - pd) > HEIGHT_SLACK_MM:
        out.append(Outside(
            "pen_down_mm", f"the program lowers joint 3 to {pen_down_mm:g} mm, the "
            f"calibration's marks were drawn at {pd:g} mm: a quill not quite vertical puts "
            "the tool elsewhere at another height",
            "draw the calibration at the working height (the robot file's pen_down_mm)",
            tuple(ids)))
    return out


def _joints_outside(rng, ids, joints_deg, std_mm, std_limit_mm, beyond_deg) -> list[Outside]:
    """The items beyond the covered joint range (``rng``) by more than the slack, which is
    :data:`RANGE_SLACK_DEG`, or ``beyond_deg`` (per joint) where the item's std
    (``std_mm``) is within ``std_limit_mm``: none, or one :class:`Outside` naming each."""
    known = (std_mm is not None and std_limit_mm is not None and math.isfinite(std_limit_mm)
             and beyond_deg is not None)
    stds = list(std_mm) if known else [None] * len(ids)

    def slack(s, j):
        ok = s is not None and math.isfinite(s) and s <= std_limit_mm
        return max(RANGE_SLACK_DEG, float(beyond_deg[j])) if ok else RANGE_SLACK_DEG

    bad = [(i, q, s) for i, q, s in zip(ids, joints_deg, stds)
           if any(not rng[j][0] - slack(s, j) <= q[j] <= rng[j][1] + slack(s, j)
                  for j in range(2))]
    if not bad:
        return []
    cover = ("draw marks there (a sheet placed there: vision-cal design ... --pilot), or "
             "calibrate several placements together (vision-cal calibrate A/ B/ C/ --joint)")
    span = (f"joint 1 {rng[0][0]:.1f}..{rng[0][1]:.1f} deg, joint 2 "
            f"{rng[1][0]:.1f}..{rng[1][1]:.1f} deg")
    grows = (f"; its expected error holds {beyond_deg[0]:.1f} / {beyond_deg[1]:.1f} deg "
             f"beyond, while the predicted std stays within {std_limit_mm:.4f} mm"
             if known else "")
    each = tuple((i, f"joints {q[0]:.1f}, {q[1]:.1f} deg, beyond the {span} the marks "
                     "covered" + (f" (std {s:.4f} mm there{grows})" if s is not None
                                  and math.isfinite(s) else ""))
                 for i, q, s in bad)
    ids_out = [i for i, _, _ in bad]
    return [Outside(
        "joints", f"{len(ids_out)} of {len(ids)} outside the joints the calibration's marks "
        f"covered ({span}{grows}): {_names(ids_out)}: the model is extrapolated there and "
        "its expected error does not hold", cover, tuple(ids_out), each)]


def per_item(outside: list[Outside]) -> tuple[list[Outside], dict]:
    """The whole request's parts outside (refused or forced as one: ``enforce``) and, for
    the fields checked item by item (:data:`PER_ITEM`), each item's id -> its lines "outside
    valid_for.FIELD: why; to cover it: COMMAND" (``plan`` and ``locate`` list those and do
    the rest)."""
    whole, items = [], {}
    for o in outside:
        if o.field not in PER_ITEM:
            whole.append(o)
            continue
        why = dict(o.each)
        for i in o.ids:
            items.setdefault(i, []).append(
                f"outside valid_for.{o.field}: {why.get(i, o.reason)}; to cover it: {o.cover}")
    return whole, items


def enforce(outside: list[Outside], *, file: str, force: bool, what: str) -> list[str]:
    """Refuse a request outside ``valid_for`` (:class:`VisionCalError`, exit 2: one line,
    the reason and the command that would cover it) unless ``force``; with it, the lines
    stating the extrapolation (to print and to write into the output). ``what`` names the
    request (``TARGETS.csv``, ``--z-mm``)."""
    if not outside:
        return []
    if not force:
        o = outside[0]
        more = f" (and {len(outside) - 1} more)" if len(outside) > 1 else ""
        raise VisionCalError(f"{what}: {o.line()}{more}; give --force to write it anyway, "
                             "with the extrapolation stated", file=file,
                             field=f"valid_for.{o.field}")
    return [f"{what}: outside valid_for of {file} (written because of --force): {o.line()}"
            for o in outside]
