"""The package's one exception type."""

from __future__ import annotations


class VisionCalError(Exception):
    """Any error vision-cal reports to a user: one line naming what to fix.

    ``file`` and ``field`` (when known) are put in front of the message, so
    ``VisionCalError("expected a number", file="session.json", field="marks[2].joints_deg")``
    reads ``session.json: marks[2].joints_deg: expected a number``.
    """

    def __init__(self, message: str, *, file: str | None = None, field: str | None = None):
        self.file = file
        self.field = field
        self.reason = message
        parts = [p for p in (file, field) if p]
        super().__init__(": ".join([*parts, message]))


class CalibrationError(VisionCalError):
    """The data cannot calibrate the model (too few marks, unidentifiable plan)."""


class FailureUsed(AttributeError):
    """A :class:`Failure` was used as if it were the result it stands for (an attribute of
    the result read from it): a programming error, named with the failure's reason and the
    check that was missed. An ``AttributeError``, so ``getattr(x, name, default)`` and
    ``hasattr`` keep working."""


class Failure:
    """A result that could not be made, and why: falsy, so a caller branches with
    ``if not result:``; it carries ``reason`` (one line). Reading any other attribute from
    it, as if it were the success, raises :class:`FailureUsed` with the reason and a hint
    (scikit-image's ``FailedEstimation`` does the same). Subclasses are frozen dataclasses
    with ``reason`` as a field (``vision_cal.model.lsq.FailedFit``,
    ``vision_cal.identify.associate.NoMatch``, ``vision_cal.camera.pose_pairs.PairsFailed``).
    """

    __slots__ = ()

    def __bool__(self) -> bool:
        return False

    def __getattr__(self, name: str):
        # only called when the normal lookup fails: an attribute of the success (copy's
        # and pickle's protocol lookups get the AttributeError they expect)
        reason = object.__getattribute__(self, "reason")
        raise FailureUsed(f"{type(self).__name__} has no {name!r}: the result could not be "
                          f"made ({reason}); check `if not result:` before using it")


#: the exit code of a command that did part of what it was asked (``plan`` and ``locate
#: --csv`` with some targets not planned: each listed with its reason)
EXIT_PARTIAL = 3
