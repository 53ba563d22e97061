"""The synthetic world: its own robot with hidden effects draws on a sheet and is
photographed; it shares no code with the estimator (``tests/test_architecture.py``)."""
