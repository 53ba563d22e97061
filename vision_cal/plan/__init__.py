"""Off-line programming: calibration plans, joint trajectories and the compensated planner."""
