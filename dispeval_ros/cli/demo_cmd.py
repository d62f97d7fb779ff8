"""``dispeval demo``: the whole job on the bundled example (no downloads, no arguments).

By default it replays the sample bag (synthetic driving, three or more OpenCV methods)
through the offline pipeline: join, score, store, summarise. ``--single-scene`` evaluates one
synthetic scene in memory instead.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

from dispeval_ros.cli.output import print_json, table, wrapped
from dispeval_ros.cli.progress import Progress
from dispeval_ros.cli.summary import (
    fitted_tables,
    measure_header,
    models_text,
    run_summary_text,
    scores_text,
)
from dispeval_ros.core import Evaluator, Scores, evaluate_models
from dispeval_ros.core.objectives import default_objective_measures, objective_matrix
from dispeval_ros.summary import RunSummary

if TYPE_CHECKING:
    from dispeval_ros.io.store import ResultsStore
    from dispeval_ros.stream.core import CoreConfig

HELP = "run the whole evaluation on the bundled sample bag (or one synthetic scene)"
SHOWN = ("n", "density", "bmp", "mae", "rmse", "d1", "sze", "sze_mean", "bmpre")
ROBOT_SHOWN = ("bmp", "mae", "d1")
"""Measures shown side by side for the dense GT and the LiDAR GT (robot mode)."""
ROBOT_DEPTH = ("mae_z", "irmse")
"""Depth-domain measures shown for the LiDAR GT (robot mode)."""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``demo``."""
    parser = subparsers.add_parser(
        "demo",
        help=HELP,
        description=HELP + ". The sample bag holds a few seconds of synthetic driving with exact "
        "GT and OpenCV StereoBM/StereoSGBM variants published as DisparityImages, and a "
        "simulated LiDAR: robot mode scores the same frames against the LiDAR's projected scan "
        "(/lidar/points with /tf_static) beside the dense GT.",
    )
    parser.add_argument("--out", type=Path, help="results folder (default: a new temporary folder)")
    parser.add_argument(
        "--single-scene",
        action="store_true",
        help="evaluate one synthetic scene (ground plane and boxes) in memory instead",
    )
    parser.add_argument("--seed", type=int, default=0, help="single scene: seed (default 0)")
    parser.add_argument("--width", type=int, default=640, help="single scene: width (default 640)")
    parser.add_argument(
        "--height", type=int, default=400, help="single scene: height (default 400)"
    )
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Replay the sample bag, or score the single scene."""
    return single_scene(args) if args.single_scene else replay_sample(args)


def replay_sample(args: argparse.Namespace) -> int:
    """The offline pipeline on the sample bag: what ``dispeval bag`` does on a recording."""
    from dispeval_ros.io.bags import BagSource
    from dispeval_ros.io.store import ResultsStore
    from dispeval_ros.offline.make_bag import (
        GT_TOPIC,
        LEFT_IMAGE,
        LEFT_INFO,
        RIGHT_IMAGE,
        RIGHT_INFO,
    )
    from dispeval_ros.offline.records import record_bag_provenance, write_run_files
    from dispeval_ros.offline.sample import find_sample_bag, make_sample_bag
    from dispeval_ros.stream.core import CoreConfig

    started = time.perf_counter()
    out = args.out or Path(tempfile.mkdtemp(prefix="dispeval-demo-"))
    bag = find_sample_bag()
    if bag is None:  # not installed with the package: make it (a few seconds)
        bag = make_sample_bag(out / "sample_drive")
    with BagSource(bag) as source:
        methods = {
            topic.split("/")[2]: topic
            for topic, info in source.topics.items()
            if info.msgtype == "stereo_msgs/msg/DisparityImage"
        }
    config = CoreConfig(
        methods=methods,
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
        left_image_topic=LEFT_IMAGE,
        right_image_topic=RIGHT_IMAGE,
    )
    record = {
        "bag": str(bag),
        "methods": methods,
        "criteria": list(config.criteria),
        "gt_topic": GT_TOPIC,  # recorded so that `dispeval report --bag` can re-score frames
        "camera_info": [LEFT_INFO, RIGHT_INFO],
        "images": [LEFT_IMAGE, RIGHT_IMAGE],
    }
    progress = Progress("dispeval demo: dense GT", enabled=not args.json)
    with ResultsStore.create(out, record) as store:
        _evaluate_sample(bag, config, store, progress)
        provenance = record_bag_provenance(store, [bag], record, config)
        files = write_run_files(store, out, provenance)  # frames.csv, summary.json as `bag`
        rows, summary = files.rows, files.summary
        problems = store.problems()
        # -- the interactive report of these results (as `dispeval report OUT --bag BAG`)
        from dispeval_ros.report.data import build_report_data, error_thumbnails
        from dispeval_ros.report.html import write_report

        report = out / "report.html"
        thumbnails = error_thumbnails(store, [bag], config=config)
        write_report(build_report_data(store, title="dispeval demo", thumbnails=thumbnails), report)
        # -- end of the report
    robot = robot_mode(
        bag, methods, out / "robot", Progress("dispeval demo: robot mode (LiDAR GT)", not args.json)
    )
    if args.json:
        document = {"results": str(out), "bag": str(bag), "report": str(report)}
        if robot is not None:
            document["robot"] = robot.to_dict()  # type: ignore[assignment]
        document["gt_free_agreement"] = gt_free_agreement(summary)  # type: ignore[assignment]
        print_json({**document, **summary.to_dict(), "provenance": provenance})
        return 0
    print(
        wrapped(
            f"sample bag: {bag}\nmethods: {', '.join(methods)}; criteria: all, visibility, depth"
        )
    )
    print(run_summary_text(summary, problems))
    print("\n" + gt_free_text(summary))
    if robot is not None:
        print("\n" + robot_text(summary, robot))
    print(
        wrapped(
            f"\nresults: {out / 'results.sqlite'} ({rows} rows, also {out / 'frames.csv'}, "
            f"{out / 'summary.json'})"
        )
    )
    print(f"report: {report}")
    print(f"(done in {time.perf_counter() - started:.1f} s)")
    return 0


def robot_mode(
    bag: Path, methods: dict[str, str], out: Path, progress: Progress
) -> RunSummary | None:
    """The same frames scored against the sample's LiDAR (None if the bag has no LiDAR)."""
    from dispeval_ros.io.bags import BagSource
    from dispeval_ros.io.store import ResultsStore
    from dispeval_ros.offline.make_bag import CLOUD_TOPIC, LEFT_INFO, RIGHT_INFO
    from dispeval_ros.stream.core import CoreConfig
    from dispeval_ros.summary import summarize

    with BagSource(bag) as source:
        if CLOUD_TOPIC not in source.topics:
            return None
    config = CoreConfig(
        methods=methods,
        gt_topic=CLOUD_TOPIC,
        gt_kind="pointcloud",
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
    )
    with ResultsStore.create(out, {"bag": str(bag), **config.as_record()}) as store:
        _evaluate_sample(bag, config, store, progress)
        store.export_csv(out / "frames.csv")
        return summarize(store)


def _evaluate_sample(
    bag: Path, config: CoreConfig, store: ResultsStore, progress: Progress
) -> None:
    """The sample bag through the offline pipeline, in 1 s slices, with a progress line."""
    from dispeval_ros.offline.bag_eval import evaluate_bags

    evaluate_bags(
        [bag],
        config,
        store,
        slice_ns=1_000_000_000,
        progress=lambda done, total, r: progress.update(done, total, r.frames),
    )


def robot_text(dense: RunSummary, lidar: RunSummary) -> str:
    """Per method, criterion ``all``: the dense GT's and the LiDAR GT's scores side by side.

    Split by columns (:func:`fitted_tables`) to fit the terminal; the depth-domain measures
    are the LiDAR's only (a dense map's depth errors are in the tables above).
    """
    dense_scores = dense.sequences[0].scores
    lidar_scores = lidar.sequences[0].scores
    header = ["method", "n dense", "n LiDAR"]
    for measure in ROBOT_SHOWN:
        header += [f"{measure_header(measure)} dense", f"{measure_header(measure)} LiDAR"]
    header += [f"{measure_header(m)} LiDAR" for m in ROBOT_DEPTH]
    rows: list[list[object]] = []
    for method, scores in dense_scores.items():
        if method not in lidar_scores:
            continue
        a, b = scores["all"], lidar_scores[method]["all"]
        row: list[object] = [method, int(a["n"]), int(b["n"])]
        for measure in ROBOT_SHOWN:
            row += [a[measure], b[measure]]
        rows.append(row + [b[m] for m in ROBOT_DEPTH])
    ranking = [m for m, _ in sorted(lidar_scores.items(), key=lambda item: item[1]["all"]["mae"])]
    return (
        wrapped(
            "robot mode: the same frames against the simulated LiDAR (/lidar/points, extrinsic "
            "from /tf_static, parallax filter 7,0.1), criterion all, summed over the common "
            "frames"
        )
        + "\n"
        + fitted_tables(header, rows, keep=1)
        + f"\nby LiDAR mae: {', '.join(ranking)}"
    )


AGREEMENT_GT = ("bmp", "mae")
"""GT measures the view-prediction error's ranking is compared with."""


def gt_free_agreement(summary: RunSummary) -> dict[str, float]:
    """Kendall τ between the methods' vpe and each GT measure (sequence totals, all pixels)."""
    from dispeval_ros.core.gtfree import kendall_tau

    scores = summary.sequences[0].scores
    vpe = [s["gtfree:all"]["vpe"] for s in scores.values()]
    return {
        f"tau_vpe_{name}": kendall_tau(vpe, [s["all"][name] for s in scores.values()])
        for name in AGREEMENT_GT
    }


def gt_free_text(summary: RunSummary) -> str:
    """Per method the GT measures beside the ground-truth-free ones, and their agreement."""
    scores = summary.sequences[0].scores
    header = ["method", "bmp [%]", "mae [px]", "vpe all", "vpe textured", "vpe textureless"]
    rows = [
        [
            method,
            s["all"]["bmp"],
            s["all"]["mae"],
            s["gtfree:all"]["vpe"],
            s["gtfree:textured"]["vpe"],
            s["gtfree:textureless"]["vpe"],
        ]
        for method, s in sorted(scores.items(), key=lambda item: item[1]["gtfree:all"]["vpe"])
    ]
    agreement = gt_free_agreement(summary)
    return (
        wrapped(
            "ground-truth-free measures beside the GT ones (vpe in grey levels, from the left and "
            "right images only; criterion all, summed over the common frames), by vpe:"
        )
        + "\n"
        + table(header, rows)
        + "\nagreement with the GT ranking (Kendall τ over the methods): "
        + ", ".join(f"vpe vs {name} {agreement[f'tau_vpe_{name}']:+.2f}" for name in AGREEMENT_GT)
    )


def single_scene(args: argparse.Namespace) -> int:
    """One synthetic scene, every method scored in memory."""
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
    objectives = default_objective_measures(evaluator.measures)
    methods, names, matrix = objective_matrix(results, objectives)
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
        "partition: "
        + ", ".join(f"{k} {v}" for k, v in reference.partition.counts().items())
        + "\n"
    )
    print(scores_text(results, [m for m in SHOWN if m != "n"]))
    print("\n" + models_text(model, names))
    print(f"\n(done in {time.perf_counter() - started:.1f} s)")
    return 0
