"""Each controller language's limits, in one table: what a name may be, the words it may
not be, how long a string, a line and a program may get (docs/controllers.md cites where
each figure comes from).

The writers check the names they write (the program or module, named after its output
file; the robot file's ``pen_signal``) with :func:`check_name` and keep messages within
:attr:`Rules.string_max`; the tests' strict readers (``tests/program/checkers.py``) read
the same table, and their own reading of each language's structure.

``reserved``: the language's keywords and data types and the predefined names a
vision-cal program uses (a name the program declares is added by its writer), compared
without case where the language ignores case (RAPID, eV+, PacScript, Fanuc TP) and, to be
safe, in VAL3 as well.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from vision_cal.errors import VisionCalError


@dataclass(frozen=True)
class Rules:
    language: str
    name_chars: str            # a regular expression of one name (its characters)
    name_max: int | None       # the characters of a name (None: not limited by vision-cal)
    name_rule: str             # the rule in words, for messages
    reserved: frozenset        # upper-cased words a name may not be
    string_max: int            # the characters of a string literal (message) written
    line_chars: int | None     # the characters of one line (None: no limit known)
    lines_max: int | None      # the lines of one program (None: no limit known)

    def is_reserved(self, name: str) -> bool:
        return name.upper() in self.reserved


def _words(text: str) -> frozenset:
    return frozenset(w.upper() for w in text.split())


# ABB RAPID: "Reserved words" of the RAPID overview manual, and the names a vision-cal
# module uses (instructions, data types, predefined data, a task's entry routine `main`)
RAPID_RESERVED = _words("""
    ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF
    ENDMODULE ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR EXIT FALSE FOR FROM FUNC GOTO
    IF INOUT LOCAL MOD MODULE NOSTEPIN NOT NOVIEW OR PERS PROC RAISE READONLY RECORD RETRY
    RETURN STEP SYSMODULE TEST THEN TO TRAP TRUE TRYNEXT UNDO VAR VIEWONLY WHILE WITH XOR
    MoveAbsJ SetDO WaitTime VelSet AccSet TPWrite InPos NoEOffs
    num bool string jointtarget robjoint extjoint tooldata speeddata zonedata signaldo
    v500 fine tool0 wobj0 load0 main""")

# Staubli VAL3: the language's keywords, its types, the instructions and predefined data a
# vision-cal application uses, and its own programs (start, stop)
VAL3_RESERVED = _words("""
    begin end if then else endIf for to step endFor while endWhile do until switch case
    default endSwitch return call and or xor not true false nil
    bool num string dio aio sio screen tool frame point joint trsf config mdesc
    pointRx pointRs jointRx jointRs configRx configRs
    movej movel movec waitEndMove resetMotion delay putln disablePower enablePower
    flange world start stop""")

# Omron/Adept eV+ (V+): the keywords a vision-cal program uses and their neighbours (the
# V+ Language User's Guide: "keywords reserved by Adept cannot be used")
EVPLUS_RESERVED = _words("""
    MOVE MOVES APPRO DEPART BREAK FINE COARSE ALWAYS SIGNAL DELAY TYPE SPEED ACCEL TOOL TRANS
    PPOINT DISABLE ENABLE POWER CALL RETURN STOP HALT PAUSE WAIT IF THEN ELSE END DO UNTIL
    WHILE FOR TO STEP CASE OF VALUE ANY GOTO AND OR XOR NOT MOD TRUE FALSE ON OFF PI HERE
    SET LOCAL AUTO GLOBAL DEST""")

# Denso PacScript: the statements a vision-cal program uses and the language's keywords
# (RC8 manual, "Naming convention": a reserved word cannot name a program file)
PACSCRIPT_RESERVED = _words("""
    Sub End Function Call Return Exit If Then Else ElseIf EndIf Select Case For Next To Step
    Do Loop While Wend Until Goto GoSub Dim Const Def And Or Xor Not Mod True False On Off
    Move Approach Depart Set Reset IO Delay Speed Accel Decel Tool ChangeTool TakeArm
    GiveArm Motor PrintDbg Keep Main P J T V I F D S""")


RULES = {
    "spel": Rules("Epson SPEL+", r"[A-Za-z][A-Za-z0-9_]*", None,
                  "a letter, then letters, digits or _", frozenset(), string_max=80,
                  line_chars=512, lines_max=None),
    "rapid": Rules("ABB RAPID", r"[A-Za-z][A-Za-z0-9_]*", 32,
                   "a letter, then letters, digits or _, at most 32", RAPID_RESERVED,
                   string_max=80, line_chars=None, lines_max=None),
    "val3": Rules("Staubli VAL3", r"[A-Za-z][A-Za-z0-9_]*", 15,
                  "a letter, then letters, digits or _, at most 15", VAL3_RESERVED,
                  string_max=80, line_chars=None, lines_max=None),
    "evplus": Rules("eV+", r"[A-Za-z][A-Za-z0-9._]*", 15,
                    "a letter, then letters, digits, . or _, at most 15", EVPLUS_RESERVED,
                    string_max=128, line_chars=None, lines_max=None),
    "pacscript": Rules("PacScript", r"[A-Za-z][A-Za-z0-9_]*", 64,
                       "a letter, then letters, digits or _, at most 64", PACSCRIPT_RESERVED,
                       string_max=80, line_chars=1024, lines_max=None),
    "tp": Rules("Fanuc TP", r"[A-Za-z][A-Za-z0-9_]*", 10,
                "a letter, then letters, digits or _, at most 10", frozenset(),
                string_max=32, line_chars=None, lines_max=9999),
}

#: the characters of a mark id in any program text (comments and messages): ids come from
#: the user's targets.csv and may be of any length; the mark's number says which it is
ID_CHARS = 24


def name_problem(kind: str, name: str, *, taken=()) -> str | None:
    """Why ``name`` cannot name something in a ``kind`` program (None: it can): its
    characters, its length, a reserved word, or one of ``taken`` (names the program
    itself declares)."""
    rules = RULES[kind]
    if not re.fullmatch(rules.name_chars, name or ""):
        return f"{name!r} is not a {rules.language} name ({rules.name_rule})"
    if rules.name_max is not None and len(name) > rules.name_max:
        return (f"{name!r} has {len(name)} characters, a {rules.language} name at most "
                f"{rules.name_max}")
    if rules.is_reserved(name):
        return f"{name!r} is a word {rules.language} reserves or the program uses"
    if name.upper() in {t.upper() for t in taken}:
        return f"{name!r} is a name the program itself declares ({', '.join(taken)})"
    return None


def check_name(kind: str, name: str, *, what: str, taken=(), file=None, field=None) -> None:
    """Refuse ``name`` (:func:`name_problem`) with one line naming ``file`` and ``field``;
    ``what`` says what it names ("the program, named after its file")."""
    problem = name_problem(kind, name, taken=taken)
    if problem is not None:
        raise VisionCalError(f"{what}: {problem}", file=file, field=field)


def check_program_name(kind: str, name: str, *, taken=()) -> None:
    """A program (or module, application) named after its output file's stem: refused,
    before anything is written, when the language cannot take it."""
    check_name(kind, name, taken=taken, field="--program",
               what=f"a {RULES[kind].language} program is named after its output file; "
                    "choose another output name")


def check_pen_signal(kind: str, robot, *, taken=()) -> None:
    """The robot file's ``program.pen_signal`` as a ``kind`` name (a signal or a global
    variable of the program)."""
    sig = robot.program.pen_signal
    if sig is not None:
        check_name(kind, sig, taken=taken, file=str(robot.path), field="program.pen_signal",
                   what="the pen output's name")


def check_tool_number(robot, tools: tuple[int, int], language: str) -> None:
    """The robot file's ``program.tool_number`` within the controller's tools ``(lo, hi)``
    (``language``: how the controller names them, for the message)."""
    n = robot.program.tool_number
    if n is not None and not tools[0] <= n <= tools[1]:
        raise VisionCalError(f"{language} {tools[0]}..{tools[1]}, got {n}",
                             file=str(robot.path), field="program.tool_number")


def short_id(mark_id) -> str:
    """A mark id as program text shows it: at most :data:`ID_CHARS` characters (a longer
    one cut, ending in ``~``)."""
    s = str(mark_id)
    return s if len(s) <= ID_CHARS else s[:ID_CHARS - 1] + "~"


def plain(x, decimals: int = 6) -> str:
    """A number as every controller reads it: no exponent, at most ``decimals`` decimals,
    no trailing zeros (``5e-05`` -> ``0.00005``, ``1234567.0`` -> ``1234567``)."""
    s = f"{float(x):.{decimals}f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s
