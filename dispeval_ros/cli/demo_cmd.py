"""``dispeval demo``: the whole job on an embedded example (no downloads, no arguments)."""

from __future__ import annotations

import argparse
import time

from dispeval_ros.cli.output import print_json
from dispeval_ros.cli.summary import models_text, scores_text
from dispeval_ros.core import Evaluator, Scores, evaluate_models
from dispeval_ros.core.objectives import objective_matrix

HELP = "run the whole evaluation on a synthetic stereo scene made in code"
SHOWN = ("n", "density", "bmp", "mae", "rmse", "d1", "sze", "sze_mean", "bmpre")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``demo``."""
    parser = subparsers.add_parser(
        "demo",
        help=HELP,
        description=HELP + ": a textured ground plane and boxes with exact left and right GT, "
        "OpenCV StereoBM and StereoSGBM variants, criteria all + visibility + depth, A* Groups.",
    )
    parser.add_argument("--seed", type=int, default=0, help="scene seed (default 0)")
    parser.add_argument("--width", type=int, default=640, help="image width (default 640)")
    parser.add_argument("--height", type=int, default=400, help="image height (default 400)")
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Make the scene, run the methods, score, compare, print."""
    from dispeval_ros.testbed import default_methods, make_scene

    started = time.perf_counter()
    frame = make_scene(width=args.width, height=args.height, seed=args.seed)
    evaluator = Evaluator(criteria=("all", "visibility", "depth"))
    # The right-view GT is exact here, so occlusion comes from the left-right check.
    reference = evaluator.reference(frame.gt_left, frame.camera, gt_right=frame.gt_right)
    results: dict[str, Scores] = {}
    for method in default_methods(args.width):
        estimate = method.compute(frame.left, frame.right)
        results[method.name] = evaluator.score(
            reference, estimate, est_range=(method.min_disparity, float("inf"))
        )
    objectives_from = ["sze", "bmpre"]
    methods, names, matrix = objective_matrix(results, objectives_from)
    model = evaluate_models(methods, matrix)
    if args.json:
        print_json(
            {
                "frames": [
                    {"method": name, "criteria": s.to_dict()} for name, s in results.items()
                ],
                "objectives": names,
                "models": model.to_dict(),
            }
        )
        return 0
    camera = frame.camera
    print(
        f"synthetic scene {args.width}×{args.height} (seed {args.seed}): ground plane and boxes, "
        f"f = {camera.f:g} px, B = {camera.baseline:g} m; {len(results)} OpenCV stereo methods\n"
        f"partition: "
        + ", ".join(f"{k} {v}" for k, v in reference.partition.counts().items())
        + "\n"
    )
    print(scores_text(results, [m for m in SHOWN if m != "n"]))
    print("\n" + models_text(model, names))
    print(f"\n(done in {time.perf_counter() - started:.1f} s)")
    return 0
