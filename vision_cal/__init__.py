"""vision-cal: camera-based calibration of SCARA robots programmed off-line.

The package reads as the pipeline::

    model -> dataset -> sheet | design -> measure -> identify -> estimate -> plan -> program
    | camera -> report, with one front on top (commands/ -> actions/); world/ beside it

See ``docs/conventions.md`` for frames, units and signs.
"""

from vision_cal.errors import VisionCalError

__version__ = "0.1.0"
__all__ = ["VisionCalError", "__version__"]
