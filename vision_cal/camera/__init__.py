"""Cameras in the robot frame: a still camera's pose (``fixed``), pixel -> robot mapping,
and its export (``export``). Frames and fields: ``docs/format.md``, "Cameras"."""
