"""Measuring the sheet: ArUco grid to sheet millimetres, pen marks to sub-pixel centres."""
