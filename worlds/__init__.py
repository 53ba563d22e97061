"""The test and bench worlds built on :mod:`vision_cal.world`: what no ``vision-cal``
command runs, only ``tests/`` and ``bench/`` (not installed: ``pyproject.toml`` packages
``vision_cal*`` only; imported from the repository's root, as ``tests.*`` is).

    pose_pairs.py (pose pairs from a controller and a detector, for ``handeye --poses``),
    six_axis.py (a six-axis arm, its lens and ChArUco board, for ``handeye --robot-poses``),
    table_world.py (a sheet on a table, a block on it, seen by two cameras, for surveys)

They import ``vision_cal.world`` and what it may (``dataset/``, ``sheet/``, ...), nothing
that estimates (``tests/test_architecture.py``): a convention error there would cancel
between the data and the fit. ``world2/`` beside it is an independent generator."""
