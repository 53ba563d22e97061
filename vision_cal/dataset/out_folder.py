"""An OUT folder holds one run's results, never a mix of two (issue 19).

- :func:`retire_earlier_run`: before a calibration writes anything into OUT, the results
  an earlier run left there (:data:`RESULT_FILES`) are moved into ``OUT/previous/``
  (replacing what an even earlier run left there). So a run that fails, or is stopped with
  Ctrl-C, leaves no calibration.json or report that looks current; the earlier results are
  kept, marked as previous, not lost. The detection cache (``OUT/.cache``) stays: it is
  keyed by the photos' bytes and the settings, never stale.
- :func:`output_names`: one output sub-folder name per dataset folder: the folder's name,
  or, when two folders share a name (``day1/plan day2/plan``), their names with as many
  parent folders as needed to tell them apart (``day1-plan``, ``day2-plan``). The same
  folder given twice is refused.

Every command that writes goes through this module (issue 30):

- :func:`writing_into`: the one way into an output folder. It refuses (one line, exit 2)
  a folder that is one of the command's inputs or holds an input file;
  takes the folder's lock (:data:`LOCK`: a second run into the same folder is refused in one
  line naming the first run's command and pid; a lock left by a run that died is taken
  over); moves the results an earlier run (of this command or another) left there into
  ``previous/`` (:func:`retire_earlier_run`), so an interrupted run leaves nothing that looks
  current; and releases the lock at the end, whatever happens.
- :func:`output_file_of_kind`: a single output file (CSV, PNG) that is not an input, not
  another output, and, when it exists, holds what this command writes: a calibration.json
  given as ``-o history.csv``'s path is refused, not overwritten.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import time
from pathlib import Path

from vision_cal.dataset.io import distinct_outputs, output_dir, output_file
from vision_cal.errors import VisionCalError

#: what one calibration run writes into OUT (the cache excepted)
RESULT_FILES = ("calibration.json", "measurement.json", "report.json", "report.html",
                "verify.json", "summary.json")
PREVIOUS = "previous"
#: the lock file of a folder being written (JSON: command, pid, host, started)
LOCK = ".vision-cal.lock"


def retire_earlier_run(out_dir, *, subfolders=(), results=RESULT_FILES) -> list[str]:
    """Move an earlier run's ``results`` (default :data:`RESULT_FILES`; a command that
    writes other files names its own) and the sub-folders ``subfolders`` it wrote (e.g. the
    placements of ``calibrate --joint``) from ``out_dir`` to ``out_dir/previous/``; returns
    the names moved (none: nothing to do)."""
    out = Path(out_dir)
    found = [n for n in results if (out / n).is_file()]
    subs = [n for n in subfolders if n and n != PREVIOUS and "/" not in n and n not in (".", "..")
            and (out / n).is_dir()]
    if not found and not subs:
        return []
    prev = out / PREVIOUS
    try:
        if prev.exists() and not prev.is_dir():
            raise VisionCalError("is a file, expected a folder for the earlier run's results",
                                 file=str(prev), field="--out")
        prev.mkdir(exist_ok=True)
        for n in results:  # the even earlier set goes: previous/ holds one run
            (prev / n).unlink(missing_ok=True)
        for n in found:
            os.replace(out / n, prev / n)
        for n in subs:
            if (prev / n).is_dir():
                shutil.rmtree(prev / n)
            os.replace(out / n, prev / n)
    except OSError as e:
        raise VisionCalError(f"cannot move the earlier run's results aside: "
                             f"{e.strerror or e}", file=str(out), field="--out") from e
    return found + [n + "/" for n in subs]


def retire_and_say(out_dir, *, subfolders=(), results=RESULT_FILES,
                   quiet: bool = True) -> list[str]:
    """:func:`retire_earlier_run`, the names moved printed (the output folder's one
    notice) unless ``quiet``."""
    moved = retire_earlier_run(out_dir, subfolders=subfolders, results=results)
    if moved and not quiet:
        print(f"moved the earlier results ({', '.join(moved)}) to "
              f"{Path(out_dir) / PREVIOUS}")
    return moved


def earlier_placements(out_dir) -> list[str]:
    """The placement sub-folders an earlier ``calibrate --joint`` wrote into ``out_dir``
    (its top calibration.json's ``placements[].folder``); none when there is none."""
    try:
        doc = json.loads((Path(out_dir) / "calibration.json").read_text(encoding="utf-8"))
        return [str(p["folder"]) for p in doc.get("placements", [])
                if isinstance(p, dict) and isinstance(p.get("folder"), str)]
    except (OSError, ValueError, AttributeError, TypeError):
        return []


def refuse_input_folder(out, inputs, *, field: str = "--out") -> None:
    """Refuse an output folder that is an input folder or holds an input file. ``inputs``:
    (option or argument name, path) pairs; None paths skipped."""
    o = Path(out).resolve()
    for name, p in inputs:
        if p is None:
            continue
        q = Path(p).resolve()
        if q.is_dir() and o == q:
            raise VisionCalError(f"is the input {name} ({p}): writing there would mix this "
                                 "run's results with its input; choose another folder",
                                 file=str(out), field=field)
        if q.is_file() and q.parent == o:
            raise VisionCalError(f"holds the input {name} ({p}): this run's results would "
                                 "replace or sit beside it; choose another folder",
                                 file=str(out), field=field)


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


@contextlib.contextmanager
def folder_lock(out, *, command: str, field: str = "--out"):
    """Hold ``out/.vision-cal.lock`` while the block runs. A lock of a live run (this host,
    its pid alive) is refused in one line; a stale one (its run died) is taken over."""
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
            path.unlink(missing_ok=True)   # stale: its run died (or is this process)
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
        if _read_lock(path).get("pid") == os.getpid():
            path.unlink(missing_ok=True)


@contextlib.contextmanager
def writing_into(out, *, command: str, field: str = "--out", inputs=(), retire: bool = True,
                 subfolders=(), results=RESULT_FILES, quiet: bool = True):
    """The one way a command writes into an output folder (see the module docstring).
    Yields the folder (created); the names moved to ``previous/`` are printed unless
    ``quiet``."""
    out = output_dir(out, field=field)
    refuse_input_folder(out, inputs, field=field)
    created = _missing_folders(out)   # out and the parents mkdir makes, deepest first
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise VisionCalError(f"cannot write: {e.strerror or e}", file=str(out),
                             field=field) from e
    try:
        with folder_lock(out, command=command, field=field):
            if retire:
                retire_and_say(out, subfolders=subfolders, results=results, quiet=quiet)
            yield out
    except BaseException:
        # a run that failed before writing anything leaves no empty folder (nor the empty
        # parents made for it: `calibrate DIR` without --out makes out/ and out/DIR)
        for d in created:
            try:
                d.rmdir()
            except OSError:
                break
        raise


def _missing_folders(out: Path) -> list[Path]:
    """``out`` and each of its parents that does not exist yet, deepest first."""
    missing = []
    p = Path(out).absolute()
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    return missing


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


def output_names(folders) -> list[str]:
    """One sub-folder name per dataset folder, unique (see the module docstring)."""
    paths = [Path(f).resolve() for f in folders]
    for i, p in enumerate(paths):
        if p in paths[:i]:
            raise VisionCalError(f"given twice (as {folders[paths.index(p)]} and {folders[i]})",
                                 file=str(folders[i]), field="DIR")
    names = []
    for p in paths:
        depth = 1
        while True:
            name = "-".join(p.parts[-depth:]) if depth <= len(p.parts) - 1 else str(p)
            others = ["-".join(q.parts[-depth:]) for q in paths if q != p]
            if name not in others or depth >= len(p.parts):
                break
            depth += 1
        names.append(name.lstrip(os.sep).replace(os.sep, "-") or "root")
    for i, n in enumerate(names):  # "c-plan" the folder and c/plan: still tell them apart
        if n in names[:i]:
            names[i] = f"{n}-{i + 1}"
    return names
