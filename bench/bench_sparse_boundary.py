"""The boundary rule of sparse GT (``criteria.sparse_discontinuities``): time per map, checked.

Prints timings only (nothing is asserted about time) and checks every result against the
max/min-filter formulation of ``test/core/test_partition_reference.py``. Run:

    python bench/bench_sparse_boundary.py [--repeat N]

Maps: the KITTI LiDAR GT of ``kitti-lidar`` (when the shared data is present) and the synthetic
dense 1242×375 frame forced to the sparse rule (the worst case: every pixel valid). To compare
with another checkout, run it with that checkout first on ``PYTHONPATH``. The process is pinned
to one core.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from bench_scoring import DATA, pin_to_one_core, synthetic_frame, timed

import dispeval_ros
from dispeval_ros.core import criteria
from dispeval_ros.io import load_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))  # bag_support, ...
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test" / "core"))
from test_partition_reference import numpy_sparse_boundary

LIDAR_SCENES = ("kitti2015-with-velodyne", "stereo-rcnn-demo")


def main() -> None:
    """Time every map."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20, help="timed calls per map")
    args = parser.parse_args()
    pin_to_one_core()
    print(f"sparse-GT boundary ({dispeval_ros.__file__}; one core; median of {args.repeat})")
    maps = [("synthetic 1242×375, dense, sparse rule forced", synthetic_frame(1242, 375)[0])]
    for name in LIDAR_SCENES:
        folder = DATA / "kitti-lidar" / name
        if folder.is_dir():
            maps.append((f"KITTI LiDAR GT, {name}", load_scene(folder).gt))
    for label, gt in maps:
        valid = criteria.valid_ground_truth(gt)
        ours = criteria.sparse_discontinuities(gt, valid)
        same = np.array_equal(np.asarray(ours, bool), numpy_sparse_boundary(gt, valid))
        elapsed = timed(
            lambda gt=gt, valid=valid: criteria.sparse_discontinuities(gt, valid), args.repeat
        )
        print(
            f"  {label}: {int(valid.sum())} valid points, {int(np.count_nonzero(ours))} on the "
            f"boundary, {elapsed:7.2f} ms, same as the filter formulation: {same}"
        )


if __name__ == "__main__":
    main()
