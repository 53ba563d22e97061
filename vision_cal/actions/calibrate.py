"""The calibration action (``vision-cal calibrate``): one or several dataset folders
measured and calibrated (:func:`vision_cal.workflows.pipeline.calibrate_dataset`), or one robot from
several placements (:func:`vision_cal.workflows.placements.calibrate_placements`), with the
console summary, the optional report and, for several folders, ``summary.json``."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from vision_cal.dataset.io import atomic_write_json, output_dir, written_together
from vision_cal.dataset.marks_csv import session_from_marks_csv
from vision_cal.dataset.out_folder import (earlier_placements, output_names,
                                           refuse_input_folder, retire_earlier_run,
                                           writing_into)
from vision_cal.diagnose.verdict import Verdict
from vision_cal.errors import VisionCalError
from vision_cal.measure.survey import find_survey
from vision_cal.workflows.pipeline import calibrate_dataset
from vision_cal.workflows.placements import calibrate_placements
from vision_cal.report.html import write_report
from vision_cal.report.summary import format_summary


@dataclass(frozen=True)
class CalibrateRequest:
    """What ``vision-cal calibrate`` was asked (the command's arguments, see its ``--help``)."""

    folders: tuple[str, ...]
    out: str | None = None        # default out/<folder name>
    method: str = "lsq"           # one of vision_cal.config.METHODS
    jobs: int | None = None       # photo measurement processes (default: the cores)
    truth: bool = False           # compare with truth.json (synthetic data)
    report: bool = False          # also report.json and report.html
    joint: bool = False           # the folders are placements of one robot
    quiet: bool = False
    robot: str | None = None      # a marks CSV's robot file (issue 32)
    sigma_mm: float | None = None  # a marks CSV's stated accuracy (mm, one std per axis)
    survey: str | None = None     # survey.json (default: a survey.json in the folder)


def calibrate(req: CalibrateRequest) -> int:
    """Calibrate each folder of ``req`` (or one robot from all of them, ``req.joint``) and
    print what was found; exit code 1 when a folder of several failed."""
    if req.jobs is not None and req.jobs < 1:
        raise VisionCalError(f"--jobs must be at least 1, got {req.jobs}")
    progress = not req.quiet  # a bar on a terminal, else one line per stage
    if req.joint:   # one robot from several placements (calibrate/placements.py)
        if req.method != "lsq":
            raise VisionCalError("--joint fits by least squares only", field="--method")
        out = Path(req.out or "out")
        names = output_names(req.folders)
        # an earlier joint run's results go to previous/ first: its top file and the
        # placement folders this run does not write (whole), and, in the ones it does,
        # their results (the detection cache stays); so an interrupted run leaves nothing
        # that looks current, and no placement of an earlier run beside this one's top file
        stale = [n for n in earlier_placements(out) if n not in names]
        for n in names:   # --out . with the placements in it: their folders are inputs
            refuse_input_folder(out / n, _inputs(req.folders))
        with writing_into(out, command="calibrate --joint", inputs=_inputs(req.folders),
                          subfolders=stale, quiet=req.quiet):
            for n in names:
                moved = retire_earlier_run(out / n)
                if moved and not req.quiet:
                    print(f"moved the earlier results ({', '.join(moved)}) to "
                          f"{out / n / 'previous'}")
            doc = calibrate_placements(req.folders, out_dir=out, jobs=req.jobs,
                                       progress=progress, names=names)
        if not req.quiet:
            for pl in doc["placements"]:
                print(f"{pl['folder']}: sheet at {pl['angle_deg']:.3f} deg, base "
                      f"({pl['base_mm'][0]:.3f}, {pl['base_mm'][1]:.3f}) mm, rms "
                      f"{pl['residual_rms_mm']:.4f} mm")
            print("effects: " + (", ".join(e["name"] + (f"(joint {e['joint']})"
                                                         if "joint" in e else "")
                                           for e in doc["effects"]) or "none"))
            for pl in doc["placements"]:
                print(f"{pl['folder']}: {Verdict.from_json(pl['verdict']).text}")
            print(f"verdict: {Verdict.from_json(doc['verdict']).text}")
        print(f"wrote {out / 'calibration.json'}")
        return 0
    several = len(req.folders) > 1
    csvs = [str(f).lower().endswith(".csv") for f in req.folders]
    for name, value in (("--robot", req.robot), ("--sigma-mm", req.sigma_mm)):
        if value is not None and not any(csvs):
            raise VisionCalError("applies to a marks CSV only", field=name)
    output_dir(req.out or "out", field="--out")
    names = [Path(n).stem if c else n for n, c in zip(output_names(req.folders), csvs)]
    if several and not req.quiet:
        plain = [Path(f).resolve().name for f in req.folders]
        if names != plain:  # two folders share a name: say where each one goes
            print("outputs: " + ", ".join(f"{f} -> {Path(req.out or 'out') / n}"
                                          for f, n in zip(req.folders, names)))
    failures = 0
    rows = []
    for folder, name in zip(req.folders, names):
        out = Path(req.out) / name if (req.out and several) else Path(req.out or f"out/{name}")
        try:
            # OUT holds one run: an earlier run's results go to OUT/previous/ first, so a
            # failed or interrupted run leaves nothing that looks current; OUT is never the
            # dataset folder, and is locked while written (dataset/out_folder.py)
            is_csv = str(folder).lower().endswith(".csv")
            source = (session_from_marks_csv(folder, req.robot, sigma_mm=req.sigma_mm)
                      if is_csv else folder)
            survey = None if is_csv else find_survey(req.survey or folder)   # #28: as printed
            if req.survey and survey is None:
                raise VisionCalError("not found", file=str(req.survey))
            if survey is not None and not req.quiet:
                print(f"measuring against the sheet as surveyed: {survey}")
            with writing_into(out, command="calibrate", inputs=[("DIR", folder)],
                              quiet=req.quiet):
                with written_together():   # measurement.json renamed with calibration.json
                    result = calibrate_dataset(source, out_dir=out, method=req.method,
                                               jobs=req.jobs, progress=progress,
                                               truth=req.truth, survey=survey)
                report = _write_report(result, out) if req.report else None
        except VisionCalError as e:
            if not several:
                raise
            failures += 1
            print(f"vision-cal: error: {folder}: {e}", file=sys.stderr)
            rows.append({"folder": str(folder), "status": "failed", "reason": str(e)})
            continue
        d = result.document
        rows.append({"folder": str(folder), "status": "ok", "out": str(result.out_path),
                     "marks": len(d["marks"]),
                     "skipped_photos": sum(im.get("status") != "ok" for im in d["images"]),
                     "effects": [e["name"] + (f"(joint {e['joint']})" if "joint" in e else "")
                                 for e in d["effects"]],
                     "residual_rms_mm": d["residual_rms_mm"]["final_model"],
                     "validation_rms_mm": d["validation_rms_mm"]["final_model"]})
        if not req.quiet:
            ref = result.session.raw.get("reference")
            print(format_summary(result.document, reference=ref))
        for im in result.document.get("images", []):
            if im.get("status") != "ok":
                print(f"vision-cal: warning: {folder}/{im['file']}: skipped: {im.get('reason')}",
                      file=sys.stderr)
        meas = result.measurement
        for note in (meas.inferred_notes if meas is not None else ()):  # no images list
            print(f"vision-cal: warning: {folder}: {note}", file=sys.stderr)
        if report is not None:
            print(f"report: {report} ({report.stat().st_size / 1e6:.1f} MB)")
        print(f"wrote {result.out_path}")
    if several:
        root = Path(req.out or "out")
        atomic_write_json(root / "summary.json", {"folders": rows})
        print(_summary_table(rows))
        print(f"wrote {root / 'summary.json'}")
    return 1 if failures else 0


def _write_report(result, out: Path) -> Path:
    try:
        return write_report(result.out_path, out)
    except BaseException:  # Ctrl-C or a failure: both report files or neither
        for n in ("report.json", "report.html"):
            (out / n).unlink(missing_ok=True)
        raise


def _inputs(folders) -> list:
    return [("DIR", f) for f in folders]


def _summary_table(rows) -> str:
    def f(x):
        return "-" if x is None else f"{x:.4f}"

    lines = [f"{'folder':<28}{'status':<8}{'marks':>6}{'skipped':>8}{'rms [mm]':>10}"
             f"{'held-out':>10}  effects"]
    for r in rows:
        if r["status"] != "ok":
            lines.append(f"{r['folder'][-28:]:<28}{'failed':<8}  {r['reason']}")
            continue
        lines.append(f"{r['folder'][-28:]:<28}{'ok':<8}{r['marks']:>6}{r['skipped_photos']:>8}"
                     f"{f(r['residual_rms_mm']):>10}{f(r['validation_rms_mm']):>10}  "
                     f"{', '.join(r['effects']) or 'none'}")
    return "\n".join(lines)
