"""Failures as values (issue 31): falsy, with the reason, and raising with a hint when used
as the success they stand for (as scikit-image's FailedEstimation)."""

from __future__ import annotations

import copy
import pickle

import pytest

from vision_cal.model.lsq import FailedFit
from vision_cal.camera.pose_pairs import PairsFailed
from vision_cal.errors import CalibrationError, FailureUsed
from vision_cal.identify.associate import NoMatch

FAILURES = [FailedFit("only 3 marks"), NoMatch("only 3 marks matched"),
            PairsFailed("only 3 pairs")]


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
    """Protocol lookups (``__deepcopy__``, ``__setstate__``) are not taken as a use: a
    failure crosses to and from worker processes pickled."""
    assert copy.deepcopy(f) == f
    assert pickle.loads(pickle.dumps(f)) == f


def test_failed_fit_still_ends_the_run_on_request():
    with pytest.raises(CalibrationError, match="only 3 marks"):
        FailedFit("only 3 marks").or_raise()
