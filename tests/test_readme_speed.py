"""The README's speed figures are quotes of docs/speed.json, the file bench/speed.py and
bench/setup_times.py write (issue 41: a figure generated, not typed): each quote is in the
README as written there, and says the figures the file holds."""

from __future__ import annotations

import json

from tests.conftest import ROOT

SPEED = json.loads((ROOT / "docs" / "speed.json").read_text())


def _flat(text: str) -> str:
    return " ".join(text.split())


def test_the_readme_quotes_the_whole_run_as_measured():
    readme = _flat((ROOT / "README.md").read_text())
    whole, quotes = SPEED["whole"], SPEED["readme"]
    assert _flat(quotes["whole_row"]) in readme
    assert _flat(quotes["whole_text"]) in readme
    assert f"| {whole['ratio_cpu']:.2f}x plain OpenCV decode + detect (CPU)" in \
        quotes["whole_row"]
    assert f"costs {whole['ratio_cpu']:.1f} times plain" in quotes["whole_text"]


def test_the_readme_quotes_what_make_demo_cost_as_measured():
    readme = _flat((ROOT / "README.md").read_text())
    demo = SPEED["setup"]["demo"]
    m, s = divmod(int(round(demo["wall_s"])), 60)
    took = f"{m} min {s:02d} s" if m else f"{s} s"
    assert f"It takes {took} " in SPEED["setup"]["readme_demo"]
    assert _flat(SPEED["setup"]["readme_demo"]) in readme
