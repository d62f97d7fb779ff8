"""``dispeval eval``: score one or more estimated maps against a ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dispeval_ros.cli import common, protocol_eval
from dispeval_ros.cli.output import print_json
from dispeval_ros.cli.summary import models_text, scores_text
from dispeval_ros.core import Camera, Evaluator, Scores, evaluate_models
from dispeval_ros.core.gtfree import GT_FREE_PREFIX, GT_FREE_SCORED, is_gt_free, joined
from dispeval_ros.core.measures import DEFAULT_MEASURES, DEPTH_MEASURES
from dispeval_ros.errors import ConfigurationError, DispevalError

if TYPE_CHECKING:
    from dispeval_ros.io.scenes import Scene

HELP = "score estimated disparity maps against ground truth, by criterion"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``eval``."""
    parser = subparsers.add_parser(
        "eval",
        help=HELP,
        description=HELP + ". With several estimates, also ranks the "
        "methods with A* Groups over the SZE and BMPRE objectives of every criterion.",
    )
    source = parser.add_argument_group("inputs")
    source.add_argument(
        "--gt",
        type=Path,
        help="ground-truth disparity (PFM, PNG, NPY/NPZ); may be left out with --left-image and "
        "--right-image (ground-truth-free measures only)",
    )
    source.add_argument(
        "--est",
        action="append",
        required=True,
        metavar="[NAME=]FILE",
        help="an estimated disparity map; repeat for several methods (name defaults to the file stem)",
    )
    source.add_argument(
        "--scene", type=Path, help="a dataset scene folder: GT, masks and camera from it"
    )
    source.add_argument(
        "--gt-scale", type=float, help="divide GT PNG values by this (16-bit default 256)"
    )
    source.add_argument("--est-scale", type=float, help="divide estimate PNG values by this")
    source.add_argument(
        "--gt-right", type=Path, help="right-view GT (for occlusion by left-right check)"
    )
    source.add_argument(
        "--mask",
        action="append",
        default=[],
        metavar="NAME=FILE",
        help="official mask: all=, nonocc= or disc= (255 = inside)",
    )
    source.add_argument(
        "--roi", type=Path, help="region-of-interest mask or label image (criterion set 'roi')"
    )
    source.add_argument(
        "--roi-labels",
        metavar="V=NAME,...",
        help="name the label image's values, e.g. 1=road,2=vehicle",
    )
    free = parser.add_argument_group("ground-truth-free measures (vpe, lrc)")
    free.add_argument("--left-image", type=Path, help="the left rectified image (8 bit)")
    free.add_argument("--right-image", type=Path, help="the right rectified image (8 bit)")
    free.add_argument(
        "--gt-free",
        action="store_true",
        help="with --scene: score vpe on the scene's own left and right images",
    )
    free.add_argument(
        "--est-right",
        action="append",
        default=[],
        metavar="NAME=FILE",
        help="a method's right-view disparity, for its left-right inconsistency (lrc)",
    )
    common.add_gt_free_options(free)
    common.add_evaluation_options(parser)
    common.add_camera_options(parser)
    protocol_eval.add_options(parser)
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(run=run)


def _named(spec: str) -> tuple[str, Path]:
    if "=" in spec:
        name, _, path = spec.partition("=")
        if not name:
            raise ConfigurationError(f"empty method name in --est '{spec}'")
        return name, Path(path)
    return Path(spec).stem, Path(spec)


def _roi_names(text: str | None) -> dict[int, str] | None:
    if not text:
        return None
    names = {}
    for part in common.comma_list(text):
        value, _, name = part.partition("=")
        if not value.strip().isdigit() or not name:
            raise ConfigurationError(f"--roi-labels entry '{part}' is not VALUE=NAME (e.g. 1=road)")
        names[int(value)] = name
    return names


def _image_files(args: argparse.Namespace, scene: Scene | None) -> tuple[Path, Path] | None:
    """The left and right image files of the ground-truth-free measures, if any."""
    if (args.left_image is None) != (args.right_image is None):
        raise ConfigurationError("give both --left-image and --right-image, or neither")
    if args.left_image is not None:
        return args.left_image, args.right_image
    if args.gt_free:
        if scene is None:
            raise ConfigurationError("--gt-free reads a scene's images: give --scene DIR")
        if scene.left is None or scene.right is None:
            raise ConfigurationError(f"{args.scene}: the scene has no left and right images")
        return scene.left, scene.right
    return None


def _scene_files(scene: Scene) -> list[Path]:
    """The files of a scene folder the evaluation reads (its images are not scored)."""
    images = {scene.left, scene.right}
    return sorted(p for p in scene.source.iterdir() if p.is_file() and p not in images)


def _provenance(
    args: argparse.Namespace, evaluator: Evaluator, camera: Camera | None, inputs: list[Path]
) -> dict[str, object]:
    """Version, the options that define the numbers (and their hash), sha256 of every input."""
    from dispeval_ros.core.provenance import provenance_record
    from dispeval_ros.io.provenance import files_sha256

    configuration = {
        "command": "eval",
        "criteria": list(evaluator.criteria),
        "measures": list(evaluator.measures),
        "missing": evaluator.missing,
        "delta": evaluator.delta,
        "mu": evaluator.mu,
        "depth_ranges": args.depth_ranges,
        "roi_labels": args.roi_labels,
        "gt_scale": args.gt_scale,
        "est_scale": args.est_scale,
        "estimates": list(args.est),
        "camera": None
        if camera is None
        else {"f": camera.f, "baseline": camera.baseline, "doffs": camera.doffs},
    }
    return provenance_record(configuration, {"files": files_sha256(inputs)})


def run(args: argparse.Namespace) -> int:
    """Read the inputs, score every estimate, print tables (and models) or JSON."""
    from dispeval_ros.io import load_scene, read_disparity, read_mask

    if args.protocol is not None:
        return protocol_eval.run(args)
    if args.roi_labels and args.roi is None:
        raise ConfigurationError("--roi-labels names the classes of --roi FILE: give --roi too")
    common.positive_option(args.gt_scale, "--gt-scale")
    common.positive_option(args.est_scale, "--est-scale")
    camera: Camera | None = None
    masks: dict[str, np.ndarray] = {}
    gt_right = None
    inputs: list[Path] = []
    scene = None
    if args.scene is not None:
        scene = load_scene(args.scene)
        inputs += _scene_files(scene)
        gt, camera, masks, gt_right = scene.gt, scene.camera, dict(scene.masks), scene.gt_right
        gt_name = str(args.scene)
        if args.gt is not None:
            raise ConfigurationError("give either --scene or --gt, not both")
        if scene.layout == "kitti-lidar":  # LiDAR GT: metric depth ranges, depth measures
            args.depth_ranges = args.depth_ranges or "0-10,10-30,30-inf"
            if args.measures is None:
                args.measures = [*DEFAULT_MEASURES, *DEPTH_MEASURES]
    elif args.gt is not None:
        gt = read_disparity(args.gt, scale=args.gt_scale)
        gt_name = str(args.gt)
        inputs.append(args.gt)
    elif args.left_image is None:
        raise ConfigurationError(
            "give the ground truth with --gt FILE or --scene DIR, or the rectified images with "
            "--left-image FILE --right-image FILE for the ground-truth-free measures"
        )
    else:
        gt, gt_name = None, ""
    pair_files = _image_files(args, scene)
    camera = common.camera_from_args(args) or camera
    for spec in args.mask:
        name, path = _named(spec)
        masks[name] = read_mask(path) == 255
        inputs.append(path)
    if args.gt_right is not None:
        gt_right = read_disparity(args.gt_right, scale=args.gt_scale)
    roi = read_mask(args.roi) if args.roi is not None else None
    inputs += [p for p in (args.gt_right, args.roi, args.calib) if p is not None]

    roi_names = _roi_names(args.roi_labels)
    evaluator = common.evaluator_from_args(args, roi_names)
    reference = None
    if gt is not None:
        try:
            reference = evaluator.reference(gt, camera, masks=masks, gt_right=gt_right, roi=roi)
        except DispevalError as error:
            raise type(error)(f"{gt_name}: {error}") from None
    free, pair = None, None
    if pair_files is not None:
        from dispeval_ros.io.files import read_stereo_pair

        free = common.gt_free_from_args(args, roi_names)
        pair = free.pair(*read_stereo_pair(*pair_files), roi=roi)
        inputs += list(pair_files)
    right_estimates = dict(_named(spec) for spec in args.est_right)
    if right_estimates and free is None:
        raise ConfigurationError("--est-right needs the images (--left-image/--right-image)")
    results: dict[str, Scores] = {}
    for spec in args.est:
        name, path = _named(spec)
        if name in results:
            raise ConfigurationError(
                f"two estimates are named '{name}'; use NAME=FILE to tell them apart"
            )
        current = path
        try:
            estimate = read_disparity(path, scale=args.est_scale)
            inputs.append(path)
            gt_scores = None if reference is None else evaluator.score(reference, estimate)
            free_scores = None
            if free is not None and pair is not None:
                right_file = right_estimates.pop(name, None)
                est_right = None
                if right_file is not None:
                    current = right_file
                    est_right = read_disparity(right_file, scale=args.est_scale)
                    inputs.append(right_file)
                free_scores = free.score(pair, estimate, est_right=est_right)
            results[name] = joined(gt_scores, free_scores)
        except DispevalError as error:
            message = str(error)
            raise type(error)(
                message if str(current) in message else f"{current}: {message}"
            ) from None
    if right_estimates:
        raise ConfigurationError(
            f"--est-right names no --est method: {', '.join(sorted(right_estimates))}"
        )

    measures = list(evaluator.measures) if reference is not None else []
    first = next(iter(results.values()))
    model = None
    no_model = ""
    objectives = (
        common.model_objectives(results, measures, args.gt_free_objectives)
        if len(results) > 1
        else None
    )
    if len(results) > 1 and objectives is None:
        no_model = (
            "no A* Groups: the legacy criteria overlap (a point counts in several), so the models "
            "need a partition; add --criteria all (or visibility, depth) to compare the methods"
        )
    elif objectives is not None:
        methods, names, matrix = objectives
        model = (names, evaluate_models(methods, matrix))
    if args.json:
        document: dict[str, object] = {
            "frames": [{"method": name, "criteria": s.to_dict()} for name, s in results.items()],
            "camera": None
            if camera is None
            else {"f": camera.f, "baseline": camera.baseline, "doffs": camera.doffs},
            "sze_relative": camera is None,
            "missing": evaluator.missing,
            "overlapping": list(first.overlapping),
            "partition": {
                **(reference.partition.counts() if reference is not None else {}),
                **(
                    {GT_FREE_PREFIX + c: n for c, n in pair.partition.counts().items()}
                    if pair is not None
                    else {}
                ),
            },
            "gt_free": None
            if pair is None
            else {
                "criteria": [c for c in first.criteria if is_gt_free(c)],
                "measures": list(GT_FREE_SCORED),
                "in_objectives": bool(args.gt_free_objectives) or reference is None,
            },
        }
        if model is not None:
            document["objectives"] = model[0]
            document["models"] = model[1].to_dict()
        elif no_model:
            document["models"] = None
            document["models_note"] = no_model
        document["provenance"] = _provenance(args, evaluator, camera, inputs)
        print_json(document)
        return 0
    if reference is not None:
        print(
            f"ground truth: {gt_name}  ({reference.shape[1]}×{reference.shape[0]}, "
            f"{int(np.count_nonzero(reference.partition.cells >= 0))} valid points)"
        )
    else:
        print("ground truth: none — ground-truth-free measures only")
    if pair_files is not None and pair is not None:
        print(
            f"images: {pair_files[0]}, {pair_files[1]}  ({pair.shape[1]}×{pair.shape[0]}); "
            "gtfree: criteria are scored without ground truth"
        )
    print(
        "camera: "
        + (
            "none — SZE is relative (f·B = 1)"
            if camera is None
            else f"f = {camera.f:g} px, B = {camera.baseline:g} {camera.unit}, doffs = {camera.doffs:g} px"
        )
    )
    print(f"missing estimates: {evaluator.missing}\n")
    print(scores_text(results, first.measures, first.overlapping, first.relative))
    if model is not None:
        print("\n" + models_text(model[1], model[0]))
    elif no_model:
        print("\n" + no_model)
    return 0
