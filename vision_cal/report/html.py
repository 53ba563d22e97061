"""report.json, then report.html rendered from it (one self-contained file).

``build_report(calibration_path)`` collects the statistics into a dict that is written as
``OUT/report.json``, from the files alone: calibration.json (read by
``CalibrationResult.read``, its one reader), the measurement.json beside it (when the
calibration measured photos: marker corners and dots drawn on each photo; read by
``Measurement.read``, its one reader), the
dataset's session.json (the published ``reference`` and the declared ``camera``, when it is
still there) and loop.json (a closed loop's targets). ``render_html(report)`` makes the
HTML from that dict alone, with every figure and photo embedded as a data URI so the file
opens from disk with no network.
"""

from __future__ import annotations

import base64
import html
import math
import os
from datetime import datetime, timezone
from pathlib import Path

import cv2
import numpy as np

from vision_cal.dataset import photos as photo_files
from vision_cal.dataset.calibration_result import CalibrationResult
from vision_cal.dataset.io import atomic_write_json, atomic_write_text, read_json
from vision_cal.measure.types import ImageResult, Measurement
from vision_cal.report import plots
from vision_cal.report.headline import STATISTICS, actions, headline, mark_rows, provenance
from vision_cal.report.summary import describe_effect, survey_line, uncertainty_lines

MAX_PHOTOS = 40
# Every photo is embedded once, as a JPEG of the overlay (the full-size file is linked).
# The photos share PHOTO_BUDGET_BYTES: each takes the first (width px, JPEG quality) step
# that fits its share, so a few photos are sharp and a 40-photo series stays small.
PHOTO_BUDGET_BYTES = 2_000_000
PHOTO_STEPS = ((1000, 75), (960, 70), (960, 60), (800, 60), (720, 55), (640, 50), (480, 50))


def _read(path) -> dict | None:
    """A JSON file the report may read, or None when it is not there."""
    return read_json(path) if path is not None and Path(path).is_file() else None


def build_report(calibration_path, *, loop=None, out_dir=None) -> dict:
    """The report's statistics as a JSON-ready dict, from the written files.

    ``calibration_path``: ``OUT/calibration.json``. ``loop``: loop.json (its path, or its
    contents). ``out_dir``: where report.html goes (default: next to calibration.json);
    photo links are relative to it."""
    cal_path = Path(calibration_path)
    cal = CalibrationResult.read(cal_path)   # calibration.json's one reader
    doc = cal.to_json()   # the report carries it as JSON (report.json ``calibration``)
    loop = _read(loop) if isinstance(loop, (str, Path)) else loop
    out_dir = Path(out_dir) if out_dir is not None else cal_path.parent
    # the photos measured for this calibration (a folder of marks given in mm has none):
    # measurement.json, read by its one reader
    mpath = cal_path.parent / "measurement.json"
    meas = Measurement.read(mpath) if cal.images and mpath.is_file() else None
    dataset = cal.dataset or (None if meas is None else meas.dataset)
    session = (_read(Path(dataset) / "session.json") if dataset else None) or {}
    where = str(dataset) if dataset else "not recorded (an older calibration.json)"
    rep = {"format": "vision-cal/report/1", "dataset": where, "calibration": doc,
           "reference": session.get("reference")}
    rep["headline"] = headline(doc, loop)
    rep["actions"] = actions(doc, calibration_path=str(cal_path))
    rep["provenance"] = provenance(
        doc, dataset=where, out_dir=str(out_dir.resolve()), camera=session.get("camera"),
        created_utc=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"))
    rep["marks_table"] = mark_rows(doc, None if meas is None else meas.refused)
    rep["statistics"] = STATISTICS
    rep["photos"] = [_photo_entry(im, dataset, out_dir) for im in
                     (meas.images if meas is not None else [])]
    if meas is not None and meas.as_printed is not None:   # #28: the sheet as printed
        rep["as_printed"] = meas.as_printed.to_json()
    if loop:
        rep["loop"] = loop
    return rep


def _photo_entry(im: ImageResult, dataset, out_dir: Path) -> dict:
    """A photo of measurement.json ``images[]`` as the report draws it: where it is, its
    markers (id, corners in px) and its dots (the mark each was taken for, px)."""
    path = Path(dataset) / im.file
    names = list(im.dots_mark)
    return {"file": im.file, "path": str(path),
            "link": os.path.relpath(path.resolve(), out_dir.resolve()),
            "status": im.status, "reason": im.reason or "",
            "size_px": None if im.size_px is None else list(im.size_px),
            "markers_px": [[int(i), np.asarray(c, float).tolist()]
                           for i, c in zip(im.marker_ids, im.markers_px)],
            "dots_px": [[(names[k] or None) if k < len(names) else None, float(uv[0]),
                         float(uv[1])] for k, uv in enumerate(im.dots_uv_px)]}


def write_report(calibration_path, out_dir=None, *, loop=None) -> Path:
    """Write OUT/report.json, then OUT/report.html from it (``out_dir``: default the folder
    of calibration.json); returns the HTML path. ``loop``: loop.json, path or contents."""
    out_dir = Path(out_dir) if out_dir is not None else Path(calibration_path).parent
    rep = build_report(calibration_path, loop=loop, out_dir=out_dir)
    jpath = atomic_write_json(out_dir / "report.json", rep)
    return atomic_write_text(out_dir / "report.html", render_html(read_json(jpath)))


def _uri(png: bytes, mime="image/png") -> str:
    return f"data:{mime};base64," + base64.b64encode(png).decode("ascii")


def _f(x, nd=4) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{nd}f}"


def _e(x) -> str:
    return html.escape(str(x))


def _cell(c) -> str:
    """A cell: plain HTML, or (HTML, sort key) for a sortable column."""
    if isinstance(c, tuple):
        text, key = c
        if key is None or (isinstance(key, float) and not math.isfinite(key)):
            return f"<td data-v=''>{text}</td>"
        return f"<td data-v='{_e(key)}'>{text}</td>"
    return f"<td>{c}</td>"


def _table(head, rows, *, sortable: bool = False, tid: str | None = None) -> str:
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in head)
    body = "".join("<tr>" + "".join(_cell(c) for c in r) + "</tr>" for r in rows)
    attrs = (" class=sortable" if sortable else "") + (f" id={tid}" if tid else "")
    return f"<table{attrs}><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def _photo_overlay(p: dict, budget_bytes: int = PHOTO_BUDGET_BYTES) -> str | None:
    """The photo with its detections drawn, downscaled to fit ``budget_bytes`` (base64
    included), as a JPEG URI."""
    path = Path(p["path"])
    try:  # the same reader and frame as the measurement (no FIFO, no bomb, EXIF turn)
        img = photo_files.decode_as_measured(photo_files.read_photo(path.parent, path.name),
                                             p.get("size_px"))
    except photo_files.PhotoRefused:
        return None
    if img is None:
        return None
    h, w = img.shape[:2]
    lw = max(1, int(round(w / 800)))
    for m in p.get("markers_px", []) or []:
        mid, corners = m[0], np.asarray(m[1], float).reshape(-1, 2)
        cv2.polylines(img, [np.round(corners).astype(np.int32)], True, (0, 200, 0), lw)
        cv2.putText(img, str(mid), tuple(np.round(corners[0]).astype(int)),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.5 * lw, (0, 160, 0), lw)
    for d in p.get("dots_px", []) or []:
        did, x, y = d[0], float(d[1]), float(d[2])
        cv2.circle(img, (int(round(x)), int(round(y))), 6 * lw, (0, 0, 255), lw)
        if did is not None:
            cv2.putText(img, str(did), (int(x) + 7 * lw, int(y) - 7 * lw),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.45 * lw, (0, 0, 230), lw)
    data = b""
    for width, quality in PHOTO_STEPS:
        s = min(1.0, width / w)
        small = cv2.resize(img, (int(w * s), int(h * s)), interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, quality,
                                               cv2.IMWRITE_JPEG_OPTIMIZE, 1])
        if ok:
            data = buf.tobytes()
            if 4 * len(data) / 3 <= budget_bytes:
                break
    return _uri(data, "image/jpeg") if data else None


CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em auto;
max-width:1150px;color:#222;padding:0 1em}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ddd;padding:.25em .6em;
text-align:right;font-variant-numeric:tabular-nums}th{background:#f4f4f4}
td:first-child,th:first-child{text-align:left}.ok{color:#070}.bad{color:#b00}.warn{color:#a60}
table.sortable th{cursor:pointer}table.sortable th:after{content:" \\2195";color:#aaa}
.headline{border:2px solid #888;border-radius:6px;padding:.6em 1.2em;background:#fafafa}
.verdict{font-size:1.25em;font-weight:600;margin:.4em 0}
.verdict.ready{color:#070}.verdict.care{color:#a60}.verdict.unreliable{color:#b00}
code,pre{background:#f4f4f4;padding:.1em .3em}pre{padding:.5em;white-space:pre-wrap}
img.fig{max-width:100%;border:1px solid #eee}.thumbs{display:flex;flex-wrap:wrap;gap:8px}
.thumbs figure{margin:0;width:320px}.thumbs figcaption{font-size:.8em;color:#555}
.thumbs img{width:320px;cursor:zoom-in;border:1px solid #ccc}
#lightbox{display:none;position:fixed;inset:0;background:rgba(0,0,0,.85);z-index:9;
cursor:zoom-out;align-items:center;justify-content:center}
#lightbox img{max-width:96vw;max-height:96vh}.note{color:#555;font-size:.9em}
td.l{text-align:left}
"""

JS = """
function showFull(el){var lb=document.getElementById('lightbox');
lb.querySelector('img').src=el.src;lb.style.display='flex';}
function hideFull(){document.getElementById('lightbox').style.display='none';}
function sortBy(th){var t=th.closest('table'),b=t.tBodies[0],i=th.cellIndex;
var asc=th.getAttribute('data-dir')!=='asc';th.setAttribute('data-dir',asc?'asc':'desc');
var rows=Array.prototype.slice.call(b.rows);rows.sort(function(x,y){
var a=x.cells[i],c=y.cells[i],ka=a.getAttribute('data-v'),kc=c.getAttribute('data-v');
if(ka!==null&&kc!==null){if(ka==='')return 1;if(kc==='')return -1;
var d=parseFloat(ka)-parseFloat(kc);if(!isNaN(d))return asc?d:-d;}
var s=a.textContent.localeCompare(c.textContent);return asc?s:-s;});
rows.forEach(function(r){b.appendChild(r);});}
window.addEventListener('DOMContentLoaded',function(){
document.querySelectorAll('table.sortable th').forEach(function(th){
th.addEventListener('click',function(){sortBy(th);});});});
"""

_VERDICT_CLASS = {"ready": "ready", "check": "care", "use with care": "care",
                  "not reliable": "unreliable"}


def _headline_html(rep: dict) -> str:
    hl = rep["headline"]
    v = hl["verdict"]
    rows = []
    for a in hl["accuracy"]:
        n = f"{a['n']}" + (f" of {a['of']}" if a.get("of") is not None else "")
        if a.get("n_before") is not None and a["n_before"] != a["n"]:
            n += f" (before: {a['n_before']})"
        # what "before" is differs by row: the marks' base-model residual (the same fit
        # without effects), the targets' error with the nominal model (before calibrating)
        was = ("base model" if a["key"] in ("residual_rms_mm", "validation_rms_mm")
               else "nominal model")
        rows.append([_e(a["what"]),
                     f"<span data-key='{_e(a['key'])}.base_model'>{_f(a['before_mm'])}</span>"
                     f" <span class=note>({was})</span>",
                     f"<span data-key='{_e(a['key'])}.final_model'>{_f(a['after_mm'])}</span>",
                     n])
    eff = "".join(f"<li>{_e(e['text'])}</li>" for e in hl["effects"])
    return (f"<div class=headline id=headline><p><b>Calibrated:</b> {_e(hl['calibrated'])}</p>"
            f"<p class='verdict {_VERDICT_CLASS.get(v['status'], '')}' id=verdict>"
            f"{_e(v['text'])}</p>"
            + _table(["accuracy [mm]", "before", "after (final model)",
                      "marks / targets"], rows)
            + ("<p><b>Effects found</b> (size &plusmn; 1 std):</p><ul>" + eff + "</ul>"
               if eff else "<p><b>Effects found:</b> none; the base model explains the "
                           "marks.</p>")
            + "</div>")


def _starting_model_note(sm) -> str:
    """The model the plan was placed with (a pilot's), named as such: never the nominal."""
    if not isinstance(sm, dict):
        return ""
    z = sm.get("joint_zero_deg") or [None, None]
    return (f"<p class=note>The plan was placed with a starting model, {_e(sm.get('source', ''))}"
            f" (L1 {_f(sm.get('L1_mm'), 3)} mm, L2 {_f(sm.get('L2_mm'), 3)} mm, z1 {_f(z[0], 4)}"
            f", z2 {_f(z[1], 4)} deg): the nominal above and the offsets below are the robot "
            "file's, which the controller runs.</p>")


def _actions_html(rep: dict) -> str:
    a = rep["actions"]
    rows = [[_e(r["name"]), _f(r["nominal"], 3), f"<b>{_f(r['calibrated'], 4)}</b>",
             "&plusmn;" + _f(r["std"], 4), r["unit"]] for r in a["olp_model"]]
    out = ["<h2>What to do with it</h2>",
           "<h3>1. Enter the calibrated model in the OLP</h3>",
           _table(["parameter", "nominal (robot file)", "calibrated", "std (1 sigma)",
                   "unit"], rows),
           _starting_model_note(a.get("starting_model")),
           f"<p class=note><b>Sign convention.</b> {_e(a['sign_convention'])}</p>",
           "<h3>2. Or correct the controller's joint offsets</h3>",
           f"<p>{_e(a['controller_offsets_text'])}</p>",
           _table(["joint", "add to the controller offset [deg]", "std [deg]"],
                  [[str(o["joint"]), f"<b>{o['add_to_offset_deg']:+.4f}</b>",
                    "&plusmn;" + _f(o["std_deg"], 4)] for o in a["controller_offsets"]]),
           "<p class=note>Link lengths and the base are model parameters, not controller "
           "settings: they go to the OLP (or the controller's kinematic model where it has "
           "one).</p>"]
    for c in a["controller_effects"]:
        out.append(f"<p>{_e(c['text'])}</p>")
    out.append("<h3>3. Effects the controller cannot take: plan with them</h3>")
    if a["planner_effects"]:
        out.append(f"<p>{_e(', '.join(a['planner_effects']))} cannot be entered in a "
                   "controller; the planner compensates them in the joint commands:</p>")
    else:
        out.append("<p>No effect needs the planner; these commands still apply the "
                   "calibrated model:</p>")
    out.append("<ul>" + "".join(f"<li>{_e(c['what'])}:<pre>{_e(c['command'])}</pre></li>"
                                for c in a["commands"]) + "</ul>")
    return "\n".join(out)


def _provenance_html(rep: dict) -> str:
    p = rep["provenance"]
    rows = [["created", _e(p["created_utc"])], ["vision-cal", _e(p["vision_cal_version"])],
            ["input folder", _e(p["dataset"])], ["output folder", _e(p["out"])],
            ["camera / lens", _e(p["camera"])],
            ["photos used", f"{len(p['photos_used'])}"],
            ["photos skipped", f"{len(p['photos_skipped'])}"]]
    out = ["<h2>Provenance</h2>", _table(["", ""], rows)]
    if p["photos_skipped"]:
        out.append(_table(["skipped photo", "reason"], [[_e(s["file"]), _e(s["reason"])]
                                                        for s in p["photos_skipped"]]))
    cfg = p["configuration"]
    crow = []

    def _v(v):
        return f"{v:.4g}" if isinstance(v, float) else _e(v)

    for group, vals in cfg.items():
        if isinstance(vals, dict):
            for k, v in vals.items():
                crow.append([_e(group), _e(k), _v(v)])
        elif vals is not None:
            crow.append([_e(group), "", _e(vals)])
    out.append("<h3>Configuration (thresholds in force)</h3>"
               + _table(["stage", "setting", "value"], crow))
    return "\n".join(out)


def _marks_html(rep: dict) -> str:
    rows = []
    for r in rep.get("marks_table", []):
        m, res = r["measured_mm"], r["residual_mm"]
        rows.append([
            _e(r["id"]), _e(r["role"] or "-"),
            (_f(m[0], 3), m[0]) if m else ("-", None), (_f(m[1], 3), m[1]) if m else ("-", None),
            (_f(res[0]), res[0]) if res else ("-", None),
            (_f(res[1]), res[1]) if res else ("-", None),
            (_f(r["residual_norm_mm"]), r["residual_norm_mm"]),
            (_f(r["sigma_mm"]), r["sigma_mm"]),
            (str(r["n_photos"]) if r["n_photos"] is not None else "-", r["n_photos"]),
            f"<span class=l>{_e('; '.join(r['flags']))}</span>"])
    return ("<h2>Marks</h2><p class=note>Click a column to sort. Residual: measured minus the "
            "final model's prediction; sigma: the measurement's per-axis standard deviation "
            "(from the scatter over the photos that saw the mark).</p>"
            + _table(["mark", "role", "x [mm]", "y [mm]", "residual x [mm]",
                      "residual y [mm]", "|residual| [mm]", "sigma [mm]", "photos", "flags"],
                     rows, sortable=True, tid="marks"))


def _print_html(pr: dict) -> str:
    """calibration.json ``print`` (#28) in words."""
    if pr.get("source") == "one place":
        return (f"<p class=bad>Not measured: one camera place cannot tell the print from the "
                f"lens. The markers show {_f(pr.get('seen_rms_mm'), 3)} mm beyond each photo's "
                f"mapping; every mark carries about {_f(pr.get('limit_mm'), 3)} mm (RMS) for it. "
                "Survey the sheet (vision-cal survey) or photograph it from several places."
                "</p>")
    rep = (f"<p>Replication: {_e((pr.get('replication') or {}).get('text'))}.</p>"
           if (pr.get("replication") or {}).get("text") else "")
    if pr.get("applied") is False:
        why = (f"not applied ({_e(pr.get('status'))}): {_e(pr.get('reason'))}"
               if pr.get("reason") else
               f"on its layout within what they resolve ({_f(pr.get('rms_mm'), 3)} mm RMS "
               f"against {_f(pr.get('unresolved_mm'), 3)} mm)")
        size = (f" Every mark carries {_f(pr.get('limit_mm'), 3)} mm (RMS) for the print "
                f"the photos' mappings leave ({_f(pr.get('seen_rms_mm'), 3)} mm seen)."
                if pr.get("limit_mm") else "")
        return (f"<p>Measured from the {_e(pr.get('source'))} ({pr.get('n_places')} camera "
                f"places): {why}; the declared layout is kept.{size}</p>" + rep)
    return (f"<p>Measured from {_e(pr.get('source'))} ({pr.get('n_places')} camera places): "
            f"the markers' corners are {_f(pr.get('rms_mm'), 3)} mm RMS, "
            f"{_f(pr.get('max_mm'), 3)} mm at most, off their layout; the markers grew "
            f"{_f(pr.get('growth_mm'), 3)} mm a side (toner), the rest moved "
            f"{_f(pr.get('field_rms_mm'), 3)} mm RMS. The views leave "
            f"{_f(pr.get('unresolved_mm'), 4)} mm (RMS) not separated from the lens. The marks "
            "are measured against the markers as printed.</p>" + rep)


def tool_html(doc: dict) -> str:
    """The tool's section, from calibration.json's ``tool`` block alone (docs/format.md,
    "Joint 4, the tool and placements"): ``tool_mm`` with its std when the marks at several
    ``j4_deg`` identify it, else that it is folded into L2 and z2 and what marks would
    separate it. "" when the calibration says nothing about a tool."""
    t = doc.get("tool")
    if not isinstance(t, dict):
        return ""
    out = ["<h2>Tool (the pen off the joint-4 axis)</h2>"]
    if t.get("identified"):
        xy = t.get("tool_mm") or [float("nan")] * 2
        sd = t.get("std_mm") or [float("nan")] * 2
        out.append(f"<p>tool_mm = [{_f(xy[0])} &plusmn; {_f(sd[0])}, {_f(xy[1])} &plusmn; "
                   f"{_f(sd[1])}] mm in the flange frame at j4 = 0 (radius "
                   f"{_f(t.get('radius_mm'))} mm; one standard deviation).</p>")
        c = t.get("circle_joint4")
        if isinstance(c, dict):
            out.append(f"<p class=note>From the joint-4 circle (the seed paper's method): "
                       f"centre (the flange) ({', '.join(_f(v, 3) for v in c.get('center_mm') or [])}) mm, radius "
                       f"{_f(c.get('radius_mm'))} mm; base and elbow circles at j4 = "
                       f"{_f(t.get('folded_q4_deg'), 1)} deg.</p>")
        corr = [(abs(r), a, b, r) for a, row in (t.get("correlations") or {}).items()
                for b, r in row.items() if isinstance(r, (int, float)) and abs(r) > 0.9]
        if corr:
            out.append("<p class=note>tool correlated above 0.9 with: " + ", ".join(
                f"{_e(a)} ~ {_e(b)} ({r:+.3f})" for _, a, b, r in sorted(corr)[::-1])
                + "</p>")
    else:
        nom = t.get("tool_mm_nominal") or [0.0, 0.0]
        out.append(f"<p class=bad>{_e(t.get('statement', 'the tool is folded into L2 and z2'))}"
                   f" (every mark at j4 = {_f(t.get('j4_deg'), 1)} deg; the robot file's "
                   f"tool_mm [{_f(nom[0], 1)}, {_f(nom[1], 1)}] mm is not calibrated).</p>"
                   f"<p>To separate it: {_e(t.get('to_separate', 'draw marks at several j4_deg'))}"
                   ".</p>")
    return "".join(out)


def render_html(rep: dict) -> str:
    """The page, from report.json's contents alone: its sections in order, in one page
    with the style and the lightbox's script."""
    doc = rep["calibration"]
    parts = [f"<h1>vision-cal report</h1><p class=note>dataset: {_e(rep['dataset'])}"
             f" &middot; method: {_e(doc.get('method', ''))} &middot; "
             f"{len(doc.get('marks', {}))} marks</p>"]
    if rep.get("headline"):
        parts.append(_headline_html(rep))
    if rep.get("actions"):
        parts.append(_actions_html(rep))
    parts += _parameters_html(rep)
    parts.append(tool_html(doc))
    parts += _effects_html(rep)
    parts += _figures_html(rep)
    parts += _targets_html(rep)
    parts += _photos_html(rep)
    if rep.get("provenance"):
        parts.append(_provenance_html(rep))
    body = "\n".join(parts)
    return (f"<!doctype html><html lang=en><head><meta charset=utf-8><title>vision-cal report"
            f"</title><style>{CSS}</style><script>{JS}</script></head><body>{body}"
            "<div id=lightbox onclick='hideFull()'><img alt='full size'></div></body></html>\n")


def _parameters_html(rep: dict) -> list[str]:
    """The parameters (the paper's Table 2: nominal, calibrated, std, and the reference's
    figures when given; shown only beside a reference or without "What to do with it",
    which lists them), the fit's RMS (residual and held-out), the noise floor and the
    identifiability (condition number, rank, high correlations)."""
    doc = rep["calibration"]
    stats_help = rep.get("statistics") or {}
    p, s, n = doc["params"], doc.get("std") or {}, doc.get("nominal") or {}
    ref = ((rep.get("reference") or {}).get("params")) or {}
    rows = []
    for label, key, k, unit in (("L1", "L1_mm", None, "mm"), ("L2", "L2_mm", None, "mm"),
                                ("z1", "joint_zero_deg", 0, "deg"),
                                ("z2", "joint_zero_deg", 1, "deg"),
                                ("base x", "base_mm", 0, "mm"), ("base y", "base_mm", 1, "mm")):
        def g(d):
            v = d.get(key) if d else None
            return v[k] if (v is not None and k is not None) else v
        row = [f"{label} [{unit}]", _f(g(n), 3), _f(g(p), 4), "&plusmn;" + _f(g(s), 4)]
        if ref:
            row.append(_f(g(ref), 1))
        rows.append(row)
    head = ["parameter", "nominal (robot file)", "calibrated", "std (1 sigma)"]
    if ref:
        head.append(html.escape((rep.get("reference") or {}).get("label", "reference")))
    # "What to do with it" already lists the parameters; repeat them only beside published
    # figures to compare with (the paper's Table 2)
    parts = [("<h2>Parameters (Table 2)</h2>" + _table(head, rows))
             if ref or not rep.get("actions") else "<h2>Fit statistics</h2>"]
    r, v = doc.get("residual_rms_mm", {}), doc.get("validation_rms_mm", {})
    parts.append(_table(["RMS [mm]", "base model", "final model"], [
        ["residual (fitted marks)", _f(r.get("base_model")), _f(r.get("final_model"))],
        [f"held-out ({html.escape(str(v.get('kind', 'validation')))})",
         _f(v.get("base_model")), _f(v.get("final_model"))]]))
    if stats_help.get("held-out"):
        parts.append(f"<p class=note>{_e(stats_help['held-out'])}</p>")
    if doc.get("noise_floor_mm") is not None:
        parts.append(f"<p>Measurement noise floor: {_f(doc['noise_floor_mm'])} mm (RMS, 2-D)</p>")
    parts += [f"<p>{_e(line)}</p>" for line in uncertainty_lines(doc)]
    ident = doc.get("identifiability") or {}
    if ident:
        parts.append(f"<p class=note>condition number of the scaled Jacobian "
                     f"{ident.get('condition_number', float('nan')):.3g}, rank "
                     f"{ident.get('rank')} of {ident.get('n_params')}</p>")
        hc = ident.get("high_correlations", [])
        if hc:
            parts.append("<p class=note>correlations above 0.9: " + ", ".join(
                f"{html.escape(c['a'])} ~ {html.escape(c['b'])} ({c['r']:+.3f})" for c in hc)
                + "</p>")
    return parts


def _effects_html(rep: dict) -> list[str]:
    """The effects found (with the statistics' help and the diagnosis's level), the
    unexplained structure, the candidates rejected, the per-photo offsets and what this
    plan cannot identify."""
    doc = rep["calibration"]
    stats_help = rep.get("statistics") or {}
    parts = ["<h2>Effects</h2>"]
    eff = [e for e in doc.get("effects", []) if e["name"] != "unexplained"]
    parts.append("<ul>" + "".join(f"<li class=ok>{html.escape(describe_effect(e))}</li>"
                                  for e in eff) + "</ul>" if eff else
                 "<p>None found: the base model explains the marks.</p>")
    diag = doc.get("diagnosis") or {}
    th = diag.get("thresholds") or {}
    if stats_help and (eff or diag.get("rejected")):
        lvl = (f" Here alpha = {th['alpha']:g} over {th['n_candidates']} candidates: p must be "
               f"below {th['alpha_each']:.2g}." if th.get("alpha_each") else "")
        parts.append("<ul class=note>" + "".join(
            f"<li>{_e(stats_help[k])}{_e(lvl) if k == 'p' else ''}</li>"
            for k in ("F", "p", "dBIC") if k in stats_help) + "</ul>")
    for e in doc.get("effects", []):
        if e["name"] == "unexplained":
            parts.append("<p class=bad>Unexplained structure: " +
                         html.escape("; ".join(e.get("seen", []))) + "</p>")
    if diag.get("rejected"):
        parts.append("<h3>Candidates rejected</h3>" + _table(
            ["candidate", "held-out before [mm]", "held-out after [mm]", "F", "p", "dBIC", "why"],
            [[html.escape(e["label"]), _f(e["heldout_before_mm"]), _f(e["heldout_after_mm"]),
              _f(e["F"], 2), f"{e['p_value']:.2g}", _f(e["delta_bic"], 1),
              html.escape(e["reason"])] for e in diag["rejected"]])
            + "<p class=note>held-out after '-': the candidate failed the F/dBIC test, so "
              "its held-out error was not computed.</p>")
    if diag.get("per_photo_offsets"):
        parts.append(_per_photo_offsets_html(rep))
    ni = (doc.get("identifiability") or {}).get("not_identifiable", [])
    if ni:
        parts.append("<h3>Not identifiable by this plan</h3><ul>" + "".join(
            f"<li>{html.escape(d['label'])}: {html.escape(d['fix'])}</li>" for d in ni) + "</ul>")
    return parts


def _per_photo_offsets_html(rep: dict) -> str:
    """The per-photo offsets' paragraph: how many photos were checked (and why some could
    not be), which shifted beyond the noise, the largest offset, and the test's level."""
    doc = rep["calibration"]
    pp = (doc.get("diagnosis") or {}).get("per_photo_offsets") or []
    bad = [p for p in pp if p.get("flagged")]
    worst = max(pp, key=lambda p: float(np.hypot(*p["offset_mm"])))
    alpha = (((rep.get("provenance") or {}).get("configuration") or {})
             .get("per_photo_offsets") or {}).get("alpha")
    n_ok = sum(1 for im in doc.get("images") or [] if im.get("status") == "ok")
    untested = (f" ({n_ok - len(pp)} of {n_ok} with fewer than two marks: a photo's "
                "offset needs two)" if n_ok > len(pp) else "")
    return (f"<p>Per-photo offsets: {len(pp)} photos checked{untested}, "
            + (f"<span class=bad>{len(bad)} shifted beyond the noise: " +
               ", ".join(html.escape(p['file']) for p in bad) + "</span>" if bad else
               "none shifted beyond the noise")
            + f"; largest mean offset {np.hypot(*worst['offset_mm']):.4f} mm "
            f"({html.escape(worst['file'])}).</p>"
            "<p class=note>Each photo's mean residual is tested against its dots' own "
            "covariances (chi-square, 2 degrees of freedom); a photo is flagged when "
            "p is below " + (f"{alpha:g}" if alpha else "the level") + ".</p>")


def _figures_html(rep: dict) -> list[str]:
    """The figures: the residual field (and the joint residuals), the sheet's height, the
    sheet as printed, the marks' table and the circle fits, each where the calibration has
    it."""
    doc = rep["calibration"]
    parts = ["<h2>Residuals</h2>",
             f"<img class=fig alt='residual field' src='{_uri(plots.residual_field(doc))}'>"]
    if any("residual_joint_deg" in m for m in doc.get("marks", {}).values()):
        parts.append(f"<img class=fig alt='joint residuals' "
                     f"src='{_uri(plots.joint_residuals(doc))}'>")
    sh = plots.sheet_height(doc)
    if sh:
        parts.append("<h2>Sheet height</h2><p class=note>A raised paper moves a mark seen "
                     "through the marker mapping by about z r / H; against the printed grid "
                     "around it the mark keeps its paper position.</p>"
                     f"<img class=fig alt='sheet height' src='{_uri(sh)}'>")
    pr = doc.get("print") or {}
    if pr:
        parts.append("<h2>The sheet as printed</h2>" + _print_html(pr))
        fig = plots.print_deviation(rep.get("as_printed"))
        if fig:
            parts.append(f"<img class=fig alt='print deviation' src='{_uri(fig)}'>")
    if rep.get("marks_table"):
        parts.append(_marks_html(rep))
    c = plots.circles(doc)
    if c:
        parts.append("<h2>Circle fits</h2><p class=note>Arc span limits a circle fit: the "
                     "centre's uncertainty grows like sigma / (1 - cos(span/2)).</p>"
                     f"<img class=fig alt='circle fits' src='{_uri(c)}'>")
    return parts


def _targets_html(rep: dict) -> list[str]:
    """The closed loop's targets (the paper's Table 3: each target's error before and
    after, every missing value's reason below) and its figures; [] without a loop."""
    loop = rep.get("loop") or {}
    if not loop.get("targets"):
        return []
    parts = ["<h2>Targets (Table 3)</h2>"]
    if loop.get("survey"):   # the blank sheet surveyed before the robot drew
        parts.append(f"<p>{html.escape(survey_line(loop['survey']))}.</p>")
    reasons = {}
    rows = []
    for t in loop["targets"]:
        cells = [html.escape(t["id"]), _f(t["target_mm"][0], 2), _f(t["target_mm"][1], 2)]
        for side in ("before", "after"):
            val = t.get(f"{side}_error_mm")
            if val is None:
                why = (t.get(side) or {}).get("reason") or (t.get(side) or {}).get(
                    "status", "not measured")
                k = reasons.setdefault(why, len(reasons) + 1)
                cells.append(f"- <sup>{k}</sup>")
            else:
                cells.append(_f(val))
        rows.append(cells)
    parts.append(_table(["target", "x [mm]", "y [mm]", "error before [mm]",
                         "error after [mm]"], rows))
    if reasons:
        parts.append("<p class=note>" + "<br>".join(
            f"<sup>{k}</sup> - : {html.escape(w)}" for w, k in reasons.items()) + "</p>")
    tp = plots.targets(rep)
    if tp:
        parts.append(f"<img class=fig alt='target errors' src='{_uri(tp)}'>")
    for key in ("paths_png", "joints_png"):
        if loop.get(key):
            parts.append(f"<img class=fig alt='{key}' src='{_uri(base64.b64decode(loop[key]))}'>")
    return parts


def _photos_html(rep: dict) -> list[str]:
    """The photos: how many measured and skipped (with the reasons), the first
    ``MAX_PHOTOS`` measured ones as thumbnails with their detections drawn (within
    ``PHOTO_BUDGET_BYTES`` together), each linked to its file; [] without photos."""
    photos = rep.get("photos", [])
    if not photos:
        return []
    skipped = [ph for ph in photos if ph.get("status") != "ok"]
    parts = [f"<h2>Photos</h2><p>{len(photos) - len(skipped)} measured, "
             f"{len(skipped)} skipped. Click a photo to enlarge it (detections drawn: "
             f"markers green, pen marks red); the link opens the full-size file.</p>"]
    if skipped:
        parts.append(_table(["photo", "reason"], [[html.escape(ph["file"]),
                                                   html.escape(ph.get("reason", ""))]
                                                  for ph in skipped]))
    figs = []
    ok_photos = [ph for ph in photos if ph.get("status") == "ok"]
    shown = ok_photos[:MAX_PHOTOS]
    for ph in shown:
        ov = _photo_overlay(ph, PHOTO_BUDGET_BYTES // max(len(shown), 1))
        link = ph.get("link") or ph["path"]
        if ov:
            figs.append(f"<figure><img src='{ov}' onclick='showFull(this)' "
                        f"alt='{html.escape(ph['file'])}'><figcaption>"
                        f"{html.escape(ph['file'])} &middot; <a href='"
                        f"{html.escape(Path(link).as_posix())}'>full size</a>"
                        f"</figcaption></figure>")
    if figs:
        parts.append("<div class=thumbs>" + "".join(figs) + "</div>")
    if len(ok_photos) > MAX_PHOTOS:
        parts.append(f"<p class=note>{len(ok_photos) - MAX_PHOTOS} more photos are not "
                     "shown; their files are in the input folder.</p>")
    return parts
