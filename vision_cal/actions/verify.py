"""``vision-cal verify CAL.json check/``: is the robot still calibrated? The check's photos
measured (:func:`vision_cal.actions.pipeline.measure_marks`), checked against what the
calibration was calibrated for (``valid_for``), and posed to the estimator
(:func:`vision_cal.estimate.verify.compare`: which base parameters are free, the check's
marks; the verdict and its thresholds are the estimator's); ``verify.json`` (atomic) in the
output folder. A calibration verify cannot check is refused first
(:func:`check_verifiable`). The command (:func:`verify`: its request, the check in an
output folder that is never an input's, its outcome that prints itself) comes first.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vision_cal.actions.console import say, warn
from vision_cal.actions.pipeline import measure_marks
from vision_cal.dataset.calibration import load_calibration
from vision_cal.dataset.camera_block import check_cameras
from vision_cal.dataset.fields import FieldReader
from vision_cal.dataset.io import atomic_write_json
from vision_cal.dataset.out_folder import writing_into
from vision_cal.dataset.session import load_session
from vision_cal.dataset.valid_for import check as check_valid_for
from vision_cal.dataset.valid_for import enforce as enforce_valid_for
from vision_cal.dataset.valid_for import of as valid_for_of
from vision_cal.errors import VisionCalError
from vision_cal.estimate.plausible import LINK_RATIO, own_marks_offset
from vision_cal.estimate.verify import VerifyResult, compare
from vision_cal.plan.extrapolation import beyond_deg, std_at_mm, std_limit_mm


@dataclass(frozen=True)
class VerifyRequest:
    """What ``vision-cal verify`` was asked (see its ``--help``)."""

    calibration: str              # CAL.json
    folder: str                   # the check's photos and session.json
    out: str | None = None        # default PHOTOS_verify beside the photos
    force: bool = False           # check marks outside the calibration's valid_for
    jobs: int | None = None       # photo measurement processes (default: every core)
    quiet: bool = False


@dataclass(frozen=True)
class VerifyOutcome:
    """The check's result, where verify.json was written, and the warnings (``--force``:
    marks compared beyond what was calibrated) for the console."""

    result: VerifyResult
    path: Path
    warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()    # every file the check wrote into its folder

    def lines(self) -> list[str]:
        """``vision-cal verify``: each mark's error, the RMS and its bound, which parameters
        moved, ISO 9283 and the verdict with its reasons."""
        r = self.result
        lines = [f"{'mark':<8}{'error x':>10}{'error y':>10}{'|error|':>10}  [mm, the sheet's "
                 "placement taken out]"]
        for mid, m in r.marks.items():
            ex, ey = m["error_mm"]
            lines.append(f"{mid:<8}{ex:>+10.4f}{ey:>+10.4f}{m['error_norm_mm']:>10.4f}")
        lines.append(f"RMS {r.rms_mm['sheet_placed']:.4f} mm (bound for 'still good': "
                     f"{r.bound_mm:.4f} mm)")
        lines.append(f"{'parameter':<12}{'change':>10}{'std':>9}  moved?")
        for label, c in r.changes.items():
            if c.get("sheet_placement"):
                continue
            lines.append(f"{label:<12}{c['delta']:>+10.4f}{c['std']:>9.4f}  "
                         f"{'yes' if c['moved'] else 'no'} ({c['sigmas']:.1f} std)")
        if r.iso9283:
            lines.append("ISO 9283 (each visit's own commanded point taken out; assumes the "
                         "robot's error is the same over each point's few-mm grid of visits):")
            lines += [f"  {name}: AP {v['AP_mm']:.4f} mm, RP {v['RP_mm']:.4f} mm "
                      f"({v['n']} visits)" for name, v in r.iso9283.items()]
        lines.append(f"verdict: {r.verdict}")
        lines += [f"  - {reason}" for reason in r.reasons]   # one finding or action a line
        others = [p.name for p in self.written if p != self.path]
        return lines + [f"wrote {self.path}" + (f" (and {', '.join(others)} beside it: the "
                                                 "photos as measured)" if others else "")]

    def show(self, quiet: bool = False) -> int:
        for w in self.warnings:   # --force: the check compared beyond what was calibrated
            warn(w)
        if not quiet:
            say(self.lines())
        return 0


def default_out(folder) -> Path:
    """Where a check's results go without ``-o``: ``PHOTOS_verify`` beside the photos,
    named as the user named the folder (``check/`` -> ``check_verify``: a relative path
    stays relative, so the console says what the user typed, not the machine's path)."""
    folder = Path(folder)
    if folder.name in ("", ".", ".."):
        here = folder.resolve()
        return here.with_name(here.name + "_verify")
    return folder.parent / f"{folder.name}_verify"


def verify(req: VerifyRequest) -> VerifyOutcome:
    """Check ``req.calibration`` on the photos of ``req.folder``; writes verify.json."""
    if req.jobs is not None and req.jobs < 1:
        raise VisionCalError(f"must be at least 1, got {req.jobs}", field="--jobs")
    folder = Path(req.folder)
    out = Path(req.out) if req.out else default_out(folder)
    # the output folder: never the photos' folder nor the one holding CAL.json; an earlier
    # check's results go to previous/; locked while written (issue 30)
    with writing_into(out, command="verify", field="-o",
                      inputs=[("CAL.json", req.calibration), ("PHOTOS/", req.folder)],
                      quiet=req.quiet) as out:
        r, path, said = verify_folder(req.calibration, folder, out_dir=out, jobs=req.jobs,
                                      progress=not req.quiet, force=req.force)
    written = tuple(sorted(p for p in Path(out).iterdir() if p.is_file()
                           and not p.name.startswith(".")))
    return VerifyOutcome(r, path, tuple(said), written)


#: the calibrations verify can check: pen marks fitted in one sheet's frame (a joint
#: calibration's placements too: OUT/<folder>/calibration.json)
CHECKABLE_METHODS = ("lsq", "paper", "lsq-placements")


def check_verifiable(model, doc: dict, path, session) -> None:
    """Refuse (one line naming ``path`` and the field, exit 2) a calibration verify cannot
    check a drawn check against: another ``method`` (a camera on the arm: no marks to
    compare), another ``frame`` (a joint calibration of several placements is in the robot
    frame), units that are not mm and degrees (its links beyond x0.7..x1.4 of the check's
    robot block, or its own marks not where its parameters put them), a verdict of ``not
    reliable`` or none it knows, or no promised error to hold the check to."""
    r = FieldReader(str(path))
    method = doc.get("method")
    if method not in CHECKABLE_METHODS:
        r.fail("method", f"{method!r}: verify checks a pen-mark calibration (method "
                         f"{' or '.join(CHECKABLE_METHODS)}) against marks drawn with design "
                         "--verify" + ("; check a camera on the arm with a new handeye run"
                                       if method == "arm_camera" else ""))
    frame = doc.get("frame", "sheet")
    if frame != "sheet":
        r.fail("frame", f"{frame!r}: verify checks a calibration in its sheet's frame; for a "
                        "joint calibration of several placements, verify one placement's "
                        "own calibration.json (OUT/<folder>/calibration.json)")
    v = doc.get("verdict")
    if v is not None:
        status = v.get("status") if isinstance(v, dict) else None
        if status == "not reliable":
            why = "; ".join(str(x) for x in (v.get("reasons") or [])[:2])
            r.fail("verdict.status", "'not reliable': there is no promise to check"
                                     + (f" ({why})" if why else "") + "; calibrate again")
        if status not in ("ready", "check"):
            r.fail("verdict.status", f"expected ready, check or not reliable, got {status!r}")
    promised = [((doc.get(k) or {}).get("final_model") if isinstance(doc.get(k), dict) else None)
                for k in ("validation_rms_mm", "residual_rms_mm")]
    if not any(isinstance(x, (int, float)) and x > 0 for x in promised):
        r.fail("residual_rms_mm", "missing: the calibration promises no error (no "
                                  "validation_rms_mm or residual_rms_mm final_model) to hold "
                                  "the check to")
    p, nom = model.params, session.robot
    for name, got, want in (("L1_mm", p.L1_mm, nom.L1_mm), ("L2_mm", p.L2_mm, nom.L2_mm)):
        ratio = got / want
        if not LINK_RATIO[0] <= ratio <= LINK_RATIO[1]:
            r.fail(f"params.{name}", f"{got:.6g} mm against the check's robot block {want:g} mm "
                                     f"({ratio:.3g}x, {session.path}): "
                                     + ("lengths in metres?" if 5e-4 < ratio < 2e-3 else
                                        "not this robot's calibration, or not in mm"))
    _check_own_marks(model, doc, r)
    check_cameras(doc, str(path))          # a still camera it carries: the one validator


def _check_own_marks(model, doc: dict, r: FieldReader) -> None:
    """The calibration's own marks lie where its parameters put them (its units are the
    marks': mm and degrees; the owner: ``estimate/plausible.own_marks_offset``)."""
    off = own_marks_offset(model, doc)
    if off is not None:
        r.fail("params", f"its own marks lie {off[0]:.3g} mm RMS from where its parameters "
                         f"put them (it fitted {off[1]:.3g} mm): {off[2]} verify reads mm "
                         "and degrees")


def verify_folder(cal_path, folder, *, out_dir, jobs: int | None = None,
                  progress: bool = False, force: bool = False
                  ) -> tuple[VerifyResult, Path, list[str]]:
    """Measure the check's photos in ``folder`` and compare them with ``cal_path``; writes
    ``out_dir/verify.json``. The check's marks are first checked against the calibration's
    ``valid_for`` (:mod:`vision_cal.dataset.valid_for`): a mark outside it compares the
    check with an extrapolation, refused unless ``force`` (then said in verify.json
    ``outside_valid_for`` and in the lines returned, for the console)."""
    model, doc = load_calibration(cal_path)
    session = load_session(folder)
    check_verifiable(model, doc, cal_path, session)
    out_dir = Path(out_dir)
    if out_dir.resolve() == Path(folder).resolve():
        raise VisionCalError("is the check's folder: the input folder is never written to",
                             file=str(out_dir), field="--out")
    q, a = session.joints_deg.tolist(), session.approach.astype(int).tolist()
    outside = check_valid_for(
        valid_for_of(doc, file=str(cal_path)), cal=str(cal_path),
        ids=[m.id for m in session.marks], joints_deg=q, approach=a,
        joint4_deg=session.j4_deg.tolist() if session.uses_joint4 else None,
        # beyond the marks' joints as far as the calibration's own expected error holds
        std_mm=std_at_mm(model, doc, [v[:2] for v in q], [v[:2] for v in a],
                         file=str(cal_path)),
        std_limit_mm=std_limit_mm(model, doc, file=str(cal_path)), beyond_deg=beyond_deg(doc))
    said = enforce_valid_for(outside, file=str(cal_path), force=force,
                             what=f"{folder}/session.json marks")
    measurement, data, missing = measure_marks(session, out_dir=out_dir, jobs=jobs,
                                               progress=progress)
    noise = (float(np.sqrt(2 * np.mean(data.sigma_mm**2)))
             if data.sigma_mm is not None and len(data.sigma_mm) else None)
    design = session.raw.get("design") if isinstance(session.raw, dict) else None
    iso_info = (((design or {}).get("iso9283") or {}).get("marks")) or {}
    k = np.array([i not in iso_info for i in data.ids], bool)
    iso = None
    if iso_info:
        j = ~k
        iso = ([i for i, s in zip(data.ids, j) if s], data.q_deg[j], data.approach[j],
               data.xy_mm[j], [iso_info[i]["point"] for i, s in zip(data.ids, j) if s])
    r = compare(model, doc, [i for i, s in zip(data.ids, k) if s], data.q_deg[k],
                data.approach[k], data.xy_mm[k], noise_floor_mm=noise, iso=iso)
    out = r.to_json()
    out.update(calibration=str(cal_path), folder=str(folder), missing_marks=missing,
               noise_floor_mm=noise)
    if outside:   # written because of force: the extrapolation stated in the file
        out["outside_valid_for"] = [o.to_json() for o in outside]
    path = atomic_write_json(out_dir / "verify.json", out)
    return r, path, said
