"""Calibration of the base model: circle fits (the paper), closed-form init, least squares."""
