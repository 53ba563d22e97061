"""The README's shell blocks, as a user types them (tests/test_readme.py, tests/test_rehearsal.py).

A block is a run of lines indented by four spaces after a blank line (Markdown's indented
code), under the nearest ``## `` heading. :func:`type_line` types one line in a folder: a
``vision-cal ...`` line through the command line's own entry point (in-process,
``main(shlex.split(line)[1:] + ["-q"])``), any other line through the shell.
"""

from __future__ import annotations

import os
import shlex
import subprocess
from dataclasses import dataclass

from tests.conftest import ROOT


@dataclass(frozen=True)
class Block:
    heading: str
    lines: tuple[str, ...]

    @property
    def commands(self) -> list[str]:
        """The lines a user types: without the ``-> what it writes`` notes."""
        return [ln.split("   -> ")[0].rstrip() if "   -> " in ln else ln for ln in self.lines]


def blocks(text: str | None = None) -> list[Block]:
    """Every indented block of the README, in order."""
    text = (ROOT / "README.md").read_text() if text is None else text
    out, heading, cur, prev_blank = [], "", [], True
    for ln in text.splitlines():
        if ln.startswith("## "):
            heading = ln[3:].strip()
        if ln.startswith("    ") and ln.strip() and (cur or prev_blank):
            cur.append(ln.strip())
        elif cur and not ln.startswith("    "):
            out.append(Block(heading, tuple(cur)))
            cur = []
        prev_blank = not ln.strip()
    if cur:
        out.append(Block(heading, tuple(cur)))
    return out


def blocks_under(heading: str) -> list[Block]:
    return [b for b in blocks() if b.heading.startswith(heading)]


def type_line(line: str, cwd, *, expect: int = 0) -> None:
    """Type ``line`` in folder ``cwd``; its exit code must be ``expect``."""
    if line.startswith("vision-cal "):
        from vision_cal.commands.main import main

        old = os.getcwd()
        os.chdir(cwd)
        try:
            rc = main(shlex.split(line)[1:] + ["-q"])
        finally:
            os.chdir(old)
        assert rc == expect, f"{line} exited {rc}"
    else:
        subprocess.run(line, shell=True, cwd=cwd, check=True)
