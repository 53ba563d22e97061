"""Datasets: session.json, truth.json, calibration.json and the plan CSVs (vision-cal/1)."""
