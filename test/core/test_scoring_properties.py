"""Property-based: partitions cover the valid points and scores equal the numpy
re-computation on random frames; 3-means is a deterministic fixed point.

Conventions of the code under test: reference.py (METHOD.md §1–3).
"""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from reference import (
    POLICIES,
    assert_matches,
    near_jumps,
    numpy_measures,
    zbuffer_occlusion,
)
from scoring_support import INF, NAN

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.evaluator import Evaluator

GT_VALUES = st.one_of(
    st.floats(0.25, 64.0, width=32),
    st.sampled_from([1.0, 4.0, 4.0, 12.5, 30.0, 30.5]),
    st.sampled_from([0.0, NAN, INF, -2.0]),
)
OFFSETS = st.one_of(
    st.sampled_from([0.0, 0.0, 1.0, -1.0, 0.5, 3.5, -20.0]), st.floats(-6.0, 6.0, width=32)
)
CAMERAS = st.one_of(
    st.none(),
    st.builds(
        Camera,
        f=st.floats(50, 1500),
        baseline=st.floats(0.05, 1.0),
        doffs=st.sampled_from([0.0, 0.0, 12.5, 60.0]),
    ),
)


@st.composite
def frames(draw: st.DrawFn) -> dict[str, object]:
    """A small GT with random invalid points, an estimate with every kind of missing value."""
    height = draw(st.integers(1, 9))
    width = draw(st.integers(2, 12))
    shape = (height, width)
    gt = draw(hnp.arrays(np.float32, shape, elements=GT_VALUES))
    gt[0, 0] = 3.0  # at least one valid point
    offsets = draw(hnp.arrays(np.float32, shape, elements=OFFSETS))
    kinds = draw(hnp.arrays(np.int8, shape, elements=st.integers(0, 6)))
    with np.errstate(invalid="ignore"):
        base = np.where(np.isfinite(gt) & (gt > 0), gt, np.float32(10.0))
        est = (base + offsets).astype(np.float32)
    specials = {3: NAN, 4: 0.0, 5: -1.0, 6: 90.0}  # 90: outside est_range when one is given
    for kind, value in specials.items():
        est[kinds == kind] = value
    roi = draw(hnp.arrays(np.int8, shape, elements=st.integers(0, 3)))
    use_masks = draw(st.booleans())
    masks = None
    if use_masks:
        masks = {
            name: draw(hnp.arrays(np.bool_, shape, elements=st.booleans()))
            for name in ("nonocc", "disc")
        }
        if draw(st.booleans()):
            masks["all"] = draw(hnp.arrays(np.bool_, shape, elements=st.booleans()))
            masks["all"][0, 0] = True
    return {
        "gt": gt,
        "est": est,
        "roi": roi,
        "masks": masks,
        "camera": draw(CAMERAS),
        "est_range": draw(st.sampled_from([None, (0.5, 64.0), (2.0, 40.0)])),
        "delta": draw(st.sampled_from([1.0, 0.5, 2.0])),
    }


def independent_criteria(frame: dict, partition) -> dict[str, np.ndarray]:
    """Criterion masks built here, except the 3-means (checked by its own property test)."""
    gt = frame["gt"]
    masks = frame["masks"] or {}
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(gt) & (gt > 0)
    if "all" in masks:
        valid &= masks["all"]
    if "nonocc" in masks:
        occluded = valid & ~masks["nonocc"]
        near = masks["disc"]
    else:
        occluded = zbuffer_occlusion(gt, valid)
        near = near_jumps(gt, valid)
    boundary = valid & near & ~occluded
    interior = valid & ~near & ~occluded
    roi = frame["roi"]
    return {
        "all": valid,
        "occluded": occluded,
        "boundary": boundary,
        "interior": interior,
        "road": valid & (roi == 1),
        "car": valid & (roi == 2),
        "unlabelled": valid & (roi != 1) & (roi != 2),
        "nonocc": boundary | interior,
        "disc": boundary,
        **{name: partition.mask(name) for name in ("near", "mid", "far")},
    }


CRITERIA = ("all", "visibility", "depth", "roi", "legacy")
PROPERTY = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@PROPERTY
@given(frame=frames())
def test_partitions_are_disjoint_and_cover_the_valid_points(frame: dict) -> None:
    evaluator = Evaluator(criteria=CRITERIA, roi_names={1: "road", 2: "car"})
    reference = evaluator.reference(
        frame["gt"], frame["camera"], masks=frame["masks"], roi=frame["roi"]
    )
    partition = reference.partition
    expected = independent_criteria(frame, partition)
    valid = expected["all"]
    counts = partition.counts()
    sets = {
        "all": ("all",),
        "visibility": ("occluded", "boundary", "interior"),
        "depth": ("near", "mid", "far"),
        "roi": ("road", "car", "unlabelled"),
    }
    for members in sets.values():
        stack = np.array([partition.mask(name) for name in members], dtype=np.int64)
        np.testing.assert_array_equal(stack.sum(axis=0), valid.astype(np.int64))
        for name in members:
            assert counts[name] == int(partition.mask(name).sum())
        assert sum(counts[name] for name in members) == int(valid.sum())
    for name, mask in expected.items():
        np.testing.assert_array_equal(partition.mask(name), mask, err_msg=name)
    assert set(partition.overlapping) == {"nonocc", "disc"}


@PROPERTY
@given(frame=frames(), policy=st.sampled_from(POLICIES))
def test_scores_equal_numpy_recomputation(frame: dict, policy: str) -> None:
    evaluator = Evaluator(
        criteria=CRITERIA, missing=policy, delta=frame["delta"], roi_names={1: "road", 2: "car"}
    )
    kwargs = {"masks": frame["masks"], "roi": frame["roi"]}
    scores = evaluator.score(
        frame["gt"], frame["est"], frame["camera"], est_range=frame["est_range"], **kwargs
    )
    partition = evaluator.reference(frame["gt"], frame["camera"], **kwargs).partition
    expected = numpy_measures(
        frame["gt"],
        frame["est"],
        independent_criteria(frame, partition),
        policy,
        camera=frame["camera"],
        est_range=frame["est_range"],
        delta=frame["delta"],
    )
    assert scores.relative == (frame["camera"] is None)
    assert_matches(scores, expected)


def check_three_means(gt: np.ndarray, partition) -> None:
    """Lloyd fixed point: each value is nearest its own centroid, centroids are the means."""
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(gt) & (gt > 0)
    values = gt.astype(np.float64)
    clusters = [values[partition.mask(name)] for name in ("far", "mid", "near")]
    assert sum(c.size for c in clusters) == int(valid.sum())
    occupied = [c for c in clusters if c.size]
    centroids = np.array([c.mean() for c in occupied])
    # equal within float32 resolution counts as a tie (a value on a threshold)
    tolerance = 4 * np.finfo(np.float32).eps * float(np.abs(values[valid]).max())
    for own, cluster in enumerate(occupied):
        distances = np.abs(cluster[:, None] - centroids[None, :])
        assert (distances[:, own] <= distances.min(axis=1) + tolerance).all()
    # clusters are ordered intervals: far < mid < near
    for lower, upper in itertools.pairwise(occupied):
        assert lower.max() < upper.min()


@settings(max_examples=150, deadline=None)
@given(
    gt=hnp.arrays(
        np.float32,
        st.tuples(st.integers(1, 6), st.integers(1, 12)),
        elements=st.one_of(
            st.floats(0.5, 200.0, width=32), st.sampled_from([0.0, NAN, 1.0, 2.0, 3.0, 4.0, 7.0])
        ),
    )
)
def test_three_means_is_a_deterministic_fixed_point(gt: np.ndarray) -> None:
    gt[0, 0] = 5.0
    partition = Evaluator(criteria=("depth",)).reference(gt).partition
    check_three_means(gt, partition)
    again = Evaluator(criteria=("depth",)).reference(gt.copy()).partition
    for name in ("near", "mid", "far"):
        np.testing.assert_array_equal(partition.mask(name), again.mask(name))
