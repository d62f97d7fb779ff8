"""``dispeval make-bag``: write a test-bed bag from a dataset folder or a synthetic drive."""

from __future__ import annotations

import argparse
import itertools
import math
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dispeval_ros.cli.output import plural, print_json, wrapped
from dispeval_ros.cli.progress import Progress
from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.offline.static_bag import DEFAULT_SENSOR_NOISE

if TYPE_CHECKING:
    from dispeval_ros.offline.make_bag import Estimates

HELP = "write a bag with stereo images, CameraInfo, exact GT and OpenCV methods' DisparityImages"
STORAGES = ("rosbag2-mcap", "rosbag2-sqlite3", "mcap")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``make-bag``."""
    parser = subparsers.add_parser(
        "make-bag",
        help=HELP,
        description=HELP + ". Source: a synthetic driving sequence made in code (default) or a "
        "dataset scene folder (--scene). Disparities are published as ROS 2 stereo_image_proc does.",
    )
    parser.add_argument(
        "output", type=Path, help="bag to write (a folder for rosbag2, a .mcap file for mcap)"
    )
    parser.add_argument(
        "--storage",
        choices=STORAGES,
        default="rosbag2-mcap",
        help="rosbag2 with MCAP or sqlite3 storage (metadata version 8, Humble reads it), "
        "or a plain MCAP file (default rosbag2-mcap)",
    )
    parser.add_argument(
        "--scene",
        type=Path,
        help="dataset scene folder instead of the synthetic drive: any layout 'eval --scene' "
        "reads, or a KITTI raw drive DATE/DRIVE_sync (or a DATE folder holding one drive)",
    )
    parser.add_argument(
        "--est",
        action="append",
        default=[],
        metavar="NAME=DIR",
        help="add external predictions as DisparityImages on /stereo/NAME/disparity: DIR holds "
        "one map per frame named by the frame's number (0000000003.png or 000003.png = frame "
        "3; 16-bit PNG value/256, PFM, NPY); repeatable",
    )
    add_drive_options(parser)
    parser.add_argument(
        "--no-lidar",
        action="store_true",
        help="synthetic drive without its simulated LiDAR (32 beams, ±15°, 0.2° azimuth, "
        "0.4 m above and 0.3 m behind the left camera; published on /lidar/points with "
        "/tf_static). A kitti-lidar --scene always publishes its scans",
    )
    parser.add_argument(
        "--compress",
        action="store_true",
        help="zstd-compress MCAP chunks (smaller, slower to read; rosbag2 records uncompressed by default)",
    )
    parser.add_argument(
        "--static",
        type=int,
        metavar="N",
        help="a static camera: the first frame (of the drive or --scene) recorded N times at "
        "--fps, each with its own sensor noise, the methods run on every frame (for "
        "dispeval bag --flicker)",
    )
    parser.add_argument(
        "--sensor-noise",
        type=int,
        default=DEFAULT_SENSOR_NOISE,
        metavar="G",
        help="with --static: uniform integer noise of ±G grey levels per pixel, image and frame "
        f"(default {DEFAULT_SENSOR_NOISE})",
    )
    parser.add_argument(
        "--confidence",
        action="store_true",
        help="also each OpenCV method's 8-bit left-right consistency confidence (mono8, higher "
        "is better) on /stereo/NAME/confidence, for dispeval bag --confidence NAME=TOPIC",
    )
    parser.add_argument("--json", action="store_true", help="print what was written as JSON")
    parser.set_defaults(run=run)


MAX_SIDE = 8192
"""Largest synthetic image side (px): 8192×8192 float32 maps are already 256 MB a frame."""


def add_drive_options(parser: argparse.ArgumentParser) -> None:
    """The synthetic drive's options (``make-bag``, ``make-scene``): frames, rate, size, seed."""
    parser.add_argument("--frames", type=int, default=30, help="synthetic frames (default 30)")
    parser.add_argument("--fps", type=float, default=10.0, help="synthetic frame rate (default 10)")
    parser.add_argument(
        "--width", type=int, default=620, help="synthetic image width (default 620)"
    )
    parser.add_argument(
        "--height", type=int, default=188, help="synthetic image height (default 188)"
    )
    parser.add_argument("--seed", type=int, default=0, help="synthetic world seed (default 0)")


def check_drive_options(args: argparse.Namespace) -> None:
    """Refuse a drive that cannot be made (one line)."""
    if not (args.frames >= 1 and math.isfinite(args.fps) and args.fps > 0):
        raise ConfigurationError(
            f"need --frames ≥ 1 and --fps > 0, got {args.frames}, {args.fps:g}"
        )
    if not (64 <= args.width <= MAX_SIDE and 32 <= args.height <= MAX_SIDE):
        raise ConfigurationError(
            f"--width must be in 64..{MAX_SIDE} and --height in 32..{MAX_SIDE}, got "
            f"{args.width}×{args.height}"
        )


def _remove(path: Path) -> None:
    """Delete a bag this command started (a rosbag2 folder or an MCAP file)."""
    if path.is_dir():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def run(args: argparse.Namespace) -> int:
    """Render or read the frames, run the methods, write the bag."""
    from dispeval_ros.offline.make_bag import dataset_frames, synthetic_frames, write_bag
    from dispeval_ros.testbed.lidar import LidarModel

    check_drive_options(args)
    if args.output.exists():
        raise InputError(f"{args.output} exists; remove it or choose another path")
    estimates = _estimates(args.est)
    if args.scene is not None:
        frames: Iterator[Any] = dataset_frames(args.scene)
        total = None
    else:
        lidar = None if args.no_lidar else LidarModel()
        frames = synthetic_frames(args.frames, args.width, args.height, args.fps, args.seed, lidar)
        total = args.frames
    # The first frame before the bag: a scene that cannot be read leaves no file behind.
    first = next(frames, None)
    if first is None:
        raise InputError(f"{args.scene}: no frame to write")
    if args.static is not None:
        from dispeval_ros.offline.static_bag import static_frames

        frames = static_frames(first, args.static, args.fps, args.sensor_noise, args.seed)
        first, total = next(frames), args.static
    elif args.sensor_noise != DEFAULT_SENSOR_NOISE:
        raise ConfigurationError("--sensor-noise G goes with --static N")
    progress = Progress("dispeval make-bag: writing", enabled=not args.json, unit="frames")
    try:
        summary = write_bag(
            args.output,
            itertools.chain([first], frames),
            storage=args.storage,
            fps=args.fps,
            compress=args.compress,
            progress=(lambda n: progress.update(n, total, n)) if total else None,
            estimates=estimates,
            confidence=args.confidence,
        )
    except BaseException:  # a later frame failed, or Ctrl-C: no half-written bag
        _remove(args.output)
        raise
    if args.json:
        print_json(summary)
    else:
        methods = summary["methods"]
        assert isinstance(methods, dict)
        count = summary["frames"]
        assert isinstance(count, int)
        print(f"wrote {plural(count, 'frame')} to {args.output} ({args.storage})")
        print(wrapped(f"ground truth: {_ground_truth(summary)}"))
        print(wrapped("methods: " + ", ".join(f"{k}={v}" for k, v in methods.items())))
        confidences = summary.get("confidences")
        if isinstance(confidences, dict):
            print(
                wrapped(
                    "confidence maps (preset "
                    f"{summary['confidence_preset']}): "
                    + ", ".join(f"{k}={v}" for k, v in confidences.items())
                )
            )
        if "gt_cloud" in summary:
            motion = (
                f"; ego-motion on {summary['tf']} (odom → base_link)" if "tf" in summary else ""
            )
            print(wrapped(f"LiDAR: {summary['gt_cloud']} with {summary['tf_static']}{motion}"))
            offset = summary["cloud_offset_ms"]
            assert isinstance(offset, float)
            if offset > 0:
                print(
                    wrapped(
                        f"the scans are stamped up to {offset:.2f} ms from the left images: give "
                        f"dispeval bag --tolerance {math.ceil(offset)} (ms) or more"
                    )
                )
        elif "tf" in summary:
            print(
                wrapped(f"ego-motion: {summary['tf']} (odom → base_link), {summary['tf_static']}")
            )
    return 0


def _ground_truth(summary: dict[str, object]) -> str:
    """The GT line: its topic and what it is, or how to score a bag that has none."""
    if summary["gt"] is None:
        cloud = summary.get("gt_cloud")
        reference = f": its scans are the reference (dispeval bag --gt-cloud {cloud})"
        return "no GT map" + (reference if cloud else "")
    source = summary.get("gt_source")
    return f"{summary['gt']}" + (f" = {source}" if source else "")


def _estimates(specs: list[str]) -> list[Estimates]:
    """``--est NAME=DIR`` options, indexed and checked before any frame is read."""
    from dispeval_ros.offline.make_bag import estimates_from
    from dispeval_ros.testbed import default_methods

    reserved = {method.name for method in default_methods(640)}
    estimates: list[Estimates] = []
    for spec in specs:
        name, sep, folder = spec.partition("=")
        if not (sep and name and folder):
            raise ConfigurationError(f"--est must be NAME=DIR, got {spec!r}")
        if any(name == known.name for known in estimates):
            raise ConfigurationError(f"--est {name} is given twice")
        estimates.append(estimates_from(name, Path(folder), reserved))
    return estimates
