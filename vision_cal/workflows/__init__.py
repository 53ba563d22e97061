"""The workflows on top: the calibration pipeline, the closed loop, verify, the
report's data. They call the stages below; commands call them through actions/."""
