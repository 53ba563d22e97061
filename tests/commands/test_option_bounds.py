"""Every numeric option of every command has a range (issue 38): the parser is enumerated,
so an option added without one fails here; a value beyond either end, or not finite, is one
line naming the option, exit 2, before anything is read or written."""

from __future__ import annotations

import argparse

import pytest

from tests.commands.test_trust import assert_one_line, cli
from vision_cal.commands.main import build_parser


PARSER = build_parser()   # built once: main() builds the same


def _numeric_options():
    """(command, option, action) of every option and positional that takes numbers."""
    sub = next(a for a in PARSER._actions if isinstance(a, argparse._SubParsersAction))
    found = []
    for name, p in sub.choices.items():
        for a in p._actions:
            numeric = a.type in (int, float) or hasattr(a.type, "bounds")
            if numeric:
                flag = max(a.option_strings, key=len) if a.option_strings else a.dest
                found.append((name, flag, a))
    return found


OPTIONS = _numeric_options()


def test_the_enumeration_finds_the_options():
    names = {(c, o) for c, o, _ in OPTIONS}
    assert {("design", "--trigger-output"), ("calibrate", "--jobs"), ("sheet", "--custom"),
            ("locate", "--joints"), ("plan", "--home")} <= names
    assert len(OPTIONS) >= 30


def test_every_numeric_option_has_a_range():
    """A number is either one of a few choices or bounded at both ends."""
    unbounded = [f"{c} {o}" for c, o, a in OPTIONS
                 if a.choices is None and not (hasattr(a.type, "bounds")
                                               and None not in a.type.bounds)]
    assert unbounded == [], "give these a range (vision_cal.commands.bounded)"


def _beyond(a) -> list[list[str]]:
    """Values beyond each end of ``a``'s range, and one that is not finite."""
    lo, hi = a.type.bounds
    n = a.nargs if isinstance(a.nargs, int) else 1
    out = [[str(hi * 10 + 10)] * n, [str(lo - abs(lo) * 10 - 10)] * n]
    if a.type.__name__ == "number":
        out.append(["nan"] * n)
    return out


CASES = [(c, o, v) for c, o, a in OPTIONS if a.choices is None and hasattr(a.type, "bounds")
         for v in _beyond(a)]


@pytest.mark.parametrize("command,option,values", CASES,
                         ids=[f"{c}{o}={v[0]}" for c, o, v in CASES])
def test_a_value_out_of_range_is_one_line(capsys, command, option, values):
    """main()'s parser (the one error path of every option; built once here: cheap)."""
    with pytest.raises(SystemExit) as e:
        PARSER.parse_args([command, option, *values])
    assert e.value.code == 2
    line = assert_one_line(capsys.readouterr().err, option)
    assert "expected" in line and values[0] in line


def test_through_main_nothing_is_written(tmp_path, capsys):
    """The whole command: exit 2, one line, no output folder (--trigger-output=-5 wrote
    `On -5` into the camera program)."""
    rc, _, err = cli(["design", "robot.yaml", "--sheet", "s.json", "--camera-on-arm",
                      "--out", tmp_path / "o", "--trigger-output=-5"], capsys)
    assert rc == 2
    assert_one_line(err, "--trigger-output", "non-negative", "got -5")
    assert list(tmp_path.iterdir()) == []


def test_the_ranges_agree_with_the_library():
    """Where the library checks the same number, the command line's range is the same."""
    from vision_cal.dataset.session import MAX_POSES
    from vision_cal.dataset.robot import OUTPUT_BITS
    from vision_cal.sheet.layout import MAX_PAGE_MM

    bounds = {(c, o): a.type.bounds for c, o, a in OPTIONS if hasattr(a.type, "bounds")}
    assert bounds[("design", "--n-poses")] == (8, MAX_POSES)
    assert bounds[("design", "--trigger-output")] == OUTPUT_BITS
    assert bounds[("sheet", "--custom")][1] == MAX_PAGE_MM
