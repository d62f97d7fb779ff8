"""The two independent interpolations of reference.py agree (each checks the other)."""

from __future__ import annotations

import numpy as np
from reference import kitti_devkit_interpolation, kitti_fill


def test_vectorized_fill_equals_the_devkit_port() -> None:
    """kitti_fill (index arithmetic) and the devkit's loops are one definition, two ways."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        shape = tuple(rng.integers(1, 9, 2))
        est = rng.uniform(0.5, 40.0, shape)
        valid = rng.random(shape) < rng.uniform(0.0, 1.0)
        missing = np.where(valid, est, 0.0)
        np.testing.assert_array_equal(
            kitti_fill(missing, valid), kitti_devkit_interpolation(missing)
        )
