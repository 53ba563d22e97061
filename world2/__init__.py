"""world2: a second, independent print-off world for vision-cal (see README.md).

Not part of the vision_cal package and never imported by it: tests and benches put the
repository root on sys.path and ``import world2``.
"""

from .world import Options, World, make_world, session_and_truth, write_dataset

__all__ = ["Options", "World", "make_world", "session_and_truth", "write_dataset"]
