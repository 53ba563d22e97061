"""The report's tool section, from calibration.json's ``tool`` block alone (issue 21)."""

from __future__ import annotations

import numpy as np

from tests.tool.test_tool_pipeline import _session
from vision_cal.commands.main import main
from vision_cal.report.html import tool_html


def test_identified_tool_with_std_and_joint4_circle():
    doc = {"tool": {"identified": True, "tool_mm": [-18.7012, 22.4003], "std_mm": [0.0031, 0.0042],
                    "radius_mm": 29.18, "circle_joint4": {"center_mm": [1.0, 2.0], "radius_mm": 29.2},
                    "folded_q4_deg": 0.0,
                    "correlations": {"tool.x_mm": {"L2_mm": -0.95, "z2": 0.2}}}}
    h = tool_html(doc)
    assert "tool_mm = [-18.7012 &plusmn; 0.0031, 22.4003 &plusmn; 0.0042] mm" in h
    assert "joint-4 circle" in h and "tool.x_mm ~ L2_mm (-0.950)" in h and "z2" not in h


def test_folded_tool_says_what_would_separate_it():
    doc = {"tool": {"identified": False, "j4_deg": 30.0, "tool_mm_nominal": [-20.0, 20.0],
                    "statement": "every mark has the same j4_deg: folded into L2 and z2",
                    "to_separate": "draw marks at three or more j4_deg values"}}
    h = tool_html(doc)
    assert "folded into L2 and z2" in h and "j4 = 30.0 deg" in h
    assert "To separate it: draw marks at three or more j4_deg values" in h
    assert tool_html({"params": {}}) == ""


def test_report_html_has_the_tool(tmp_path):
    rng = np.random.default_rng(5)
    n = 30
    q = np.column_stack([rng.uniform(10, 100, n), rng.uniform(-110, -40, n)])
    d = _session(tmp_path, rng.uniform(-160, 160, n), q)
    assert main([str(d), "--out", str(tmp_path / "out"), "--report", "-q"]) == 0
    page = (tmp_path / "out" / "report.html").read_text()
    assert "Tool (the pen off the joint-4 axis)" in page and "tool_mm = [" in page
