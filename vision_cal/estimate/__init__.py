"""The estimator: marks in, a calibration out (circle fits of the paper, the tool and joint
4, placements, plausibility; the effects the base model lacks traced from the residual,
the replication by halves and the verdict)."""
