"""``dispeval make-scene``: the test-bed's synthetic drive as a scene folder (a KITTI raw drive).

``eval --scene DRIVE --temporal`` and ``--egomotion`` score consecutive frames with their GT
and the camera's poses; this writes the synthetic drive in the layout that carries both, so
they can be seen without any dataset (:mod:`~dispeval_ros.offline.make_drive`).
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from dispeval_ros.cli.make_bag_cmd import add_drive_options, check_drive_options
from dispeval_ros.cli.output import plural, print_json, wrapped
from dispeval_ros.cli.progress import Progress

HELP = "write the synthetic drive as a KITTI raw drive: images, LiDAR, poses, exact GT, estimates"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``make-scene``."""
    parser = subparsers.add_parser(
        "make-scene",
        help=HELP,
        description=HELP + ". The drive (DAY/DRIVE_sync with the day's calibration) has the "
        "rendered pairs, the simulated LiDAR's scans, oxts poses that are the rig's exact motion, "
        "the exact GT map of every frame in gt/disp_occ_0 (KITTI's 16-bit PNG, value/256; what "
        "eval --scene scores against, --gt-source scan: the LiDAR) and the test-bed's OpenCV "
        "methods in OUT/estimates, so that eval --scene DRIVE --temporal --egomotion runs.",
    )
    parser.add_argument("output", type=Path, help="folder to write (must not exist)")
    add_drive_options(parser)
    parser.add_argument(
        "--no-traffic",
        action="store_true",
        help="leave the moving vehicles out: every surface is static, so the ego-motion "
        "residual of the true disparity is its exactness alone",
    )
    parser.add_argument("--json", action="store_true", help="print what was written as JSON")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Render the drive, run the methods, write the folder; say how to score it."""
    from dispeval_ros.offline.make_drive import write_drive

    check_drive_options(args)
    progress = Progress("dispeval make-scene: writing", enabled=not args.json, unit="frames")
    summary = write_drive(
        args.output,
        args.frames,
        args.width,
        args.height,
        args.fps,
        args.seed,
        traffic=not args.no_traffic,
        progress=lambda n: progress.update(n, args.frames, n),
    )
    if args.json:
        print_json(summary)
        return 0
    drive, gt, estimates = summary["drive"], summary["gt"], summary["estimates"]
    assert isinstance(estimates, dict)
    traffic = "" if args.no_traffic else ", with moving traffic"
    print(f"wrote {plural(args.frames, 'frame')} of the synthetic drive{traffic} to {args.output}")
    print(wrapped(f"drive: {drive} (a KITTI raw drive: exact motion in oxts/)"))
    print(wrapped(f"ground truth: {gt} (exact; KITTI 16-bit PNG, value/256)"))
    print(wrapped("estimates: " + ", ".join(f"{k}={v}" for k, v in estimates.items())))
    first = next(iter(estimates))
    command = [
        "dispeval", "eval", "--scene", str(drive), "--est", f"true={gt}",
        "--est", f"{first}={estimates[first]}", "--temporal", "--egomotion",
    ]  # fmt: skip
    print(wrapped("score it: " + shlex.join(command)))
    return 0
