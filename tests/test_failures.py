"""Failures as values (issue 31): falsy, with the reason, and raising with a hint when used
as the success they stand for (as scikit-image's FailedEstimation)."""

from __future__ import annotations

import copy
import pickle

import pytest

from vision_cal.model.lsq import FailedFit
from vision_cal.workflows.arm_session import SkippedPhoto, measure_view
from vision_cal.camera.pose_pairs import PairsFailed
from vision_cal.errors import CalibrationError, FailureUsed
from vision_cal.identify.associate import NoMatch

FAILURES = [FailedFit("only 3 marks"), NoMatch("only 3 marks matched"),
            SkippedPhoto("a.png", "only 3 markers found"), PairsFailed("only 3 pairs")]


@pytest.mark.parametrize("f", FAILURES, ids=lambda f: type(f).__name__)
def test_a_failure_is_falsy_and_carries_its_reason(f):
    assert not f
    assert "only 3" in f.reason


@pytest.mark.parametrize("f", FAILURES, ids=lambda f: type(f).__name__)
def test_a_failure_used_as_the_success_raises_with_the_reason_and_a_hint(f):
    with pytest.raises(FailureUsed, match=r"has no 'params'.*only 3.*if not result"):
        f.params
    # still an AttributeError: getattr with a default and hasattr keep working
    assert getattr(f, "params", None) is None and not hasattr(f, "pairs")


@pytest.mark.parametrize("f", FAILURES, ids=lambda f: type(f).__name__)
def test_a_failure_copies_and_pickles(f):
    """Protocol lookups (``__deepcopy__``, ``__setstate__``) are not taken as a use: the
    arm camera's photos come back from worker processes pickled."""
    assert copy.deepcopy(f) == f
    assert pickle.loads(pickle.dumps(f)) == f


def test_failed_fit_still_ends_the_run_on_request():
    with pytest.raises(CalibrationError, match="only 3 marks"):
        FailedFit("only 3 marks").or_raise()


def test_an_unreadable_arm_photo_is_a_skipped_photo_with_its_entry(tmp_path):
    (tmp_path / "a.png").write_bytes(b"not a png")
    v, entry = measure_view(tmp_path, None, None, "a.png", (0.0, -90.0, 0.0), 0.0)
    assert isinstance(v, SkippedPhoto) and not v and v.file == "a.png"
    assert entry == {"file": "a.png", "status": "skipped", "reason": v.reason} and v.reason
    with pytest.raises(FailureUsed, match="corners_px"):
        v.corners_px
