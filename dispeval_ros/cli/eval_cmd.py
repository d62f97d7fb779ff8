"""``dispeval eval``: score one or more estimated maps against a ground truth."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dispeval_ros.cli import (
    common,
    confidence_eval,
    egomotion_eval,
    flicker_eval,
    protocol_eval,
    temporal_eval,
)
from dispeval_ros.cli.output import print_json
from dispeval_ros.cli.summary import models_text, scores_text
from dispeval_ros.core import Camera, Evaluator, ModelResult, Reference, Scores, evaluate_models
from dispeval_ros.core.gtfree import (
    GT_FREE_PREFIX,
    GT_FREE_SCORED,
    ImagePair,
    is_gt_free,
    joined,
)
from dispeval_ros.core.masks import inside_mask
from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.io.scene_frames import GT_SOURCES

if TYPE_CHECKING:
    from dispeval_ros.core.confidence import ConfidenceSums
    from dispeval_ros.io.scenes import Scene

HELP = "score estimated disparity maps against ground truth, by criterion"
RESULTS = ("temporal", "egomotion", "flicker")
"""The sequence results beside the frames' scores, as the JSON and --out name them."""


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
        "--scene",
        type=Path,
        help="a dataset scene folder: GT, masks and camera from it. In a folder of several "
        "frames each estimate is scored against the frame it names: a file FRAME.png (or "
        ".pfm, .npy, ...), or NAME=DIR holding one such file per frame",
    )
    source.add_argument(
        "--frame",
        help="with --scene: score only this frame (e.g. 000043); any file given is for it",
    )
    source.add_argument(
        "--gt-source",
        choices=GT_SOURCES,
        help="with --scene: the official GT map or the projected LiDAR scan of a frame that has "
        "both (default auto: the official map where the frame has one, else the scan)",
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
    temporal_eval.add_options(parser)
    egomotion_eval.add_options(parser)
    flicker_eval.add_options(parser)
    confidence_eval.add_options(parser)
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="also write the results folder 'dispeval bag' writes (results.sqlite, frames.csv, "
        "summary.json; the scene is one sequence, its frames numbered 0, 1, …) for 'dispeval "
        "report DIR' and 'dispeval models DIR'",
    )
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
    args: argparse.Namespace, evaluator: Evaluator, scored: list[_Scored], inputs: list[Path]
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
        "camera": _camera_dict(scored[0].frame.camera),
    }
    if args.gt is not None:
        configuration["gt"] = str(args.gt)
    if args.scene is not None:
        configuration["scene"] = str(args.scene)
        configuration["gt_source"] = args.gt_source or "auto"
        configuration["frames"] = [
            {"frame": s.frame.frame, "gt_source": s.frame.gt_source} for s in scored
        ]
    if args.temporal is not None:
        configuration["temporal"] = args.temporal
    configuration.update(egomotion_eval.configuration(args))
    configuration.update(flicker_eval.configuration(args))
    configuration.update(confidence_eval.configuration(args))
    return provenance_record(configuration, {"files": files_sha256(inputs)})


@dataclass
class _Frame:
    """One ground truth and the estimates scored against it."""

    label: str
    """Where the GT came from, as the text output names it."""
    gt: np.ndarray | None
    camera: Camera | None
    masks: dict[str, np.ndarray]
    gt_right: np.ndarray | None
    images: tuple[Path, Path] | None
    estimates: list[tuple[str, Path]]
    inputs: list[Path]
    frame: str | None = None
    """The scene frame (``None`` for ``--gt`` or images only)."""
    gt_source: str | None = None
    """``official`` or ``scan`` for a scene frame."""


@dataclass
class _Scored:
    """One frame's results: scores per method, the GT and images as prepared, the models."""

    frame: _Frame
    results: dict[str, Scores]
    reference: Reference | None
    pair: ImagePair | None
    model: tuple[list[str], ModelResult] | None
    no_model: str
    confidence: dict[str, ConfidenceSums]
    """Each method's confidence sums (``--confidence``)."""


def _scene_frames(args: argparse.Namespace, estimates: list[tuple[str, Path]]) -> list[_Frame]:
    """Every frame of ``--scene`` an estimate is for (or ``--frame``), with its chosen GT."""
    from dispeval_ros.io import list_frames
    from dispeval_ros.io.scene_frames import attribute, frame_truth

    scenes = list_frames(args.scene)
    common.scene_defaults(args, scenes[0].layout)
    frames = []
    for scene, assigned in attribute(args.scene, scenes, estimates, args.frame):
        truth = frame_truth(args.scene, scene, args.gt_source or "auto")
        label = (
            f"{args.scene}, frame {truth.frame}: {truth.describe()}"
            if len(scenes) > 1
            else f"{args.scene} ({truth.describe()})"
        )
        frames.append(
            _Frame(
                label,
                truth.gt,
                scene.camera,
                truth.masks,
                scene.gt_right if truth.source == "official" else None,
                _image_files(args, scene),
                assigned,
                [*_scene_files(scene), *truth.files],
                truth.frame,
                truth.source,
            )
        )
    return frames


def _files_frame(args: argparse.Namespace, estimates: list[tuple[str, Path]]) -> _Frame:
    """The one frame of ``--gt FILE`` (or of the images alone)."""
    from dispeval_ros.io import read_disparity

    images = _image_files(args, None)
    if args.gt is not None:
        gt = read_disparity(args.gt, scale=args.gt_scale)
        return _Frame(str(args.gt), gt, None, {}, None, images, estimates, [args.gt])
    if args.left_image is None:
        raise ConfigurationError(
            "give the ground truth with --gt FILE or --scene DIR, or the rectified images with "
            "--left-image FILE --right-image FILE for the ground-truth-free measures"
        )
    return _Frame("", None, None, {}, None, images, estimates, [])


def _score(
    args: argparse.Namespace,
    evaluator: Evaluator,
    frame: _Frame,
    roi: np.ndarray | None,
    roi_names: dict[int, str] | None,
    confidences: dict[str, tuple[Path, Any]],
) -> _Scored:
    """Score every estimate of one frame against its GT (and images); the models if several."""
    from dispeval_ros.io import read_disparity

    reference = None
    if frame.gt is not None:
        try:
            reference = evaluator.reference(
                frame.gt, frame.camera, masks=frame.masks, gt_right=frame.gt_right, roi=roi
            )
        except DispevalError as error:
            raise type(error)(f"{frame.label}: {error}") from None
    free, pair = None, None
    if frame.images is not None:
        from dispeval_ros.io.files import read_stereo_pair

        free = common.gt_free_from_args(args, roi_names)
        pair = free.pair(*read_stereo_pair(*frame.images), roi=roi)
        frame.inputs += list(frame.images)
    right_estimates = dict(_named(spec) for spec in args.est_right)
    if right_estimates and free is None:
        raise ConfigurationError("--est-right needs the images (--left-image/--right-image)")
    if confidences and reference is None:
        raise ConfigurationError(
            f"{confidence_eval.OPTION} needs the ground truth (--gt or --scene)"
        )
    results: dict[str, Scores] = {}
    rated: dict[str, ConfidenceSums] = {}
    for name, path in frame.estimates:
        if name in results:
            raise ConfigurationError(
                f"two estimates are named '{name}'; use NAME=FILE to tell them apart"
            )
        current = path
        try:
            estimate = read_disparity(path, scale=args.est_scale)
            frame.inputs.append(path)
            gt_scores = None if reference is None else evaluator.score(reference, estimate)
            if name in confidences and reference is not None:
                current, preset = confidences[name]
                rated[name] = confidence_eval.score_one(
                    evaluator, preset, reference, estimate, current
                )
                frame.inputs.append(current)
                current = path
            free_scores = None
            if free is not None and pair is not None:
                right_file = right_estimates.pop(name, None)
                est_right = None
                if right_file is not None:
                    current = right_file
                    est_right = read_disparity(right_file, scale=args.est_scale)
                    frame.inputs.append(right_file)
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
    return _Scored(frame, results, reference, pair, model, no_model, rated)


def _camera_dict(camera: Camera | None) -> dict[str, float] | None:
    return (
        None
        if camera is None
        else {"f": camera.f, "baseline": camera.baseline, "doffs": camera.doffs}
    )


def _entries(scored: _Scored) -> list[dict[str, object]]:
    """The JSON ``frames`` entries of one frame: a method's scores, with the frame and source."""
    where = {"frame": scored.frame.frame, "gt_source": scored.frame.gt_source}
    return [
        {"method": name, "criteria": s.to_dict(), **where} for name, s in scored.results.items()
    ]


def _document(args: argparse.Namespace, evaluator: Evaluator, scored: _Scored) -> dict[str, object]:
    """One frame's JSON (the shape of a single-frame run, without the provenance)."""
    frame, reference, pair = scored.frame, scored.reference, scored.pair
    first = next(iter(scored.results.values()))
    document: dict[str, object] = {
        "frames": _entries(scored),
        "camera": _camera_dict(frame.camera),
        "sze_relative": frame.camera is None,
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
        "frame": frame.frame,
        "gt_source": frame.gt_source,
        "ground_truth": frame.label or None,
    }
    if scored.model is not None:
        document["objectives"] = scored.model[0]
        document["models"] = scored.model[1].to_dict()
    elif scored.no_model:
        document["models"] = None
        document["models_note"] = scored.no_model
    return document


def _write_out(
    args: argparse.Namespace,
    scored: list[_Scored],
    provenance: dict[str, object],
    extras: dict[str, object],
) -> str:
    """Write ``--out`` as a bag run's results folder; the line saying what was written."""
    from dispeval_ros.core.records import FrameScores
    from dispeval_ros.io.store import FRAMES_CSV, RESULTS_FILE, SUMMARY_JSON
    from dispeval_ros.offline.bag_eval import bag_location, sequence_names
    from dispeval_ros.offline.records import write_scored_folder

    where = Path(args.scene or args.gt or args.left_image)
    sequence = sequence_names([where])[0]
    frames = [
        FrameScores(sequence, stamp, method, scores)
        for stamp, one in enumerate(scored)
        for method, scores in one.results.items()
    ]
    info = {
        "frames": [
            {"stamp": stamp, "frame": one.frame.frame, "gt_source": one.frame.gt_source}
            for stamp, one in enumerate(scored)
        ],
        "camera": _camera_dict(scored[0].frame.camera),
        **extras,
    }
    files = write_scored_folder(args.out, sequence, bag_location(where), info, frames, provenance)
    return (
        f"results: {args.out / RESULTS_FILE} ({files.rows} rows; {args.out / FRAMES_CSV}, "
        f"{args.out / SUMMARY_JSON})"
    )


def _text(evaluator: Evaluator, scored: _Scored) -> str:
    """One frame's human report: where the GT came from, the camera, tables, models."""
    frame, reference, pair = scored.frame, scored.reference, scored.pair
    lines = []
    if reference is not None:
        lines.append(
            f"ground truth: {frame.label}  ({reference.shape[1]}×{reference.shape[0]}, "
            f"{int(np.count_nonzero(reference.partition.cells >= 0))} valid points)"
        )
    else:
        lines.append("ground truth: none — ground-truth-free measures only")
    if frame.images is not None and pair is not None:
        lines.append(
            f"images: {frame.images[0]}, {frame.images[1]}  ({pair.shape[1]}×{pair.shape[0]}); "
            "gtfree: criteria are scored without ground truth"
        )
    camera = frame.camera
    lines.append(
        "camera: "
        + (
            "none — SZE is relative (f·B = 1)"
            if camera is None
            else f"f = {camera.f:g} px, B = {camera.baseline:g} {camera.unit}, doffs = {camera.doffs:g} px"
        )
    )
    lines.append(f"missing estimates: {evaluator.missing}\n")
    first = next(iter(scored.results.values()))
    lines.append(scores_text(scored.results, first.measures, first.overlapping, first.relative))
    if scored.model is not None:
        lines.append("\n" + models_text(scored.model[1], scored.model[0]))
    elif scored.no_model:
        lines.append("\n" + scored.no_model)
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Read the inputs, score every estimate of every frame, print tables (and models) or JSON."""
    from dispeval_ros.io import read_disparity, read_mask

    scene_only = [o for o, v in (("--frame", args.frame), ("--gt-source", args.gt_source)) if v]
    temporal_eval.check_options(args)
    egomotion_eval.check_options(args)
    flicker_eval.check_options(args)
    confidence_eval.check_options(args)
    if args.protocol is not None:
        if args.out is not None:
            raise ConfigurationError(
                "--out does not apply with --protocol: a results folder holds the sums of "
                "dispeval's measures, not a benchmark's official numbers (drop one of them)"
            )
        if scene_only:
            raise ConfigurationError(
                f"{scene_only[0]} chooses a --scene frame's GT for the measures; --protocol "
                "reads the benchmark's own GT of every frame"
            )
        return protocol_eval.run(args)
    if args.out is not None:
        from dispeval_ros.offline.records import check_new_results_folder

        check_new_results_folder(args.out)
    if args.roi_labels and args.roi is None:
        raise ConfigurationError("--roi-labels names the classes of --roi FILE: give --roi too")
    common.positive_option(args.gt_scale, "--gt-scale")
    common.positive_option(args.est_scale, "--est-scale")
    estimates = [_named(spec) for spec in args.est]
    if args.scene is not None:
        if args.gt is not None:
            raise ConfigurationError("give either --scene or --gt, not both")
        frames = _scene_frames(args, estimates)
    elif scene_only:
        raise ConfigurationError(
            f"{scene_only[0]} chooses among the frames of a scene folder: give --scene DIR"
        )
    else:
        frames = [_files_frame(args, estimates)]
    pairs = temporal_eval.plan(args, [(f.frame, f.gt_source, f.estimates) for f in frames])
    motion = egomotion_eval.plan(args, [(f.frame, f.estimates) for f in frames])
    if len(frames) > 1:
        one_file = [
            option
            for option, value in (
                ("--mask", args.mask),
                ("--gt-right", args.gt_right),
                ("--roi", args.roi),
                ("--left-image", args.left_image),
                ("--est-right", args.est_right),
                (confidence_eval.OPTION, args.confidence),
            )
            if value
        ]
        if one_file:
            raise ConfigurationError(
                f"{one_file[0]} is for one frame, but {len(frames)} frames are scored "
                f"({', '.join(str(f.frame) for f in frames)}): choose one with --frame"
            )
    camera = common.camera_from_args(args)
    shared: list[Path] = []
    masks = {}
    for spec in args.mask:
        name, path = _named(spec)
        masks[name] = inside_mask(f"{path} (--mask {name})", read_mask(path))
        shared.append(path)
    gt_right = None if args.gt_right is None else read_disparity(args.gt_right, scale=args.gt_scale)
    roi = read_mask(args.roi) if args.roi is not None else None
    shared += [p for p in (args.gt_right, args.roi, args.calib) if p is not None]
    for frame in frames:
        frame.camera = camera or frame.camera
        frame.masks.update(masks)
        frame.gt_right = frame.gt_right if gt_right is None else gt_right
        frame.inputs += shared

    roi_names = _roi_names(args.roi_labels)
    evaluator = common.evaluator_from_args(args, roi_names)
    confidences = confidence_eval.plan(args, [name for name, _ in estimates])
    scored = [_score(args, evaluator, frame, roi, roi_names, confidences) for frame in frames]
    references = [s.reference for s in scored]
    temporal = temporal_eval.score(pairs, evaluator, references, args.est_scale)
    by_frame = {f.frame: r for f, r in zip(frames, references, strict=True)}
    ego = egomotion_eval.score(motion, args, frames[0].camera, by_frame)
    flicker = flicker_eval.score(args, scored)
    done = [(n, r) for n, r in zip(RESULTS, (temporal, ego, flicker), strict=True) if r is not None]
    result: dict[str, object] = {name: one.to_dict() for name, one in done}
    from dispeval_ros.core.confidence import by_method

    pooled = by_method({n: [s.confidence[n] for s in scored if n in s.confidence]
                        for n in confidences})  # fmt: skip
    rated = confidence_eval.summaries(pooled)
    drawn = confidence_eval.plot(args, pooled)
    inputs = [path for s in scored for path in s.frame.inputs]
    wanted = args.json or args.out is not None  # the text alone hashes nothing
    provenance = _provenance(args, evaluator, scored, inputs) if wanted else {}
    written = None if args.out is None else _write_out(args, scored, provenance, result)
    if args.json:
        documents = [_document(args, evaluator, s) for s in scored]
        if len(documents) == 1:
            document = documents[0]
        else:
            document = {
                "scene": str(args.scene),
                "frames": [entry for s in scored for entry in _entries(s)],
                "per_frame": documents,
            }
        document.update(result)
        if rated:
            document["confidence"] = rated
        document["provenance"] = provenance
        print_json(document)
        return 0
    print("\n\n".join(_text(evaluator, s) for s in scored))
    for _, one in done:
        print("\n" + one.text())
    if rated:
        print("\n" + confidence_eval.text(rated))
    if drawn is not None:
        print(f"\n{drawn}")
    if written is not None:
        print(f"\n{written}")
    return 0
