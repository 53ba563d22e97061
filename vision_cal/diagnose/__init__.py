"""Diagnosis: residuals traced to the effects the base model lacks."""
