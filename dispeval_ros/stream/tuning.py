"""A tuning sweep's plan and its scenes, without a matcher: what ``tune`` and ``tune --node`` share.

Each ``--scene`` folder is a sequence (its frames are stamps 0, 1, … as ``eval --out`` numbers
them); a unit is one sequence and a chunk of consecutive configurations. Whether the maps come
from OpenCV in this process (:mod:`dispeval_ros.offline.tuning.sweep`) or from a running ROS 2
node (:mod:`dispeval_ros.ros.tune_node`), the frames, their references, the units and the
database's sequences are these, so both store the same kind of database and a resumed run skips
the same units.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dispeval_ros.core import Evaluator, Reference
from dispeval_ros.core.camera import Camera
from dispeval_ros.errors import ConfigurationError, DispevalError, InputError
from dispeval_ros.io.scenes import Scene
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.io.store.naming import bag_location, sequence_names
from dispeval_ros.testbed.node_parameters import Configuration

NODE_TIMEOUT = 5.0
"""``tune --node``: seconds to wait for the node's map of one frame (then it counts as dropped)."""


@dataclass(frozen=True)
class TuneUnit:
    """One sequence (scene folder) and a chunk of configurations (on some of its frames)."""

    scene: int
    sequence: str
    name: str
    configurations: tuple[Configuration, ...]
    stamps: tuple[int, ...] | None = None
    """The frames scored (None: every frame; a multi-fidelity round scores only its new ones)."""

    def frames_of(self, frames: Sequence[SceneFrame]) -> list[SceneFrame]:
        """The unit's frames among the scene's."""
        if self.stamps is None:
            return list(frames)
        wanted = set(self.stamps)
        return [frame for frame in frames if frame.stamp in wanted]


@dataclass
class SceneFrame:
    """One frame of a scene, ready to score: its images and its reference."""

    stamp: int
    frame: str
    gt_source: str
    left: np.ndarray
    right: np.ndarray
    reference: Reference
    files: list[Path] = field(default_factory=list)
    camera: Camera | None = None
    """The scene's camera (a node is sent it as its CameraInfo pair)."""


def load_scene(
    folder: Path, evaluator: Evaluator, listed: Sequence[Scene] | None = None
) -> list[SceneFrame]:
    """Every frame of a scene folder: images (8-bit grey) and reference; one line if unusable.

    ``listed``: the folder's frames as :func:`~dispeval_ros.io.list_frames` returned them.
    """
    from dispeval_ros.io import list_frames
    from dispeval_ros.io.files import read_stereo_pair
    from dispeval_ros.io.scene_frames import frame_truth

    frames = []
    for stamp, scene in enumerate(list_frames(folder) if listed is None else listed):
        truth = frame_truth(folder, scene, "auto")
        if scene.left is None or scene.right is None:
            raise InputError(f"{folder}: frame {truth.frame} has no left and right images to match")
        left, right = read_stereo_pair(scene.left, scene.right)
        gt_right = scene.gt_right if truth.source == "official" else None
        try:
            reference = evaluator.reference(
                truth.gt, scene.camera, masks=truth.masks, gt_right=gt_right
            )
        except DispevalError as error:
            raise type(error)(f"{folder}, frame {truth.frame}: {error}") from None
        files = [p for p in scene.source.iterdir() if p.is_file()] if scene.source.is_dir() else []
        frames.append(
            SceneFrame(
                stamp,
                truth.frame,
                truth.source,
                left,
                right,
                reference,
                sorted(files),
                scene.camera,
            )
        )
    return frames


def check_fits(
    configurations: Sequence[Configuration],
    scenes: Sequence[Path],
    loaded: Mapping[int, list[SceneFrame]],
) -> None:
    """Refuse (one line) an SGBM configuration whose search does not fit a scene's images.

    OpenCV's SGBM raises unless ``width − (min_disparity + disparity_range)`` exceeds half the
    window; found here, before anything is written, rather than in the middle of the run.
    """
    for index, folder in enumerate(scenes):
        for width in sorted({frame.left.shape[1] for frame in loaded[index]}):
            for configuration in configurations:
                method = configuration.method
                reach = method.min_disparity + method.num_disparities
                if method.kind == "sgbm" and width - reach <= method.block_size // 2:
                    raise ConfigurationError(
                        f"{folder}: images {width} px wide are too narrow for configuration "
                        f"{configuration.name}: OpenCV's SGBM needs width − (min_disparity + "
                        f"disparity_range) = {width - reach} > correlation_window_size / 2"
                    )


def sequence_info(folder: Path, frames: Sequence[SceneFrame]) -> dict[str, object]:
    """A sequence's metadata in the database: its frames and their ground-truth sources."""
    return {
        "frames": [{"stamp": f.stamp, "frame": f.frame, "gt_source": f.gt_source} for f in frames],
        "scene": str(folder),
    }


def plan(
    sequences: Sequence[str],
    configurations: Sequence[Configuration],
    chunk: int,
    stamps: Sequence[Sequence[int]] | None = None,
    prefix: str = "",
) -> list[TuneUnit]:
    """The units of a sweep: per sequence, consecutive chunks of ``chunk`` configurations.

    ``stamps``: per sequence, the frames to score (None: all; a sequence with none has no
    unit); ``prefix`` starts the units' names (a multi-fidelity round's names are its own).
    """
    units = []
    for index, sequence in enumerate(sequences):
        chosen = None if stamps is None else tuple(stamps[index])
        if chosen is not None and not chosen:
            continue
        for start in range(0, len(configurations), chunk):
            part = tuple(configurations[start : start + chunk])
            units.append(TuneUnit(index, sequence, f"{prefix}{start // chunk:06d}", part, chosen))
    return units


@dataclass
class SweepReport:
    """What a run did: units written now, units a previous run had written, method-frames."""

    units_done: int = 0
    units_skipped: int = 0
    frames: int = 0
    dropped: int = 0
    """Frames a node sent no map of in time (``tune --node``; counted, not scored)."""


def set_sequences(
    store: ResultsStore, scenes: Sequence[Path], loaded: Mapping[int, list[SceneFrame]]
) -> list[str]:
    """Name the scenes' sequences and record them (source and frames) in ``store``."""
    sequences = sequence_names(list(scenes))
    for index, (folder, sequence) in enumerate(zip(scenes, sequences, strict=True)):
        store.set_sequence(sequence, bag_location(folder), sequence_info(folder, loaded[index]))
    return sequences


def start_sweep(
    store: ResultsStore,
    scenes: Sequence[Path],
    loaded: Mapping[int, list[SceneFrame]],
    configurations: Sequence[Configuration],
    chunk: int,
) -> tuple[list[TuneUnit], SweepReport]:
    """Record the sequences in ``store``; the units still to do and a report counting the rest."""
    sequences = set_sequences(store, scenes, loaded)
    return units_to_do(store, plan(sequences, configurations, chunk))


def units_to_do(
    store: ResultsStore, units: Sequence[TuneUnit]
) -> tuple[list[TuneUnit], SweepReport]:
    """The ``units`` not done in ``store`` yet (in plan order), and a report counting the rest."""
    done = {sequence: store.done_units(sequence) for sequence in {u.sequence for u in units}}
    todo = [unit for unit in units if unit.name not in done[unit.sequence]]
    return todo, SweepReport(units_skipped=len(units) - len(todo))
