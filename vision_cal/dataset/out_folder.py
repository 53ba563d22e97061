"""Output sets: what one run of a command writes, replaced as a whole (issues 19, 30, 38).

Every command that writes files goes through this module, the one owner of the rule "OUT
holds one run of each command; what an earlier run wrote goes to ``previous/``":

- :func:`writing_into`: a command writing into a folder OUT (calibrate, handeye, verify,
  survey, design, sheet, simulate, render, loop).
- :func:`replacing_files`: a command writing files it is given the names of (plan, export,
  history, locate, init, robot-template); the folder of the first one plays OUT's part.

Both, in this order, before the run writes anything:

1. refuse, in one line naming the path and the option, an OUT that is one of the command's
   inputs, lies inside an input folder or holds an input file, a file where a folder is
   wanted (and the reverse), a lock of a run still going (:data:`LOCK`; a lock left by a run
   that died is taken over; a lock path that is not a file is refused);
2. move into ``OUT/previous/<set>/`` (:data:`PREVIOUS`) the earlier output sets this run
   replaces, each whole: everything this command's earlier run wrote there (the record
   :data:`RECORD` names it), and the whole set of any other command holding a file this one
   writes (``handeye`` into a pen calibration's folder moves that calibration to
   ``previous/calibrate/``). ``<set>`` is the command (``calibrate``, ``design`` ...), or for
   named files the command and the first file's stem (``plan-targets_plan``), so
   ``previous/`` keeps the last earlier run of each and never drops another command's. Files
   this command writes that no record names (written by an older vision-cal, or put there
   by hand) go to ``previous/unrecorded/`` (``unrecorded-2`` ... : never replaced). Input
   files are never moved; the detection cache (``.cache``) stays.

While the run writes, each file it writes (:func:`vision_cal.dataset.io.atomic_write_bytes`)
is recorded, and when it ends (done, failed or stopped) the record names them under its set:
the next run knows exactly what to move, however many files a dialect or a plan wrote. So a
run that fails or is stopped leaves nothing that looks current, and nothing is lost.

Also here: :func:`output_names` (one output sub-folder per input of several, never two
inputs into one), :func:`output_file_of_kind` (a single output file that holds what the
command writes, never a calibration given as a CSV's name) and :func:`refuse_other_sheet`.
"""

from __future__ import annotations

import contextlib
import fnmatch
import json
import os
import shutil
import socket
import time
from pathlib import Path

from vision_cal.dataset.io import (atomic_write_bytes, distinct_outputs, output_dir, output_file,
                                   recording_writes)
from vision_cal.errors import VisionCalError

PREVIOUS = "previous"
#: the lock file of a folder being written (JSON: command, pid, host, started)
LOCK = ".vision-cal.lock"
#: the record of which files each command's last run wrote into a folder (JSON)
RECORD = ".vision-cal-runs.json"
RECORD_FORMAT = "vision-cal/runs/1"
#: where files no record names go (``unrecorded``, ``unrecorded-2`` ...)
UNRECORDED = "unrecorded"

#: what a calibration's folder holds
CALIBRATION_FILES = ("calibration.json", "measurement.json", "report.json", "report.html")
#: what each command writes into its folder (names or patterns; ``name/`` a sub-folder):
#: the files a run replaces, whoever wrote them (a record names the exact set)
WRITES = {
    "calibrate": (*CALIBRATION_FILES, "summary.json"),
    "handeye": CALIBRATION_FILES,
    "verify": ("verify.json", "measurement.json"),
    "survey": ("survey.json",),
    "design": ("session.json", "preview.png", "trajectory.csv", "program.*", "program_*.csv",
               "survey.json", "placements.json"),
    "sheet": ("sheet.json", "sheet.pdf", "sheet.svg", "sheet.png"),
    "simulate": ("truth.json",),
    "render": ("session.json", "truth.json"),
    "loop": ("loop.json", "targets.csv", "plan_*.csv", "session/", "calibration/",
             "sheet_*/", "measure_*/", "survey_photos/", "survey/"),
}


# --------------------------------------------------------------------------- refusals

def refuse_input_folder(out, inputs, *, field: str = "--out") -> None:
    """Refuse an output folder that is an input folder, lies inside one, or holds an input
    file. ``inputs``: (option or argument name, path) pairs; None paths skipped."""
    o = Path(out).resolve()
    for name, p in inputs:
        if p is None:
            continue
        q = Path(p).resolve()
        if q.is_dir() and o == q:
            raise VisionCalError(f"is the input {name} ({p}): writing there would mix this "
                                 "run's results with its input; choose another folder",
                                 file=str(out), field=field)
        if q.is_dir() and o.is_relative_to(q):
            raise VisionCalError(f"lies inside the input {name} ({p}): this run's results "
                                 "would sit among its input; choose a folder outside it",
                                 file=str(out), field=field)
        if q.is_file() and q.parent == o:
            raise VisionCalError(f"holds the input {name} ({p}): this run's results would "
                                 "replace or sit beside it; choose another folder",
                                 file=str(out), field=field)


def refuse_other_sheet(out, sheet_id: str, *, field: str = "--out") -> None:
    """``vision-cal sheet --out DIR`` over a folder holding another sheet (another size,
    markers or field): refused, that sheet.json is what the plans were designed on."""
    path = Path(out) / "sheet.json"
    if not path.is_file():
        return
    try:
        printed = json.loads(path.read_text(encoding="utf-8")).get("printed") or {}
        earlier = printed.get("sheet_id")
        page = printed.get("page") or {}
    except (OSError, ValueError, AttributeError):
        earlier, page = None, {}
    if earlier != sheet_id:
        what = " ".join(str(page.get(k)) for k in ("name", "orientation") if page.get(k))
        raise VisionCalError(f"holds another sheet ({earlier or 'unreadable'}"
                             f"{', ' + what if what else ''}): plans designed on it would no "
                             "longer match the printed page; choose another folder (or remove "
                             "it)", file=str(path), field=field)


# --------------------------------------------------------------------------- the lock

def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def _read_lock(path: Path) -> dict:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        return doc if isinstance(doc, dict) else {}
    except (OSError, ValueError):
        return {}


def _not_a_file(path: Path, what: str, field: str) -> VisionCalError:
    kind = "a folder" if path.is_dir() else "not a regular file"
    return VisionCalError(f"is {kind}, expected {what}: remove it (vision-cal makes it)",
                          file=str(path), field=field)


@contextlib.contextmanager
def folder_lock(out, *, command: str, field: str = "--out"):
    """Hold ``out/.vision-cal.lock`` while the block runs. A lock of a live run (this host,
    its pid alive) is refused in one line; a stale one (its run died) is taken over; a lock
    path that is a folder or not a regular file is refused in one line."""
    out = Path(out)
    path = out / LOCK
    me = {"command": command, "pid": os.getpid(), "host": socket.gethostname(),
          "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    for _ in range(3):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            other = _read_lock(path)
            pid = other.get("pid")
            here = other.get("host") in (None, me["host"])
            if isinstance(pid, int) and pid != os.getpid() and (_alive(pid) or not here):
                raise VisionCalError(
                    f"is being written by another run (vision-cal {other.get('command', '?')},"
                    f" pid {pid}{'' if here else ' on ' + str(other.get('host'))}, since "
                    f"{other.get('started', '?')}): wait for it to end or choose another "
                    f"folder (if no such run is going, remove {path})",
                    file=str(out), field=field) from None
            try:
                path.unlink(missing_ok=True)   # stale: its run died (or is this process)
            except OSError as e:
                raise _not_a_file(path, "vision-cal's lock file", field) from e
            continue
        except OSError as e:
            raise VisionCalError(f"cannot write: {e.strerror or e}", file=str(out),
                                 field=field) from e
        with os.fdopen(fd, "w") as f:
            json.dump(me, f)
        break
    try:
        yield out
    finally:
        if path.is_file() and _read_lock(path).get("pid") == os.getpid():
            path.unlink(missing_ok=True)


# --------------------------------------------------------------------------- the record

def _read_record(folder: Path, field: str) -> dict:
    """set name -> the files (paths relative to ``folder``, ``/`` between folders) its last
    run wrote; {} without a record (or an unreadable one: its files count as unrecorded)."""
    path = folder / RECORD
    if path.is_symlink() or (path.exists() and not path.is_file()):
        raise _not_a_file(path, "vision-cal's record of the runs written here", field)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    runs = doc.get("runs") if isinstance(doc, dict) else None
    if not isinstance(runs, dict):
        return {}
    return {k: [f for f in v if isinstance(f, str) and f] for k, v in runs.items()
            if isinstance(k, str) and isinstance(v, list)}


def _write_record(folder: Path, record: dict) -> None:
    path = folder / RECORD
    runs = {k: sorted(set(v)) for k, v in sorted(record.items()) if v}
    if not runs:
        path.unlink(missing_ok=True)
        return
    text = json.dumps({"format": RECORD_FORMAT, "runs": runs}, indent=2) + "\n"
    atomic_write_bytes(path, text.encode("utf-8"), at_once=True)


def _relative(path: Path, folder: Path) -> str:
    """``path`` relative to ``folder`` with ``/`` (``../x`` for a file beside it)."""
    return Path(os.path.relpath(Path(path).absolute(), Path(folder).absolute())).as_posix()


def _record_run(folder: Path, key: str, written, *, outside: bool) -> None:
    """The record names what the run of set ``key`` wrote into ``folder`` (its files that
    exist: a ``written_together`` block that failed renamed none); a file another set's
    record named is this one's now. ``outside``: files outside ``folder`` are kept (named
    files), else left out (a folder's set is what is inside it)."""
    folder = Path(folder)
    rels = set()
    for p in written:
        rel = _relative(p, folder)
        parts = rel.split("/")
        if not (Path(p).exists() or Path(p).is_symlink()):
            continue
        if parts[0] == "..":
            if outside:
                rels.add(rel)
            continue
        if parts[0] in (PREVIOUS, ".") or any(s.startswith(".") for s in parts):
            continue   # the cache, the lock, the record, previous/: never a result
        rels.add(rel)
    try:
        record = _read_record(folder, "--out")
    except VisionCalError:
        return
    for k in list(record):
        record[k] = [f for f in record[k] if f not in rels]
    record[key] = sorted(rels | (set(record.get(key, [])) if key in record else set()))
    _write_record(folder, record)


# --------------------------------------------------------------------------- moving aside

def _matches(rel: str, patterns, folder: Path) -> bool:
    """Whether ``rel`` (a top-level name, or a path) is one a command writes."""
    for pat in patterns:
        if pat.endswith("/"):
            top = rel.split("/")[0]
            if fnmatch.fnmatchcase(top, pat[:-1]) and (folder / top).is_dir():
                return True
        elif fnmatch.fnmatchcase(rel, pat):
            return True
    return False


def _exists(p: Path) -> bool:
    return p.exists() or p.is_symlink()


def _earlier_sets(out: Path, record: dict, key: str, writes, keep: set) -> list:
    """The sets this run moves aside: [(set name, [relative paths that exist])], see the
    module docstring; files in ``keep`` (the run's inputs) are never among them."""
    def present(files):
        return [f for f in dict.fromkeys(files) if _exists(out / f)
                and (out / f).resolve() not in keep and f.split("/")[0] != PREVIOUS]

    sets = [(key, present(record.get(key, [])))]
    for other, files in record.items():
        if other != key and any(_matches(f, writes, out) for f in present(files)):
            sets.append((other, present(files)))
    recorded = {f.split("/")[0] for files in record.values() for f in files}
    loose = sorted(e.name for e in os.scandir(out)
                   if not e.name.startswith(".") and e.name != PREVIOUS
                   and e.name not in recorded and _matches(e.name, writes, out))
    sets.append((UNRECORDED, present(loose)))
    return [(k, files) for k, files in sets if files]


def _free_name(prev: Path, name: str) -> str:
    """``name``, or ``name-2`` ... the first not in ``prev`` (unrecorded sets never replace
    one another)."""
    n, i = name, 1
    while _exists(prev / n):
        i += 1
        n = f"{name}-{i}"
    return n


def _tidy(out: Path, dest: Path, moved, into) -> None:
    """After the files ``moved`` left their sub-folders: the folders left empty removed; one
    left with hidden files only (a cache) moved along, unless this run writes into it
    (``into``: its cache stays)."""
    tops = sorted({f.split("/")[0] for f in moved if "/" in f and not f.startswith("..")})
    for top in tops:
        d = out / top
        if not d.is_dir() or d.is_symlink():
            continue
        for sub in sorted((p for p in d.rglob("*") if p.is_dir() and not p.is_symlink()),
                          key=lambda p: -len(p.parts)):
            with contextlib.suppress(OSError):
                sub.rmdir()   # only when empty
        left = list(d.iterdir())
        if left and (any(fnmatch.fnmatchcase(top, i) for i in into)
                     or not all(p.name.startswith(".") for p in left)):
            continue
        for p in left:
            (dest / top).mkdir(parents=True, exist_ok=True)
            os.replace(p, dest / top / p.name)
        d.rmdir()


def _move_aside(out: Path, sets, *, into=(), field: str) -> list[str]:
    """Move each set's files into ``out/previous/<set>/`` (the set's earlier content there
    dropped; unrecorded sets get a new folder); returns the names moved."""
    if not sets:
        return []
    prev = out / PREVIOUS
    moved_names = []
    try:
        if _exists(prev) and not prev.is_dir():
            raise VisionCalError("is a file, expected a folder for the earlier runs' results",
                                 file=str(prev), field=field)
        prev.mkdir(exist_ok=True)
        for key, files in sets:
            name = _free_name(prev, key) if key == UNRECORDED else key
            dest = prev / name
            if dest.is_dir() and not dest.is_symlink():
                shutil.rmtree(dest)
            elif _exists(dest):
                dest.unlink()
            for f in files:
                if not _exists(out / f):   # named by two records: moved already
                    continue
                target = dest / (Path(f).name if f.startswith("..") else f)
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(out / f, target)
                moved_names.append(f"{PREVIOUS}/{name}/{target.relative_to(dest).as_posix()}")
            _tidy(out, dest, files, into)
    except OSError as e:
        raise VisionCalError(f"cannot move the earlier run's results aside: "
                             f"{e.strerror or e}", file=str(out), field=field) from e
    return moved_names


def _say_moved(out: Path, moved, quiet: bool) -> None:
    if moved and not quiet:
        names = [m.split("/", 1)[1] for m in moved]
        more = f" and {len(names) - 4} more" if len(names) > 4 else ""
        print(f"moved the earlier results ({', '.join(names[:4])}{more}) to "
              f"{Path(out) / PREVIOUS}/")


# --------------------------------------------------------------------------- the owners

def _missing_folders(out: Path) -> list[Path]:
    """``out`` and each of its parents that does not exist yet, deepest first."""
    missing = []
    p = Path(out).absolute()
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    return missing


def _make(out: Path, field: str) -> list[Path]:
    created = _missing_folders(out)   # out and the parents mkdir makes, deepest first
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise VisionCalError(f"cannot write: {e.strerror or e}", file=str(out),
                             field=field) from e
    return created


def _unmake(created) -> None:
    """A run that failed before writing anything leaves no empty folder (nor the empty
    parents made for it: ``calibrate DIR`` without --out makes out/ and out/DIR)."""
    for d in created:
        try:
            d.rmdir()
        except OSError:
            break


def _resolved(paths) -> set:
    return {Path(p).resolve() for p in paths if p is not None}


def _refuse_others(out: Path, sets, command: str, field: str) -> None:
    """``alone``: files the run would neither replace nor move aside are refused."""
    moving = {f.split("/")[0] for _, files in sets for f in files}
    others = sorted(e.name for e in os.scandir(out) if not e.name.startswith(".")
                    and e.name != PREVIOUS and e.name not in moving)
    if others:
        more = f" and {len(others) - 3} more" if len(others) > 3 else ""
        raise VisionCalError(f"holds {', '.join(others[:3])}{more}, not written by an earlier "
                             f"{command}: its output folder holds its own files only; choose "
                             "an empty folder (or move them)", file=str(out), field=field)


def _refuse_displacing(out: Path, sets, key: str, field: str) -> None:
    """``displace=False``: another command's results would be moved aside: refused."""
    for other, files in sets:
        if other not in (key, UNRECORDED):
            raise VisionCalError(f"holds what vision-cal {other} wrote ({', '.join(files[:3])}"
                                 f"{' ...' if len(files) > 3 else ''}), which this run would "
                                 "replace; choose another folder", file=str(out), field=field)


@contextlib.contextmanager
def writing_into(out, *, command: str, field: str = "--out", inputs=(), reads=(),
                 writes=None, into=(), alone: bool = False, displace: bool = True,
                 refuse=None, quiet: bool = True):
    """The one way a command writes into an output folder (see the module docstring).

    ``command``: the command (its first word names the set: ``calibrate --joint`` is
    ``calibrate``'s); ``inputs``: (name, path) pairs OUT must not be, lie inside nor hold;
    ``reads``: other paths the run reads (never moved); ``writes``: the names it writes
    (default :data:`WRITES` of the command); ``into``: sub-folders it writes into (names
    or patterns; their cache stays); ``alone``: files of other commands or of none in OUT
    are refused (render, loop); ``displace=False``: another command's set holding a file
    this run writes is refused rather than moved aside (a survey over a plan's copy);
    ``refuse(out, moving)``: the command's own refusal, called before anything moves with
    the relative paths that would. Yields the folder (created); what moved to
    ``previous/`` is printed unless ``quiet``."""
    key = command.split()[0]
    writes = WRITES.get(key, ()) if writes is None else tuple(writes)
    out = output_dir(out, field=field)
    refuse_input_folder(out, inputs, field=field)
    created = _make(out, field)
    try:
        with folder_lock(out, command=command, field=field):
            keep = _resolved([p for _, p in inputs] + list(reads))
            record = _read_record(out, field)
            sets = _earlier_sets(out, record, key, writes, keep)
            if refuse is not None:
                refuse(out, {f for _, files in sets for f in files})
            if alone:
                _refuse_others(out, sets, command, field)
            if not displace:
                _refuse_displacing(out, sets, key, field)
            moved = _move_aside(out, sets, into=into, field=field)
            for k, _ in sets:
                record.pop(k, None)
            _write_record(out, record)
            _say_moved(out, moved, quiet)
            with recording_writes() as written:
                try:
                    yield out
                finally:
                    _record_run(out, key, written, outside=False)
    except BaseException:
        _unmake(created)
        raise


@contextlib.contextmanager
def replacing_files(outputs, *, command: str, inputs=(), siblings=(), quiet: bool = True):
    """The one way a command writes files it was given the names of: ``outputs`` (option,
    path) pairs (None paths skipped), the first the main one; ``inputs`` (option, path)
    pairs never written nor moved; ``siblings``: other files an earlier run of the set may
    have written (a program of another dialect beside the plan). Refuses outputs that are
    inputs or each other or folders, locks the main file's folder, moves the set's earlier
    files (recorded, this run's outputs that exist, ``siblings``) into
    ``previous/<command>-<stem>/`` beside the main file, and records what the run writes."""
    outs = [(f, Path(p)) for f, p in outputs if p is not None]
    field, main = outs[0]
    distinct_outputs(outs, inputs)
    for f, p in outs:
        output_file(p, field=f)
    folder = main.parent
    key = f"{command.split()[0]}-{main.stem}"
    created = _make(folder, field)
    try:
        with folder_lock(folder, command=command, field=field):
            keep = _resolved(p for _, p in inputs)
            record = _read_record(folder, field)
            files = [*record.get(key, []), *(_relative(p, folder) for _, p in outs),
                     *(_relative(p, folder) for p in siblings)]
            files = [f for f in dict.fromkeys(files) if _exists(folder / f)
                     and not (folder / f).is_dir() and (folder / f).resolve() not in keep]
            moved = _move_aside(folder, [(key, files)] if files else [], field=field)
            record.pop(key, None)
            _write_record(folder, record)
            _say_moved(folder, moved, quiet)
            with recording_writes() as written:
                try:
                    yield [p for _, p in outs]
                finally:
                    _record_run(folder, key, written, outside=True)
    except BaseException:
        _unmake(created)
        raise


# --------------------------------------------------------------------------- single files

def _sniff(path: Path) -> str:
    """What an existing file holds: empty, png, pdf, json, csv, text or binary."""
    with open(path, "rb") as f:
        head = f.read(512)
    if not head.strip():
        return "empty"
    if head.startswith(b"\x89PNG"):
        return "png"
    if head.startswith(b"%PDF"):
        return "pdf"
    try:
        text = head.decode("utf-8-sig", errors="strict" if len(head) < 512 else "ignore")
    except UnicodeDecodeError:
        return "binary"
    first = text.lstrip()[:1]
    if first in ("{", "["):
        return "json"
    if "," in text.split("\n", 1)[0]:
        return "csv"
    return "text"


def output_file_of_kind(path, kind: str, *, field: str, inputs=(), outputs=()) -> Path:
    """A single output file of ``kind`` ("csv", "png" or "text"): not an input, not another of the
    command's ``outputs``, and, when a file is there already, one that holds ``kind`` (an
    earlier result of this command), else refused in one line, the file untouched."""
    path = output_file(path, field=field)
    distinct_outputs([*outputs, (field, path)], inputs)
    if path.is_file():
        try:
            found = _sniff(path)
        except OSError:
            found = "unreadable"
        # a CSV, YAML or URDF output may replace any plain text (an earlier one), never a
        # JSON document (a calibration), an image, a PDF or other binary
        plain = ("csv", "text", "empty")
        if not (found in plain if kind in plain else found in (kind, "empty")):
            raise VisionCalError(f"exists and holds {found.upper()}, not the {kind.upper()} this "
                                 f"option writes: writing it would destroy it; choose another "
                                 "name (or remove it)", file=str(path), field=field)
    return path


def output_names(folders, *, suffixes=()) -> list[str]:
    """One sub-folder name per input (see the module docstring): the input's name (without
    a suffix of ``suffixes``: ``marks.csv`` gives ``marks``), or, when two share it, with
    as many parent folders as tell them apart (``day1-plan``, ``day2-plan``); never one name
    for two inputs (``marks.csv`` and ``other/marks/``: ``marks`` and ``other-marks``). The
    same input given twice is refused."""
    real = [Path(f).resolve() for f in folders]
    for i, p in enumerate(real):
        if p in real[:i]:
            raise VisionCalError(f"given twice (as {folders[real.index(p)]} and {folders[i]})",
                                 file=str(folders[i]), field="DIR")
    stripped = [p.with_suffix("") if p.suffix.lower() in suffixes else p for p in real]
    # marks.csv beside a folder marks/: both keep their full names
    paths = [q if stripped.count(q) == 1 else p for p, q in zip(real, stripped)]
    names = []
    for i, p in enumerate(paths):
        depth = 1
        while True:
            name = "-".join(p.parts[-depth:]) if depth <= len(p.parts) - 1 else str(p)
            others = ["-".join(q.parts[-depth:]) for j, q in enumerate(paths) if j != i]
            if name not in others or depth >= len(p.parts):
                break
            depth += 1
        names.append(name.lstrip(os.sep).replace(os.sep, "-") or "root")
    for i, n in enumerate(names):  # "c-plan" the folder and c/plan: still tell them apart
        while n in names[:i]:
            n = f"{n}-{i + 1}"
        names[i] = n
    return names
