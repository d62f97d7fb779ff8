"""Does vpe rank methods as the ground truth does? Kendall τ between vpe and bmp / mae.

Run (needs the shared data; ``DISPEVAL_DATA`` or ``../shared/data``)::

    python bench/bench_gtfree_rank.py [--scenes middeval3,kitti,kitti-lidar,eth3d,middlebury]

Every real scene with both images (MiddEval3 training Q, KITTI 2015, kitti-lidar with the
projected Velodyne scan as GT, ETH3D two-view, Middlebury 2001–2003) is matched by the five
OpenCV methods of the test bed (``testbed.methods.default_methods``). Per scene, the methods
are ranked by vpe (criterion ``gtfree:all``) and by the GT measures bmp (δ = 1 px) and mae
(criterion ``all``), all under the ``interpolate`` missing policy; τ is Kendall's τ-b of the
two rankings (1: the same order, 0: unrelated). ``vpe valid`` is vpe on valid estimates only
(``ignore``) against the GT measures as usual (``interpolate``): the inconsistent pairing.
Pooled: (concordant − discordant) / pairs over every within-scene pair of methods.
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dispeval_ros.core import Evaluator
from dispeval_ros.core.gtfree import GroundTruthFree, concordance, kendall_tau
from dispeval_ros.io import Scene, list_frames, read_stereo_pair
from dispeval_ros.testbed.methods import default_methods

DATA = Path(
    os.environ.get("DISPEVAL_DATA") or Path(__file__).resolve().parents[2] / "shared" / "data"
)
DATASETS: dict[str, Callable[[Path], list[Path]]] = {
    "middeval3": lambda root: sorted(
        p for p in (root / "middeval3-training-Q").iterdir() if p.is_dir()
    ),
    "kitti": lambda root: [root / "kitti-2015" / "000005_10"],
    "kitti-lidar": lambda root: [
        root / "kitti-lidar" / "kitti2015-with-velodyne",
        root / "kitti-lidar" / "stereo-rcnn-demo",
    ],
    "eth3d": lambda root: sorted(p for p in (root / "eth3d-two-view").iterdir() if p.is_dir()),
    "middlebury": lambda root: sorted(
        p for p in (root / "middlebury-2001-2003").iterdir() if p.is_dir()
    ),
}
COLUMNS = (("vpe", "bmp"), ("vpe", "mae"), ("vpe_valid", "mae"))


def scene_measures(scene: Scene) -> dict[str, dict[str, float]]:
    """Per method: vpe (interpolate), vpe on valid estimates only, bmp and mae on ``all``."""
    if scene.left is None or scene.right is None:
        raise SystemExit(f"{scene.source}: the scene has no left and right images")
    left, right = read_stereo_pair(scene.left, scene.right)
    gt_evaluator = Evaluator(("all",), ("bmp", "mae"), "interpolate")
    reference = gt_evaluator.reference(scene.gt, scene.camera, masks=scene.masks)
    consistent = GroundTruthFree(("all",), "interpolate")
    valid_only = GroundTruthFree(("all",), "ignore")
    pair = consistent.pair(left, right)
    measures = {}
    for method in default_methods(left.shape[1]):
        estimate = method.compute(left, right)
        gt_scores = gt_evaluator.score(reference, estimate)["all"]
        measures[method.name] = {
            "vpe": consistent.score(pair, estimate)["gtfree:all"]["vpe"],
            "vpe_valid": valid_only.score(pair, estimate)["gtfree:all"]["vpe"],
            "bmp": gt_scores["bmp"],
            "mae": gt_scores["mae"],
        }
    return measures


def main() -> None:
    """Print τ per scene, per data set and pooled."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=",".join(DATASETS), help="data sets, comma-separated")
    args = parser.parse_args()
    header = f"{'data set':<12} {'scene':<34}" + "".join(
        f" {f'τ({a}, {b})':>16}" for a, b in COLUMNS
    )
    print(header)
    pooled: dict[str, list[int]] = {}
    for dataset in args.scenes.split(","):
        totals = [[0, 0, 0] for _ in COLUMNS]
        for folder in DATASETS[dataset](DATA):
            for scene in list_frames(folder):
                measures = scene_measures(scene)
                values = {
                    name: [m[name] for m in measures.values()]
                    for name in ("vpe", "vpe_valid", "bmp", "mae")
                }
                cells = []
                for column, (a, b) in enumerate(COLUMNS):
                    cells.append(kendall_tau(values[a], values[b]))
                    concordant, discordant, *_ = concordance(values[a], values[b])
                    pairs = len(measures) * (len(measures) - 1) // 2
                    totals[column][0] += concordant
                    totals[column][1] += discordant
                    totals[column][2] += pairs
                print(
                    f"{dataset:<12} {scene.name[:34]:<34}" + "".join(f" {c:16.2f}" for c in cells),
                    flush=True,
                )
        summary = [(c - d) / n if n else math.nan for c, d, n in totals]
        print(f"{dataset:<12} {'(pooled)':<34}" + "".join(f" {c:16.2f}" for c in summary))
        pooled[dataset] = [x for t in totals for x in t]
    everything = np.sum(list(pooled.values()), axis=0).reshape(len(COLUMNS), 3)
    print(
        f"{'all':<12} {'(pooled over every scene)':<34}"
        + "".join(f" {(c - d) / n:16.2f}" for c, d, n in everything)
    )


if __name__ == "__main__":
    main()
