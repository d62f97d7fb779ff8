"""Scoring errors: shapes, empty GT, bad inputs and configurations, one-line messages.

Conventions of the code under test: reference.py (METHOD.md §1–3).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scoring_support import EST_HAND, GT_HAND, one_line

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.evaluator import Evaluator
from dispeval_ros.errors import (
    ConfigurationError,
    EmptyGroundTruthError,
    InputError,
    ShapeMismatchError,
)


def test_shape_mismatch_errors() -> None:
    evaluator = Evaluator(criteria=("all", "visibility", "roi"))
    gt = np.ones((3, 4), np.float32)
    cases = [
        lambda: evaluator.score(gt, np.ones((4, 3), np.float32), roi=np.ones((3, 4))),
        lambda: evaluator.score(
            gt, gt, masks={"nonocc": np.ones((3, 5), bool)}, roi=np.ones((3, 4))
        ),
        lambda: evaluator.score(gt, gt, roi=np.ones((2, 4))),
        lambda: evaluator.score(gt, gt, gt_right=np.ones((3, 3), np.float32), roi=np.ones((3, 4))),
    ]
    for case in cases:
        with pytest.raises(ShapeMismatchError) as error:
            case()
        one_line(error)


@pytest.mark.parametrize(
    "gt",
    [np.zeros((3, 3)), np.full((2, 2), np.nan), np.full((2, 2), -1.0), np.full((2, 2), np.inf)],
)
def test_all_invalid_gt(gt: np.ndarray) -> None:
    with pytest.raises(EmptyGroundTruthError) as error:
        Evaluator().score(gt, np.ones_like(gt))
    one_line(error)


def test_all_mask_that_leaves_nothing() -> None:
    gt = np.ones((2, 2), np.float32)
    with pytest.raises(EmptyGroundTruthError) as error:
        Evaluator().score(gt, gt, masks={"all": np.zeros((2, 2), bool)})
    assert "'all' mask" in one_line(error)


@pytest.mark.parametrize(
    ("gt", "est"),
    [
        (np.ones((2, 2, 3)), np.ones((2, 2))),
        (np.ones((2, 2)), np.ones((2, 2, 1))),
        (np.ones(4), np.ones(4)),
        (np.ones((2, 2), complex), np.ones((2, 2))),
        (np.ones((2, 2)), np.ones((2, 2), complex)),
        (np.array([["a", "b"]]), np.ones((1, 2))),
        ([[1.0, 2.0], [3.0]], np.ones((2, 2))),
    ],
)
def test_input_errors(gt: object, est: object) -> None:
    with pytest.raises(InputError) as error:
        Evaluator(criteria=("all",)).score(gt, est)  # type: ignore[arg-type]
    one_line(error)


@pytest.mark.parametrize(
    "make",
    [
        lambda: Evaluator(criteria=("all", "nope")),
        lambda: Evaluator(criteria=()),
        lambda: Evaluator(missing="skip"),
        lambda: Evaluator(measures=("bmp", "epe")),
        lambda: Evaluator(measures=()),
        lambda: Evaluator(delta=0),
        lambda: Evaluator(mu=-1),
        lambda: Evaluator().score(np.ones((2, 2)), np.ones((2, 2)), masks={"occ": np.ones((2, 2))}),
        lambda: Evaluator(criteria=("roi",)).score(np.ones((2, 2)), np.ones((2, 2))),
        lambda: Evaluator(criteria=("depth",), depth_ranges=[(0, 10)]).score(
            np.ones((2, 2)), np.ones((2, 2))
        ),
        lambda: Evaluator(criteria=("depth",), depth_ranges=[(0, 10), (20, math.inf)]).score(
            np.ones((2, 2)), np.ones((2, 2)), Camera(f=1.0, baseline=1.0)
        ),
        lambda: Evaluator(criteria=("roi",), roi_names={1: "a", 2: "a"}).score(
            np.ones((2, 2)), np.ones((2, 2)), roi=np.ones((2, 2))
        ),
    ],
)
def test_configuration_errors(make) -> None:
    with pytest.raises(ConfigurationError) as error:
        make()
    one_line(error)


def test_unknown_names_are_named_in_the_message() -> None:
    for make, name in (
        (lambda: Evaluator(criteria=("bogus",)), "bogus"),
        (lambda: Evaluator(missing="bogus"), "bogus"),
        (lambda: Evaluator(measures=("bogus",)), "bogus"),
    ):
        with pytest.raises(ConfigurationError) as error:
            make()
        assert name in one_line(error)


def test_scores_unknown_criterion_is_a_key_error() -> None:
    scores = Evaluator(criteria=("all",)).score(GT_HAND, EST_HAND)
    assert "interior" not in scores
    assert scores.get("interior") is None
    with pytest.raises(KeyError):
        scores["interior"]
