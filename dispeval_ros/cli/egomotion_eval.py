"""``eval --scene DRIVE --egomotion``: each method's temporal noise from the camera's motion.

No ground truth takes part: the estimate of frame ``t`` is moved into frame ``t + k`` by the
left camera's motion between them and compared with the estimate there
(:func:`~dispeval_ros.core.egomotion.egomotion_residual`; docs/method.md, "Temporal noise
without ground truth"). The motion is the KITTI raw drive's oxts poses carried to the camera
and looked up at the left images' stamps through the TransformHistory that a ``make-bag`` of the
drive carries on ``/tf`` (:func:`~dispeval_ros.io.kitti_raw.drive_motion`: one definition of
the camera's motion between two stamps); scenes without poses are refused. Pairs and gaps are
planned as for ``--temporal`` (:func:`~dispeval_ros.cli.temporal_eval.frame_runs`); a pair
whose pose is unusable or whose image stamp is outside the oxts samples is a problem line, the
others are scored. Criteria are the ground-truth-free ones of frame ``t``'s images, labelled
``gtfree:`` so they never pass for accuracy; a constant offset is fitted and removed per pair,
so this is noise, not bias.

Beside it, on the same pairs, each method's LiDAR drift between scans
(:func:`~dispeval_ros.core.lidar_drift.lidar_drift`: the change of its error against the
projected scans along the motion), by the criteria of frame ``t``'s scan labelled ``drift:``:
also temporal noise, never accuracy.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import reduce
from operator import add
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dispeval_ros.cli import common
from dispeval_ros.cli.output import plural, wrapped
from dispeval_ros.cli.summary import EGOMOTION_LABEL as LABEL
from dispeval_ros.cli.summary import EGOMOTION_MASKED as MASKED
from dispeval_ros.cli.summary import drift_text, fitted_tables
from dispeval_ros.cli.temporal_eval import Estimates, Runs, frame_runs
from dispeval_ros.core import criteria as crit
from dispeval_ros.core.camera import Camera
from dispeval_ros.core.egomotion import (
    EgoMotionOptions,
    MotionFrame,
    PinholeCamera,
    TemporalSums,
    egomotion_residual,
    prepare_frame,
)
from dispeval_ros.core.evaluator import Reference
from dispeval_ros.core.lidar_drift import (
    DriftOptions,
    DriftSums,
    coded_estimate,
    drift_entry,
    lidar_drift,
)
from dispeval_ros.core.measures import GT_FREE_PREFIX
from dispeval_ros.errors import ConfigurationError, DispevalError, ExtrapolationError

if TYPE_CHECKING:
    from dispeval_ros.io.kitti_raw import DriveMotion

OPTION = "--egomotion"
POSES = (
    "KITTI raw oxts (convertOxtsToPose) carried to the left camera by calib_imu_to_velo, "
    "interpolated at the left images' stamps (tf2's lookup, never extrapolated)"
)
UNITS = {"mean_abs": "px", "mean": "px", "rms": "px", "mean_abs_z": "m", "rms_z": "m"}
"""The units of the values (``bad_X``: % of the counted pixels)."""


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--egomotion`` and ``--egomotion-step K`` (off by default: nothing changes without it)."""
    parser.add_argument(
        OPTION,
        action="store_true",
        help="with --scene of a KITTI raw drive: also score each method's ego-motion residual "
        "(temporal noise without GT: frame t's estimate moved by the oxts motion into frame "
        "t + k, compared with the estimate there) and its LiDAR drift between scans (the "
        "change of its error against scan t's points moved into frame t + k; docs/method.md)",
    )
    parser.add_argument(
        "--egomotion-step",
        type=int,
        metavar="K",
        help="with --egomotion: pair frames K numbers apart (default 1)",
    )


def check_options(args: argparse.Namespace) -> None:
    """Refuse ``--egomotion`` where there is no sequence of frames (one line)."""
    if args.egomotion_step is not None and not args.egomotion:
        raise ConfigurationError("--egomotion-step K applies with --egomotion: give it too")
    if not args.egomotion:
        return
    if args.egomotion_step is not None and args.egomotion_step < 1:
        raise ConfigurationError(f"--egomotion-step must be at least 1, got {args.egomotion_step}")
    if args.protocol is not None:
        raise ConfigurationError(
            "--egomotion does not apply with --protocol: a benchmark's protocol scores frames "
            "one by one (drop one of them)"
        )
    if args.scene is None:
        raise ConfigurationError(
            "--egomotion scores the consecutive frames of a drive: give --scene DRIVE"
        )


def configuration(args: argparse.Namespace) -> dict[str, object]:
    """The provenance's entry (nothing without ``--egomotion``)."""
    return {"egomotion": {"step": args.egomotion_step or 1}} if args.egomotion else {}


@dataclass(frozen=True)
class EgoPlan:
    """The pairs to score, the drive's motion and, per frame of the plan, its index and images."""

    step: int
    runs: Runs
    motion: DriveMotion
    indices: list[int]
    """Each planned frame's index in the drive (in ``motion``)."""
    images: list[tuple[Path, Path]]
    principal: tuple[float, float]

    def between(self, first: int, second: int) -> np.ndarray:
        """The camera's motion from planned frame ``first`` to ``second`` (their image stamps)."""
        return self.motion.between(self.indices[first], self.indices[second])


def plan(
    args: argparse.Namespace, frames: Sequence[tuple[str | None, Estimates]]
) -> EgoPlan | None:
    """The pairs ``--egomotion`` scores (None without it); one line if there are none or no poses.

    ``frames``: each scored frame's name and estimates, in the scene's order.
    """
    from dispeval_ros.io.kitti_raw import drive_motion, is_raw_source, open_drive
    from dispeval_ros.offline.make_bag import BASE_FRAME, CAMERA_FRAME, ODOM_FRAME

    if not args.egomotion:
        return None
    if not is_raw_source(args.scene):
        raise ConfigurationError(
            f"--egomotion needs the camera's pose at every frame: {args.scene} has none (a "
            "KITTI raw drive has them in oxts/; for a recording use dispeval bag with /tf)"
        )
    step = args.egomotion_step or 1
    runs = frame_runs(OPTION, args, [(name, None, est) for name, est in frames], step)
    drive = open_drive(args.scene)
    where = {name: index for index, name in enumerate(drive.frames)}
    missing = [name for name in runs.frames if name not in where]
    if missing:
        raise ConfigurationError(f"--egomotion: frame {missing[0]} is not a frame of {args.scene}")
    motion = drive_motion(drive, fixed=ODOM_FRAME, base=BASE_FRAME, camera=CAMERA_FRAME)
    left, right = drive.streams["image_02"].files, drive.streams["image_03"].files
    indices = [where[name] for name in runs.frames]
    _, cx, cy = drive.calibration.ros_view()
    return EgoPlan(
        step,
        runs,
        motion,
        indices,
        [(left[i], right[i]) for i in indices],
        (cx, cy),
    )


@dataclass
class MethodMotion:
    """One method's residual over the scene: runs of frames, the pooled sums."""

    runs: list[list[str]]
    pairs: int
    pooled: TemporalSums | None


@dataclass
class EgoResult:
    """The ``--egomotion`` results of every method: for the tables, the JSON and ``--out``."""

    plan: EgoPlan
    options: EgoMotionOptions
    methods: dict[str, MethodMotion]
    problems: list[str]
    drift_options: DriftOptions
    drift: dict[str, DriftSums | None]
    """Each method's LiDAR drift pooled over its pairs (None: no pair scored)."""

    def to_dict(self) -> dict[str, object]:
        """The JSON ``egomotion`` entry (also stored with ``--out``)."""
        options = dataclasses.asdict(self.options)
        options["thresholds"] = list(self.options.thresholds)
        return {
            "measure": "egomotion",
            "label": LABEL,
            "poses": POSES,
            "step": self.plan.step,
            "options": options,
            "units": {**UNITS, **{f"bad_{t:g}": "%" for t in self.options.thresholds}},
            "frames": list(self.plan.runs.frames),
            "methods": {name: _method_dict(one) for name, one in self.methods.items()},
            "gaps": [gap.to_dict() for gap in self.plan.runs.gaps],
            "problems": self.problems,
            "lidar_drift": self._drift_dict(),
        }

    def _drift_dict(self) -> dict[str, object]:
        """The ``lidar_drift`` entry (:func:`~dispeval_ros.core.lidar_drift.drift_entry`)."""
        return drift_entry(self.drift_options, self.drift)

    def drift_text(self) -> str:
        """The drift table (:func:`~dispeval_ros.cli.summary.drift_text`)."""
        return drift_text(self.drift_options, self.drift)

    def text(self) -> str:
        """A table (criterion, method, counted pixels, residuals, mask counts), runs, gaps."""
        frames = self.plan.runs.frames
        step = "" if self.plan.step == 1 else f", frames {self.plan.step} apart"
        lines = [wrapped(f"ego-motion residual over frames {frames[0]}–{frames[-1]}{step} "
                         f"({LABEL}; missing estimates are masked, not interpolated)")]  # fmt: skip
        bad = [f"bad_{t:g}" for t in self.options.thresholds]
        header = [
            "criterion", "method", "n_residual", "mean_abs [px]", "rms [px]",
            *(f"{b} [%]" for b in bad), "mean_abs_z [m]", "rms_z [m]", *MASKED,
        ]  # fmt: skip
        rows: list[list[object]] = []
        scored = {m: one.pooled for m, one in self.methods.items() if one.pooled is not None}
        for criterion in next(iter(scored.values())).criteria if scored else ():
            for method, pooled in scored.items():
                one = pooled.summary(criterion)
                rows.append([
                    GT_FREE_PREFIX + criterion, method, int(one["n_residual"]), one["mean_abs"],
                    one["rms"], *(one[b] for b in bad), one["mean_abs_z"], one["rms_z"],
                    *(int(one[m]) for m in MASKED),
                ])  # fmt: skip
        lines.append(fitted_tables(header, rows, keep=2) if rows else "no pair was scored")
        for method, result in self.methods.items():
            runs = "; ".join(r[0] if len(r) == 1 else f"{r[0]}–{r[-1]}" for r in result.runs)
            text = f"{method}: {plural(len(result.runs), 'run')} ({runs}), {plural(result.pairs, 'pair')}"
            if result.pooled is not None:
                offsets = np.asarray(result.pooled.offsets)
                text += (
                    f"; offset removed per pair: median {np.median(offsets):.3f} px "
                    f"({offsets.min():.3f} to {offsets.max():.3f})"
                )
            lines.append(wrapped(text))
        lines += [wrapped("gap: " + gap.text()) for gap in self.plan.runs.gaps]
        lines += [wrapped("problem: " + problem) for problem in self.problems]
        lines.append("\n" + self.drift_text())
        return "\n".join(lines)


def _method_dict(one: MethodMotion) -> dict[str, object]:
    """A method's JSON: pairs, runs, the values and the pooled sums by ``gtfree:`` criterion."""
    pooled = one.pooled
    if pooled is None:
        return {"pairs": 0, "runs": one.runs, "criteria": None, "sums": None, "offsets": []}
    names = [GT_FREE_PREFIX + c for c in pooled.criteria]
    return {
        "pairs": one.pairs,
        "runs": one.runs,
        "criteria": {n: pooled.summary(c) for n, c in zip(names, pooled.criteria, strict=True)},
        "sums": {
            n: dict(zip(pooled.columns, row.tolist(), strict=True))
            for n, row in zip(names, pooled.sums, strict=True)
        },
        "offsets": list(pooled.offsets),
    }


def score(
    motion: EgoPlan | None,
    args: argparse.Namespace,
    camera: Camera | None,
    references: Mapping[str | None, Reference | None],
) -> EgoResult | None:
    """Score every planned pair of every method (None without ``--egomotion``).

    ``references``: each frame's projected scan and criteria, by frame name (the drift's).
    """
    from dispeval_ros.io import read_disparity
    from dispeval_ros.io.files import read_stereo_pair

    if motion is None:
        return None
    if camera is None:
        raise ConfigurationError("--egomotion needs the camera (f, B) of the scene")
    options = EgoMotionOptions()
    free = common.gt_free_from_args(args)
    pinhole = PinholeCamera(camera, *motion.principal)
    names, runs = motion.runs.frames, motion.runs.runs
    pairs = sorted(
        {p for method_runs in runs.values() for r in method_runs for p in itertools.pairwise(r)}
    )
    sums: dict[str, list[TemporalSums]] = {method: [] for method in runs}
    drift_options = DriftOptions.of_run(args.missing, args.delta)
    drift: dict[str, DriftSums | None] = dict.fromkeys(runs)
    coded: dict[tuple[str, int], np.ndarray] = {}
    images: dict[int, tuple[np.ndarray, crit.Partition]] = {}
    prepared: dict[tuple[str, int], MotionFrame] = {}
    problems: list[str] = []

    def image(index: int) -> tuple[np.ndarray, crit.Partition]:
        if index not in images:
            left, right = read_stereo_pair(*motion.images[index])
            images[index] = (left, free.pair(left, right).partition)
        return images[index]

    def frame(method: str, index: int) -> MotionFrame:
        if (method, index) not in prepared:
            estimate = read_disparity(motion.runs.files[method][index], scale=args.est_scale)
            prepared[method, index] = prepare_frame(estimate, image(index)[0], options=options)
        return prepared[method, index]

    for a, b in pairs:
        for index in [key for key in images if key < a]:
            del images[index]
        for key in [key for key in prepared if key[1] < a]:
            del prepared[key]
        for key in [key for key in coded if key[1] < a]:
            del coded[key]
        methods = [
            m for m, method_runs in runs.items() if any(_pairs(r, a, b) for r in method_runs)
        ]
        where = f"frames {names[a]} → {names[b]}"
        try:
            moved = motion.between(a, b)
        except DispevalError as error:
            problems.append(
                f"no pair {names[a]} → {names[b]} ({', '.join(methods)}): "
                f"{_which(error, motion, a, b)}{error}"
            )
            continue
        try:
            partition = image(a)[1]
            for method in methods:
                sums[method].append(
                    egomotion_residual(
                        frame(method, a), frame(method, b), moved, pinhole, partition, options
                    )
                )
                for index in (a, b):
                    if (method, index) not in coded:
                        coded[method, index] = coded_estimate(
                            frame(method, index).disparity, drift_options.missing
                        )
                reference, target = references[names[a]], references[names[b]]
                if reference is None or target is None:
                    continue  # pragma: no cover - every frame of a KITTI raw drive has its scan
                one = lidar_drift(
                    reference.gt, target.gt, coded[method, a], coded[method, b], moved,
                    pinhole, reference.partition, drift_options,
                )  # fmt: skip
                pooled = drift[method]
                drift[method] = one if pooled is None else pooled + one
        except DispevalError as error:
            raise type(error)(f"--egomotion, {where}: {error}") from None
    return EgoResult(
        motion,
        options,
        {method: _pooled(names, runs[method], sums[method]) for method in runs},
        problems,
        drift_options,
        drift,
    )


def _which(error: DispevalError, motion: EgoPlan, a: int, b: int) -> str:
    """Whose stamp an :class:`ExtrapolationError` is about (``frame N's left image: ``)."""
    if not isinstance(error, ExtrapolationError):
        return ""
    names, stamps = motion.runs.frames, motion.motion.stamps
    for index in (a, b):
        if stamps[motion.indices[index]] == error.stamp_ns:
            return f"frame {names[index]}'s left image (the oxts poses as /tf): "
    return ""  # pragma: no cover - the error is about one of the two stamps


def _pairs(run: list[int], a: int, b: int) -> bool:
    """Whether ``a → b`` is a pair of the run."""
    return any(x == a and y == b for x, y in itertools.pairwise(run))


def _pooled(names: Sequence[str], runs: list[list[int]], sums: list[TemporalSums]) -> MethodMotion:
    """A method's pairs pooled by their sums."""
    pooled = reduce(add, sums) if sums else None
    return MethodMotion([[names[i] for i in run] for run in runs], len(sums), pooled)
