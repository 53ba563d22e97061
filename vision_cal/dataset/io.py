"""Atomic file writing and JSON reading with one-line errors."""

from __future__ import annotations

import contextlib
import contextvars
import errno
import json
import math
import os
import re
import tempfile
from json import decoder, scanner
from pathlib import Path

import numpy as np
import yaml

from vision_cal.errors import VisionCalError


def _default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def _clean(o):
    """Replace non-finite floats by None so the file stays strict JSON."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    if isinstance(o, np.generic):
        return _clean(o.item())
    return o


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _cannot_write(path: Path, e: OSError, field: str | None = None) -> VisionCalError:
    why = e.strerror or type(e).__name__
    if isinstance(e, FileExistsError) or getattr(e, "errno", None) == errno.ENOTDIR:
        why = "a file is in the way (expected a folder on the path)"
    elif getattr(e, "errno", None) == errno.EROFS:
        why = "read-only file system"
    return VisionCalError(f"cannot write: {why}", file=str(path), field=field)


def output_dir(path, *, field: str | None = None) -> Path:
    """Check (creating nothing) that results can be written into the folder ``path``;
    else one line naming it and the option ``field`` it came from."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise VisionCalError("is a file, expected a folder: choose a folder's name (it is made "
                             "if missing)", file=str(path), field=field)
    probe = path
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if not probe.is_dir():
        raise VisionCalError(f"cannot write: {probe} is a file, expected a folder",
                             file=str(path), field=field)
    if not os.access(probe, os.W_OK | os.X_OK):
        why = "read-only file system" if _read_only(probe) else "permission denied"
        raise VisionCalError(f"cannot write: {why} ({probe})", file=str(path), field=field)
    return path


def _read_only(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def output_file(path, *, field: str | None = None) -> Path:
    """A file path that can be written (its folder created if needed), else one line."""
    path = Path(path)
    if path.is_dir() or str(path).endswith(os.sep):
        raise VisionCalError("is a folder, expected a file name", file=str(path), field=field)
    try:
        output_dir(path.parent, field=field)
    except VisionCalError as e:
        raise VisionCalError(f"cannot write into {path.parent}: {e.reason}", file=str(path),
                             field=field) from e
    return path


def atomic_write_bytes(path, data: bytes, *, at_once: bool = False) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder, then rename.
    ``at_once``: renamed now even inside :func:`written_together` (a detection cache entry,
    keyed by what it was computed from, is never stale and worth keeping from a run that
    is stopped).

    Any failure of the file system (a file where a folder should be, a folder where the file
    should be, read-only, full) is one :class:`VisionCalError` naming the path."""
    path = Path(path)
    if path.is_dir():
        raise VisionCalError("cannot write: is a folder, expected a file name", file=str(path))
    if not at_once:   # a result of the run: recorded in its output set (dataset/out_folder)
        note_written(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as e:
        raise _cannot_write(path, e) from e
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        pending = None if at_once else _PENDING.get()
        if pending is None:
            os.replace(tmp, path)
        else:  # inside written_together(): renamed with the others at its end
            pending.append((tmp, path))
    except BaseException as e:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(e, OSError):
            raise _cannot_write(path, e) from e
        raise
    return path


#: the lists the running output sets (dataset/out_folder.py) record their files in
_RECORDING: contextvars.ContextVar = contextvars.ContextVar("vision_cal_recording", default=())


@contextlib.contextmanager
def recording_writes():
    """Yields a list that receives the path of every file written (by
    :func:`atomic_write_bytes`, or told by :func:`note_written`) while the block runs, in
    nested blocks too: what a run wrote, for its output set's record."""
    written: list = []
    token = _RECORDING.set(_RECORDING.get() + (written,))
    try:
        yield written
    finally:
        _RECORDING.reset(token)


def note_written(path) -> None:
    """Tell the running output sets that ``path`` was written (a file or folder put in place
    by other means than :func:`atomic_write_bytes`, e.g. a rendered folder moved in)."""
    for written in _RECORDING.get():
        written.append(Path(path))


#: the (temporary file, final path) pairs of the ``written_together`` block being run
_PENDING: contextvars.ContextVar = contextvars.ContextVar("vision_cal_pending", default=None)


@contextlib.contextmanager
def written_together():
    """The outputs of one command, written together or not at all: inside the block every
    :func:`atomic_write_bytes` writes its temporary file only; when the block ends without
    an error (or a Ctrl-C) they are all renamed into place, else all removed, so a failure
    half-way (a program path that is a folder, a full disk) leaves every earlier output as
    it was."""
    if _PENDING.get() is not None:  # nested: the outer block decides
        yield
        return
    pending: list = []
    token = _PENDING.set(pending)
    try:
        yield
    except BaseException:
        _PENDING.reset(token)
        for tmp, _ in pending:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        raise
    _PENDING.reset(token)
    for i, (tmp, path) in enumerate(pending):
        try:
            os.replace(tmp, path)
        except OSError as e:
            for t, _ in pending[i:]:
                try:
                    os.unlink(t)
                except FileNotFoundError:
                    pass
            raise _cannot_write(Path(path), e) from e


def _same_file(a: Path, b: Path) -> bool:
    if a.resolve() == b.resolve():
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def distinct_outputs(outputs, inputs=()) -> None:
    """Refuse, in one line, an output path that is one of the command's inputs (it would be
    destroyed) or two outputs on one path (one would be lost). ``outputs`` and ``inputs``
    are (option or field name, path) pairs; None paths are skipped."""
    outs = [(f, Path(p)) for f, p in outputs if p is not None]
    ins = [(f, Path(p)) for f, p in inputs if p is not None]
    for i, (field, path) in enumerate(outs):
        for f_in, p_in in ins:
            if _same_file(path, p_in):
                raise VisionCalError(f"is the input {f_in}: writing it would destroy it; "
                                     "choose another name", file=str(path), field=field)
        for f2, p2 in outs[:i]:
            if _same_file(path, p2):
                raise VisionCalError(f"is also the output of {f2}: one would be lost; "
                                     "choose another name", file=str(path), field=field)


def atomic_write_text(path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def as_json(obj):
    """``obj`` exactly as :func:`atomic_write_json` writes it and ``json`` reads it back
    (non-finite floats None, numpy values Python ones, tuples lists)."""
    return json.loads(json.dumps(_clean(obj), default=_default, allow_nan=False))


def atomic_write_json(path, obj) -> Path:
    text = json.dumps(_clean(obj), indent=2, default=_default, allow_nan=False)
    return atomic_write_text(path, text + "\n")


#: what each reader expects (its ``what``), said when given a PDF, an image, a folder or
#: another kind of file instead: (the file's usual name in a folder, what to give)
EXPECTED = {
    "calibration": ("calibration.json", "the calibration.json `vision-cal calibrate` wrote"),
    "measurement": ("measurement.json", "the measurement.json `vision-cal calibrate` wrote"),
    "sheet file": ("sheet.json", "the sheet.json `vision-cal sheet` wrote"),
    "robot file": ("robot.yaml", "the robot file (YAML; `vision-cal robot-template -o "
                                 "robot.yaml` writes one to fill in)"),
    "session": ("session.json", "a dataset's session.json (`vision-cal design` writes it)"),
    "simulated robot file": (None, "the simulated robot's file (`vision-cal robot-template "
                                   "--simulated -o true_robot.yaml` writes one)"),
    "scene file": (None, "a scene file (YAML, like renders/default.yaml)"),
    "survey": ("survey.json", "the survey.json `vision-cal survey` wrote"),
    "poses file": (None, "the pose pairs file (JSON or CSV, docs/format.md)"),
    "targets CSV": (None, "a targets CSV (id,x_mm,y_mm)"),
    "plan CSV": (None, "a plan CSV (`vision-cal plan` writes it)"),
    "pixels CSV": (None, "a CSV of pixels (id,u_px,v_px)"),
    "marks CSV": (None, "a marks CSV (docs/format.md: marks measured by an instrument)"),
    "point list CSV": (None, "a program's point list (`--program csv`)"),
}
_TEXT = "a text file (JSON, YAML or CSV)"


def expected(what: str) -> str:
    """What a reader of ``what`` expects, in words (:data:`EXPECTED`)."""
    return EXPECTED.get(what, (None, _TEXT))[1]


def read_text(path, *, what: str = "file") -> str:
    """A UTF-8 text file (a leading byte-order mark, as Windows tools save, is dropped);
    missing or unreadable is one clear line naming it, and a folder, a PDF, an image or a
    path through a file says what to give instead (``what``: a key of :data:`EXPECTED`)."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError as e:
        raise VisionCalError(f"{what} not found", file=str(path)) from e
    except IsADirectoryError as e:
        raise VisionCalError(_folder_given(path, what), file=str(path)) from e
    except NotADirectoryError as e:   # sheet.pdf/session.json: a file given for a folder
        above = next((q for q in path.parents if q.is_file()), path.parent)
        raise VisionCalError(f"is a file, expected a folder (holding {path.name})",
                             file=str(above)) from e
    except UnicodeDecodeError as e:
        raise VisionCalError(_binary_given(path, what), file=str(path)) from e
    except OSError as e:
        raise VisionCalError(f"cannot read: {e.strerror or e}", file=str(path)) from e


def _folder_given(path: Path, what: str) -> str:
    """A folder given where a file is wanted: the file in it that was meant, else what to
    give."""
    name = EXPECTED.get(what, (None, None))[0]
    names = (name,) if name else () if what in EXPECTED else \
        ("calibration.json", "session.json", "sheet.json", "robot.yaml")
    try:
        known = [n for n in names if (path / n).is_file()]
    except OSError:
        known = []
    if known:
        return (f"is a folder, expected a file (in it: {', '.join(known)}; give the one "
                f"wanted, e.g. {path / known[0]})")
    return f"is a folder, expected {expected(what) if what in EXPECTED else 'a file'}"


def _binary_given(path: Path, what: str) -> str:
    """A binary file (the printable PDF, a photo) given where a text file is wanted."""
    try:
        head = path.read_bytes()[:8]
    except OSError:
        head = b""
    if head.startswith(b"%PDF"):
        beside = path.with_suffix(".json")
        sheets = what == "sheet file" or (what not in EXPECTED and (
            beside.is_file() or "sheet" in path.stem.lower()))
        if not sheets:  # not the sheet's PDF: a calibration, robot file... saved as PDF
            return f"is a PDF, expected {expected(what)}"
        return ("is the PDF to print, not the sheet's description: pass the sheet.json "
                f"beside it{f' ({beside})' if beside.is_file() else ''}")
    if head.startswith((b"\x89PNG", b"\xff\xd8\xff")):
        return f"is an image, expected {expected(what)}"
    return f"is not UTF-8 text (a binary file?), expected {expected(what)}"


def _line(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _top_keys(s: str, start: int, end: int):
    """(key, position) of the keys of the JSON object whose text is ``s[start:end]`` (after
    its ``{``), skipping nested objects, lists and strings."""
    depth, i = 0, start
    while i < end:
        c = s[i]
        if c == '"':
            j = i + 1
            while s[j] != '"':
                j += 2 if s[j] == "\\" else 1
            if depth == 0:
                k = j + 1
                while s[k] in " \t\r\n":
                    k += 1
                if s[k] == ":":
                    yield json.loads(s[i:j + 1]), i
            i = j + 1
            continue
        if c in "{[":
            depth += 1
        elif c in "}]":
            depth -= 1
        i += 1


def _json_duplicate(text: str) -> tuple[str, int, int]:
    """The first key given twice in one object, with its two lines: found again with the
    pure-Python scanner, which tells where each object starts (only run on a duplicate)."""
    found: list = []

    def parse_object(s_and_end, *args, **kw):
        s, start = s_and_end
        pairs, end = decoder.JSONObject(s_and_end, *args, **kw)
        if not found:
            keys = [k for k, _ in pairs]
            dup = next((k for i, k in enumerate(keys) if k in keys[:i]), None)
            if dup is not None:
                pos = [p for k, p in _top_keys(s, start, end) if k == dup]
                found.append((dup, _line(s, pos[0]), _line(s, pos[1])))
        return pairs, end

    dec = json.JSONDecoder(object_pairs_hook=list, parse_constant=float)
    dec.parse_object = parse_object
    dec.scan_once = scanner.py_make_scanner(dec)
    dec.decode(text)
    return found[0]


class _DuplicateKey(Exception):
    pass


def _no_duplicates(pairs):
    d = dict(pairs)
    if len(d) != len(pairs):
        raise _DuplicateKey
    return d


def read_json(path, *, what: str = "file") -> dict:
    """Read a JSON object; a missing or malformed file is one clear line. A key given twice
    in one object (JSON parsers silently keep the last) is refused naming both lines."""
    path = Path(path)
    text = read_text(path, what=what)
    try:
        obj = json.loads(text, parse_constant=lambda c: float(c),
                         object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as e:
        raise VisionCalError(f"not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})",
                             file=str(path)) from e
    except RecursionError as e:
        raise VisionCalError("not valid JSON: nested too deeply", file=str(path)) from e
    except _DuplicateKey as e:
        try:
            key, a, b = _json_duplicate(text)
        except RecursionError:
            raise VisionCalError("a key is given twice in one object", file=str(path)) from e
        raise VisionCalError(f"key {key!r} is given twice (lines {a} and {b}); keep one",
                             file=str(path)) from e
    if not isinstance(obj, dict):
        raise VisionCalError("expected a JSON object at the top level", file=str(path))
    return obj


#: the most values a YAML document may expand to through its aliases (``*name``): a robot
#: or scene file has a few hundred; an "alias bomb" of nine nested lists of nine has 10^9
MAX_YAML_VALUES = 1_000_000

#: YAML 1.2's core-schema float (``1e5``, ``2.5E-3``): PyYAML follows YAML 1.1, whose float
#: needs a dot and a signed exponent (``1.0e+5``), and reads ``1e5`` as the string "1e5"
_YAML12_FLOAT = r"^[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)[eE][-+]?[0-9]+$"


def _yaml_loader():
    class Loader(yaml.SafeLoader):
        """``safe_load`` plus: a key given twice in one mapping is refused with both lines,
        numbers follow YAML 1.2's core schema for exponents (``1e5`` is 100000.0), and a
        document whose aliases expand beyond :data:`MAX_YAML_VALUES` values is refused
        before anything is built."""

        def construct_mapping(self, node, deep=False):
            if isinstance(node, yaml.MappingNode):
                seen: dict = {}
                for key_node, _ in node.value:
                    if isinstance(key_node, yaml.ScalarNode):
                        k = key_node.value
                        if k in seen:
                            raise yaml.constructor.ConstructorError(
                                None, None, f"key {k!r} is given twice (lines {seen[k] + 1} "
                                f"and {key_node.start_mark.line + 1}); keep one",
                                key_node.start_mark)
                        seen[k] = key_node.start_mark.line
            return super().construct_mapping(node, deep=deep)

        def construct_document(self, node):
            sizes: dict = {}

            def size(n) -> int:
                if id(n) in sizes:
                    return sizes[id(n)]
                sizes[id(n)] = 1  # a recursive alias counts once
                if isinstance(n, yaml.SequenceNode):
                    total = 1 + sum(size(c) for c in n.value)
                elif isinstance(n, yaml.MappingNode):
                    total = 1 + sum(size(k) + size(v) for k, v in n.value)
                else:
                    total = 1
                sizes[id(n)] = total
                if total > MAX_YAML_VALUES:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"its aliases expand to more than {MAX_YAML_VALUES:,} "
                        "values (an alias bomb?)", n.start_mark)
                return total

            size(node)
            return super().construct_document(node)

    Loader.add_implicit_resolver("tag:yaml.org,2002:float", re.compile(_YAML12_FLOAT),
                                 list("-+.0123456789"))
    return Loader


def read_yaml(path, *, what: str = "file"):
    """Read a YAML document with a safe loader (no tags that build objects or run code; see
    :func:`_yaml_loader` for duplicate keys, ``1e5`` and aliases); a malformed file is one
    clear line with the line and column."""
    path = Path(path)
    text = read_text(path, what=what)
    try:
        return yaml.load(text, Loader=_yaml_loader())  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise VisionCalError(f"not valid YAML{where}: {problem}", file=str(path)) from e
    except RecursionError as e:
        raise VisionCalError("not valid YAML: nested too deeply", file=str(path)) from e
