"""The estimator: marks in, a calibration out (circle fits of the paper, the tool and joint
4, placements, plausibility)."""
