"""Strict readers of each controller language, written from the vendors' public manuals and
example programs (docs/controllers.md, "What the syntax follows"), not from the writers:
each reads a program file as its controller would load it and fails (AssertionError) on
any statement, structure, name, string length or line count the language does not take.

The limits and reserved words are the one table both the writers and these readers use
(``vision_cal.program.rules.RULES``); the structure is read here, independently.

``read_program(kind, path)`` returns ``(ops, tool)``: ops ``("move", (j1, j2, j3, j4))``,
``("pen", down)``, ``("wait", s)``, ``("say", text)`` in the order the controller runs
them, and the calibrated tool ``(x, y)`` the program defines or names in a comment (None:
none).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

from vision_cal.program.rules import RULES, name_problem

NUM = r"\s*(-?\d+(?:\.\d+)?)\s*"
EXPONENT = re.compile(r"(?<![A-Za-z_])\d+(?:\.\d+)?[eE][-+]?\d")


def _ascii_lines(kind: str, text: str, newline: str) -> list[str]:
    """The file's lines (its own line ending only), each printable ASCII and within the
    language's line length."""
    assert text.isascii(), "a character outside ASCII"
    bad = re.search(r"[^\t\r\n\x20-\x7e]", text)
    assert bad is None, f"a control character {bad and bad.group(0)!r}"
    body = text.split(newline)
    assert body[-1] == "", "the last line is not ended"
    body = body[:-1]
    limit = RULES[kind].line_chars
    for i, line in enumerate(body, 1):
        assert "\r" not in line and "\n" not in line, f"line {i}: a stray line break"
        assert limit is None or len(line.encode()) <= limit, f"line {i}: over {limit} characters"
    return body


def _no_exponent(code: str, where: str, allowed=()) -> None:
    for m in EXPONENT.finditer(code):
        assert m.group(0) in allowed, f"{where}: a number with an exponent {m.group(0)!r}"


def _message(kind: str, text: str, where: str) -> str:
    assert len(text) <= RULES[kind].string_max, \
        f"{where}: a string of {len(text)} characters (at most {RULES[kind].string_max})"
    return text


def _name(kind: str, name: str, where: str, taken=()) -> str:
    problem = name_problem(kind, name, taken=taken)
    assert problem is None, f"{where}: {problem}"
    return name


def _split_comment(line: str, marks: str) -> tuple[str, str]:
    """(code, comment) of a line whose comment starts at a character of ``marks`` outside
    a double-quoted string."""
    inside = False
    for i, c in enumerate(line):
        if c == '"':
            inside = not inside
        elif c in marks and not inside:
            return line[:i], line[i + 1:]
    assert not inside, f"an unterminated string: {line!r}"
    return line, ""


# ------------------------------------------------------------------------------ SPEL+

def read_spel(path: Path):
    lines = _ascii_lines("spel", path.read_bytes().decode("ascii"), "\r\n")
    ops, tool, inside, ended, last = [], None, False, False, None
    for i, raw in enumerate(lines, 1):
        code, comment = _split_comment(raw, "'")
        code = code.strip()
        if m := re.match(rf"^\s*TLSet n, XY\({NUM},{NUM}, 0, 0\)$", comment):
            tool = (float(m[1]), float(m[2]))
        if not code:
            continue
        _no_exponent(code, f"line {i}")
        if not inside:
            assert code == "Function main" and not ended, f"line {i}: code outside a function"
            inside = True
        elif code == "Fend":
            inside, ended = False, True
        else:
            last = _spel_statement(code, i, ops, last)
            if m := re.match(rf"^TLSet (\d+), XY\({NUM},{NUM}, 0, 0\)$", code):
                assert 1 <= int(m[1]) <= 15, f"line {i}: TLSet {m[1]}"
                tool = (float(m[2]), float(m[3]))
    assert ended and not inside, "no Fend"
    return ops, tool


def _spel_statement(code: str, i: int, ops: list, last):
    """One SPEL+ statement into ``ops``; returns the point the arm stands on."""
    ja = rf"JA\({NUM},{NUM},{NUM},{NUM}\)"
    if m := re.match(rf"^Go {ja}$", code):
        q = tuple(float(v) for v in m.groups())
        ops.append(("move", q))
        return q
    if m := re.match(rf"^Jump {ja} LimZ{NUM}$", code):   # rise, travel, come down
        q, z = tuple(float(v) for v in m.groups()[:4]), float(m[5])
        if last is not None:
            ops.append(("move", (last[0], last[1], z, last[3])))
        ops += [("move", (q[0], q[1], z, q[3])), ("move", q)]
        return q
    if m := re.match(r"^(On|Off) (\d+)$", code):
        ops.append(("pen", m[1] == "On"))
    elif m := re.match(rf"^Wait{NUM}$", code):
        ops.append(("wait", float(m[1])))
    elif m := re.match(r'^Print "([^"]*)"$', code):
        ops.append(("say", _message("spel", m[1], f"line {i}")))
    elif m := re.match(r"^(Speed (\d+)|Accel (\d+), (\d+))$", code):
        assert all(1 <= int(v) <= 100 for v in m.groups()[1:] if v), f"line {i}: {code}"
    elif not re.match(r"^(Motor (On|Off)|Power (Low|High)|TLSet .*)$", code):
        raise AssertionError(f"line {i}: unexpected statement {code!r}")
    return last


# ------------------------------------------------------------------------------ RAPID

def read_rapid(path: Path):
    lines = _ascii_lines("rapid", path.read_bytes().decode("ascii"), "\n")
    name = path.stem
    assert lines[0] == f"MODULE MOD_{name}" and lines[-1] == "ENDMODULE"
    _name("rapid", f"MOD_{name}", "module")
    _name("rapid", name, "routine")
    ops, tool, inside, routines, tool_name = [], None, False, 0, None
    for i, raw in enumerate(lines[1:-1], 2):
        code = _split_comment(raw, "!")[0].strip()
        if not code:
            continue
        _no_exponent(code, f"line {i}", allowed=("9E9",))
        if not inside:
            m = re.match(rf"^LOCAL PERS tooldata tVisionCal := \[TRUE,\[\[{NUM},{NUM},0\],"
                         r"\[1,0,0,0\]\],\[0\.1,\[0,0,1\],\[1,0,0,0\],0,0,0\]\];$", code)
            if m and routines == 0:
                tool = (float(m[1]), float(m[2]))
            elif code == f"PROC {name}()":
                inside, routines = True, routines + 1
            else:
                raise AssertionError(f"line {i}: unexpected declaration {code!r}")
        elif code == "ENDPROC":
            inside = False
        else:
            tool_name = _rapid_statement(code, i, ops, name) or tool_name
    assert routines == 1 and not inside, "one PROC ... ENDPROC"
    assert tool_name == ("tool0" if tool is None else "tVisionCal")
    return ops, tool


def _rapid_statement(code: str, i: int, ops: list, name: str) -> str | None:
    """One RAPID statement into ``ops``; returns the tool a move names."""
    move = re.match(rf"^MoveAbsJ \[\[{NUM},{NUM},{NUM},{NUM},0,0\],\[9E9,9E9,9E9,9E9,9E9,"
                    rf"9E9\]\]\\NoEOffs, v500, fine, (tool0|tVisionCal);$", code)
    if move:
        ops.append(("move", tuple(float(v) for v in move.groups()[:4])))
        return move[5]
    if m := re.match(r"^SetDO (\w+), ([01]);$", code):
        _name("rapid", m[1], f"line {i}: the signal", taken=(f"MOD_{name}", name, "tVisionCal"))
        ops.append(("pen", m[2] == "1"))
    elif m := re.match(rf"^WaitTime \\InPos,{NUM};$", code):
        ops.append(("wait", float(m[1])))
    elif m := re.match(r'^TPWrite "([^"\\]*)";$', code):
        ops.append(("say", _message("rapid", m[1], f"line {i}")))
    elif m := re.match(rf"^AccSet{NUM},{NUM};$", code):
        assert 20 <= float(m[1]) <= 100, f"line {i}: AccSet below RAPID's 20 %"
    elif not re.match(rf"^VelSet{NUM},{NUM};$", code):
        raise AssertionError(f"line {i}: unexpected statement {code!r}")
    return None


# ------------------------------------------------------------------------------ VAL3

V3 = "http://www.staubli.com/robotics/VAL3/"
XSI_TYPE = "{http://www.w3.org/2001/XMLSchema-instance}type"


def read_val3(path: Path):
    """The application whose project is ``path`` (``NAME/NAME.pjx``)."""
    folder, app = path.parent, path.stem
    assert folder.name == app, "the application's folder is not named as its project"
    _name("val3", app, "the application")
    for f in folder.iterdir():
        _ascii_lines("val3", f.read_bytes().decode("ascii"), "\n")
    project = ET.fromstring(path.read_bytes())
    assert project.tag == f"{{{V3}Project/3}}Project"
    params = project.find(f"{{{V3}Project/3}}Parameters")
    assert re.fullmatch(r"s[78]\.\d+(\.\d+)?", params.get("version"))
    assert params.get("millimeterUnit") == "true" and int(params.get("stackSize")) > 0
    files = [p.get("file") for p in project.iter(f"{{{V3}Project/3}}Program")]
    (data_file,) = [d.get("file") for d in project.iter(f"{{{V3}Project/3}}Data")]
    assert data_file == f"{app}.dtx" and {"start.pgx", "stop.pgx"} <= set(files)
    assert sorted(f.name for f in folder.iterdir()) == sorted([path.name, data_file, *files]), \
        "files in the folder the project does not list, or listed and missing"
    data, data_tool = _val3_data(folder / data_file, app)
    programs = {f[:-4]: _val3_program(folder / f) for f in files}
    ops, tool = _val3_code("start", programs["start"], data)
    stop_ops, _ = _val3_code("stop", programs["stop"], data)
    assert [op for op, _ in stop_ops if op == "move"] == [], "stop() moves the arm"
    assert tool == data_tool, "the tool start() names is not the application's"
    return ops, data_tool


def _val3_data(path: Path, app: str) -> tuple[dict, tuple | None]:
    """The application's global data (name -> type; dio links checked) and its tool."""
    root = ET.fromstring(path.read_bytes())
    ns = f"{{{V3}Data/2}}"
    assert root.tag == f"{ns}Database"
    out: dict = {}
    tool = None
    for d in root.iter(f"{ns}Data"):
        name, typ = d.get("name"), d.get("type")
        _name("val3", name, "global data", taken=(app, *out))
        assert d.get(XSI_TYPE) == "array" and d.get("size") == "1"
        (value,) = d.findall(f"{ns}Value")
        if typ == "dio":
            assert re.fullmatch(r"[A-Za-z][\w-]*\\%Q\d+", value.get("link")), value.get("link")
        elif typ == "tool":
            assert value.get("fatherId") == "flange[0]"
            tool = (float(value.get("x")), float(value.get("y")))
        else:
            raise AssertionError(f"{name}: data of type {typ}")
        out[name] = typ
    return out, tool


def _val3_program(path: Path) -> tuple[dict, list[str]]:
    """(locals: name -> type, code lines) of a one-program ``.pgx`` named as its file."""
    root = ET.fromstring(path.read_bytes())
    ns = f"{{{V3}Program/2}}"
    (prog,) = root.findall(f"{ns}Program")
    assert prog.get("name") == path.stem
    locs = {loc.get("name"): loc.get("type") for loc in prog.iter(f"{ns}Local")}
    for n in locs:
        _name("val3", n, f"{path.name}: a local")
    lines = prog.find(f"{ns}Code").text.split("\n")
    assert lines[0] == "begin" and lines[-1] == "end", f"{path.name}: begin ... end"
    return locs, lines[1:-1]


def _val3_code(name: str, program, data: dict):
    locs, lines = program
    assert not set(locs) & set(data), f"{name}: a local hides a global"
    ops, tool, j, waiting = [], None, {}, False
    dios = [n for n, t in data.items() if t == "dio"]
    for i, raw in enumerate(lines, 2):
        code, _, comment = raw.partition("//")
        code = code.strip()
        if m := re.match(rf"^The calibrated tool is tPen \(x{NUM}mm, y{NUM}mm", comment.strip()):
            tool = (float(m[1]), float(m[2]))
        if not code:
            continue
        _no_exponent(code, f"{name} line {i}")
        assert not waiting or code == "waitEndMove()", f"movej without waitEndMove: {code!r}"
        if m := re.match(rf"^l_j\.j([1-4]) ={NUM}$", code):
            assert locs.get("l_j") == "joint"
            j[int(m[1])] = float(m[2])
        elif code == "movej(l_j, flange, l_m)":
            assert sorted(j) == [1, 2, 3, 4], "a joint not set before movej"
            ops.append(("move", (j[1], j[2], j[3], j[4])))
            j, waiting = {}, True
        elif code == "waitEndMove()":
            waiting = False
        elif (m := re.match(r"^(\w+) = (true|false)$", code)) and m[1] in dios:
            ops.append(("pen", m[2] == "true"))
        elif m := re.match(rf"^delay\({NUM}\)$", code):
            ops.append(("wait", float(m[1])))
        elif m := re.match(r'^putln\("([^"]*)"\)$', code):
            ops.append(("say", _message("val3", m[1], f"{name} line {i}")))
        elif m := re.match(rf"^l_m\.(vel|accel|decel) ={NUM}$|^l_m\.blend = off$", code):
            assert locs.get("l_m") == "mdesc"
        elif code not in ("disablePower()", "resetMotion()"):
            raise AssertionError(f"{name} line {i}: unexpected statement {code!r}")
    assert not waiting
    return ops, tool


# ------------------------------------------------------------------------------ eV+

def read_evplus(path: Path):
    lines = _ascii_lines("evplus", path.read_bytes().decode("ascii"), "\n")
    name = _name("evplus", path.stem, "the program")
    assert lines[0] == f".PROGRAM {name}()" and lines[-1] == ".END"
    assert sum(1 for ln in lines if ln.startswith(".PROGRAM")) == 1
    ops, tool, pending = [], None, False
    for i, raw in enumerate(lines[1:-1], 2):
        code, comment = _split_comment(raw, ";")
        code = code.strip()
        if m := re.match(rf"^\s*TOOL TRANS\({NUM},{NUM}, 0, 0, 0, 0\)$", comment):
            tool = (float(m[1]), float(m[2]))
        if not code:
            continue
        _no_exponent(code, f"line {i}")
        assert not pending or code == "BREAK", f"a MOVE without BREAK before {code!r}"
        if m := re.match(rf"^MOVE #PPOINT\({NUM},{NUM},{NUM},{NUM}\)$", code):
            ops.append(("move", tuple(float(v) for v in m.groups())))
            pending = True
        elif code == "BREAK":
            pending = False
        elif m := re.match(r"^SIGNAL (-?\d+)$", code):
            assert int(m[1]) != 0
            ops.append(("pen", int(m[1]) > 0))
        elif m := re.match(rf"^DELAY{NUM}$", code):
            ops.append(("wait", float(m[1])))
        elif m := re.match(r'^TYPE "([ !#-~]*)"$', code):   # ASCII 32..126 but "
            ops.append(("say", _message("evplus", m[1], f"line {i}")))
        elif m := re.match(rf"^TOOL TRANS\({NUM},{NUM}, 0, 0, 0, 0\)$", code):
            tool = (float(m[1]), float(m[2]))
        elif not re.match(rf"^(SPEED{NUM}ALWAYS|ACCEL{NUM},{NUM}|FINE ALWAYS|DISABLE POWER)$",
                          code):
            raise AssertionError(f"line {i}: unexpected statement {code!r}")
    assert not pending
    return ops, tool


# ------------------------------------------------------------------------------ PacScript

def read_pacscript(path: Path):
    lines = _ascii_lines("pacscript", path.read_bytes().decode("ascii"), "\r\n")
    _name("pacscript", path.stem, "the program (its file)")
    ops, tool, inside, ended, defined = [], None, False, False, None
    for i, raw in enumerate(lines, 1):
        code, comment = _split_comment(raw, "'")
        code = code.strip()
        if m := re.match(rf"^\s*Tool n, P\({NUM},{NUM}, 0, 0, 0, 0\)$", comment):
            tool = (float(m[1]), float(m[2]))
        if not code:
            continue
        _no_exponent(code, f"line {i}")
        if not inside:
            assert code == "Sub Main" and not ended, f"line {i}: code outside Sub Main"
            inside = True
        elif code == "End Sub":
            inside, ended = False, True
        elif m := re.match(rf"^Move P, @E J\({NUM},{NUM},{NUM},{NUM}\)$", code):
            ops.append(("move", tuple(float(v) for v in m.groups())))
        elif m := re.match(r"^(Set|Reset) IO\[(\d+)\]$", code):
            ops.append(("pen", m[1] == "Set"))
        elif m := re.match(r"^Delay (\d+)$", code):
            ops.append(("wait", int(m[1]) / 1000))
        elif m := re.match(r'^PrintDbg "([^"]*)"$', code):
            ops.append(("say", _message("pacscript", m[1], f"line {i}")))
        elif m := re.match(rf"^Tool (\d+), P\({NUM},{NUM}, 0, 0, 0, 0\)$", code):
            assert 1 <= int(m[1]) <= 63
            defined, tool = int(m[1]), (float(m[2]), float(m[3]))
        elif m := re.match(r"^ChangeTool (\d+)$", code):
            assert int(m[1]) == defined, "ChangeTool of a tool the program did not define"
        elif not re.match(rf"^(TakeArm Keep = 0|Motor On|Motor Off|GiveArm|"
                          rf"(Speed|Accel|Decel){NUM})$", code):
            raise AssertionError(f"line {i}: unexpected statement {code!r}")
    assert ended
    return ops, tool


# ------------------------------------------------------------------------------ Fanuc TP

def read_tp(path: Path):
    text = path.read_bytes().decode("ascii")
    _ascii_lines("tp", text, "\n")
    name = _name("tp", path.stem, "the program")
    sections = re.split(r"^(/PROG .*|/ATTR|/MN|/POS|/END)$", text, flags=re.M)
    heads = [s for s in sections if s.startswith("/")]
    assert heads == [f"/PROG  {name.upper()}", "/ATTR", "/MN", "/POS", "/END"]
    attr, mn, pos = sections[4], sections[6], sections[8]
    assert len(re.search(r'COMMENT\t\t= "([^"]*)";', attr)[1]) <= 16
    tool_num = None
    points = {}
    for m in re.finditer(rf"P\[(\d+)\]\{{\n   GP1:\n\tUF : 0, UT : (\d+),\n\tJ1={NUM}deg,"
                         rf"\tJ2={NUM}deg,\tJ3={NUM} mm,\n\tJ4={NUM}deg\n\}};", pos):
        points[int(m[1])] = tuple(float(v) for v in m.groups()[2:])
        tool_num = tool_num or int(m[2])
        assert int(m[2]) == tool_num, "points recorded with different tools"
    assert len(points) == pos.count("P["), "a /POS entry the reader does not read"
    body = mn.strip("\n").split("\n")
    count = int(re.search(r"LINE_COUNT\t= (\d+);", attr)[1])
    assert len(body) == count <= RULES["tp"].lines_max
    ops, tool = _tp_body(body, points, tool_num)
    return ops, tool


def _tp_body(body: list[str], points: dict, tool_num):
    ops, tool = [], None
    line = re.compile(r"^([ \d]{4}):(J P\[(\d+)\] (\d+)% FINE|  (.*)) ;$")
    for i, raw in enumerate(body, 1):
        m = line.match(raw)
        assert m and m[1] == f"{i:4d}", f"not TP line {i}: {raw!r}"
        if m[3]:
            assert 1 <= int(m[4]) <= 100
            ops.append(("move", points[int(m[3])]))
            continue
        code = m[5]
        _no_exponent(code, f"line {i}")
        if mm := re.match(r"^DO\[(\d+)\]=(ON|OFF)$", code):
            assert int(mm[1]) >= 1
            ops.append(("pen", mm[2] == "ON"))
        elif mm := re.match(rf"^WAIT{NUM}\(sec\)$", code):
            ops.append(("wait", float(mm[1])))
        elif code.startswith("!"):
            assert ";" not in code
            _message("tp", code[1:], f"line {i}")
            if mm := re.match(rf"^!UTOOL\[(\d+)\] x{NUM}y{NUM}$", code):
                tool = (float(mm[2]), float(mm[3]))
            ops.append(("say", code[1:]))
        elif (mm := re.match(r"^UTOOL_NUM=(\d+)$", code)):
            assert tool_num is None or int(mm[1]) == tool_num, "UTOOL_NUM is not the points'"
        elif code != "UFRAME_NUM=0":
            raise AssertionError(f"line {i}: unexpected statement {code!r}")
    return ops, tool


READERS = {"spel": read_spel, "rapid": read_rapid, "val3": read_val3, "evplus": read_evplus,
           "pacscript": read_pacscript, "tp": read_tp}


def read_program(kind: str, path) -> tuple[list, tuple | None]:
    """Read the program of ``kind`` at ``path`` strictly (:data:`READERS`)."""
    return READERS[kind](Path(path))
