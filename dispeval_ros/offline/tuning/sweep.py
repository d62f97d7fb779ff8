"""Run a sweep: every configuration's maps of every scene frame, scored into one database.

Each ``--scene`` folder is a sequence (its frames are stamps 0, 1, … as ``eval --out``
numbers them); a unit is one sequence and a chunk of consecutive configurations. A unit
computes the chunk's OpenCV maps on the sequence's frames and scores each one with the
:class:`~dispeval_ros.core.Evaluator` against the frame's reference, exactly as ``dispeval
eval`` scores a map read from a file (the same ground truth, masks and camera of the scene).
Units run here or on ``--jobs`` worker processes and are written in plan order, one
transaction each, so any number of workers gives the same database, a killed run loses at most
the units in flight and a resumed one skips the units that are done.
"""

from __future__ import annotations

import multiprocessing
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, CancelledError, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dispeval_ros.core import Evaluator, Reference
from dispeval_ros.core.records import FrameScores, MatchCounts
from dispeval_ros.errors import ConfigurationError, DispevalError, InputError
from dispeval_ros.io.scenes import Scene
from dispeval_ros.io.store import PreparedUnit, ResultsStore, prepare_unit
from dispeval_ros.offline.bag_eval import bag_location, sequence_names
from dispeval_ros.offline.executors import end_with_the_parent
from dispeval_ros.offline.tuning.space import Configuration

DEFAULT_CHUNK = 8
"""Configurations per unit of work (stored with the run: a resume cuts the same units)."""
WINDOW_PER_WORKER = 2
"""Units submitted ahead of the oldest one not yet written, per worker (bounds memory)."""
EVALUATOR_FIELDS = ("criteria", "measures", "missing", "delta", "mu", "depth_ranges")
"""The :class:`Evaluator` settings a worker rebuilds its evaluator from."""


@dataclass(frozen=True)
class Setup:
    """What every worker needs, sent once: the scene folders and the evaluator's settings."""

    scenes: tuple[Path, ...]
    evaluator: dict[str, Any]


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


def evaluator_settings(evaluator: Evaluator) -> dict[str, Any]:
    """The settings that rebuild ``evaluator`` in a worker (an Evaluator does not pickle)."""
    return {name: getattr(evaluator, name) for name in EVALUATOR_FIELDS}


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
            SceneFrame(stamp, truth.frame, truth.source, left, right, reference, sorted(files))
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


class _Worker:
    """A process's evaluator and loaded scenes (each loaded once, on its first unit)."""

    def __init__(self, setup: Setup, loaded: Mapping[int, list[SceneFrame]] | None = None):
        self.setup = setup
        self.evaluator = Evaluator(**setup.evaluator)
        self.frames: dict[int, list[SceneFrame]] = dict(loaded or {})

    def run(self, unit: TuneUnit) -> PreparedUnit:
        """Compute, score and prepare the rows of one unit."""
        import cv2

        frames = self.frames.get(unit.scene)
        if frames is None:
            frames = self.frames[unit.scene] = load_scene(
                self.setup.scenes[unit.scene], self.evaluator
            )
        frames = unit.frames_of(frames)
        scored = []
        for frame in frames:
            for configuration in unit.configurations:
                try:
                    estimate = configuration.method.compute(frame.left, frame.right)
                except cv2.error as error:
                    message = " ".join(str(error.err or error).split())
                    raise InputError(
                        f"{self.setup.scenes[unit.scene]}, frame {frame.frame}: OpenCV refused "
                        f"configuration {configuration.name} ({message})"
                    ) from None
                scores = self.evaluator.score(frame.reference, estimate)
                scored.append(FrameScores(unit.sequence, frame.stamp, configuration.name, scores))
        counts = {c.name: MatchCounts(len(frames), 0, 0, 0) for c in unit.configurations}
        return prepare_unit(unit.sequence, unit.name, scored, counts=counts)


_process_worker: dict[str, _Worker] = {}
"""A pool process's worker (set once when it starts)."""
_dask_workers: dict[str, _Worker] = {}
"""A Dask worker process's workers, one per sweep setup (scenes loaded once each)."""


def _start_worker(setup: Setup) -> None:
    end_with_the_parent()
    _process_worker["worker"] = _Worker(setup)


def _run_in_worker(unit: TuneUnit) -> PreparedUnit:
    return _process_worker["worker"].run(unit)


def _run_on_dask(setup: Setup, unit: TuneUnit) -> PreparedUnit:
    key = repr(setup)
    worker = _dask_workers.get(key)
    if worker is None:
        worker = _dask_workers[key] = _Worker(setup)
    return worker.run(unit)


def _in_order(
    units: Sequence[TuneUnit],
    submit: Callable[[TuneUnit], Any],
    wait_any: Callable[[list[Any]], Iterable[Any]],
    window: int,
) -> Iterator[PreparedUnit]:
    """Each unit's rows in plan order, at most ``window`` units ahead of the oldest one due.

    ``submit`` starts a unit and returns its future; ``wait_any`` returns the futures done (at
    least one). A unit's error is the run's (raised here, the units before it written).
    """
    running: dict[Any, int] = {}
    arrived: dict[int, PreparedUnit] = {}
    submitted = written = 0
    while written < len(units):
        while submitted < len(units) and submitted < written + window:
            running[submit(units[submitted])] = submitted
            submitted += 1
        for future in wait_any(list(running)):
            arrived[running.pop(future)] = future.result()
        while written in arrived:
            yield arrived.pop(written)
            written += 1


def _outcomes(
    setup: Setup,
    units: Sequence[TuneUnit],
    jobs: int,
    loaded: Mapping[int, list[SceneFrame]],
    scheduler: str | None = None,
) -> Iterator[PreparedUnit]:
    """Each unit's rows, in plan order: here (``jobs`` 1), on processes or on a Dask cluster."""
    if scheduler is not None:
        yield from _on_dask(setup, units, scheduler)
        return
    if jobs == 1:
        worker = _Worker(setup, loaded)
        for unit in units:
            yield worker.run(unit)
        return
    method = "spawn" if threading.active_count() > 1 else "fork"  # see PoolExecutor
    pool = ProcessPoolExecutor(
        jobs,
        mp_context=multiprocessing.get_context(method),
        initializer=_start_worker,
        initargs=(setup,),
    )
    try:
        yield from _in_order(
            units,
            lambda unit: pool.submit(_run_in_worker, unit),
            lambda futures: wait(futures, return_when=FIRST_COMPLETED)[0],
            jobs * WINDOW_PER_WORKER,
        )
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _on_dask(setup: Setup, units: Sequence[TuneUnit], scheduler: str) -> Iterator[PreparedUnit]:
    """The units as Dask tasks (not pure: a retry runs again); a lost scheduler is one line."""
    from dispeval_ros.offline.dask_executor import connect, disconnect

    client, cluster = connect(scheduler)
    import distributed

    workers = max(1, len(client.scheduler_info().get("workers", {})))
    try:
        yield from _in_order(
            units,
            lambda unit: client.submit(_run_on_dask, setup, unit, pure=False),
            lambda futures: distributed.wait(futures, return_when="FIRST_COMPLETED").done,
            workers * WINDOW_PER_WORKER,
        )
    except (OSError, TimeoutError, CancelledError) as error:
        raise InputError(
            f"lost the Dask scheduler at {scheduler} ({type(error).__name__}); the units "
            "written so far are kept, continue with --resume"
        ) from None
    finally:
        disconnect(client, cluster)


@dataclass
class SweepReport:
    """What a run did: units written now, units a previous run had written, method-frames."""

    units_done: int = 0
    units_skipped: int = 0
    frames: int = 0


def set_sequences(
    store: ResultsStore, scenes: Sequence[Path], loaded: Mapping[int, list[SceneFrame]]
) -> list[str]:
    """Name the scenes' sequences and record them (source and frames) in ``store``."""
    sequences = sequence_names(list(scenes))
    for index, (folder, sequence) in enumerate(zip(scenes, sequences, strict=True)):
        store.set_sequence(sequence, bag_location(folder), sequence_info(folder, loaded[index]))
    return sequences


def run_units(
    store: ResultsStore,
    scenes: Sequence[Path],
    loaded: Mapping[int, list[SceneFrame]],
    units: Sequence[TuneUnit],
    evaluator: Evaluator,
    *,
    jobs: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int, SweepReport], None] | None = None,
) -> SweepReport:
    """Run and write the ``units`` not yet done in ``store`` (in plan order)."""
    done = {sequence: store.done_units(sequence) for sequence in {u.sequence for u in units}}
    todo = [unit for unit in units if unit.name not in done[unit.sequence]]
    report = SweepReport(units_skipped=len(units) - len(todo))
    # absolute: a Dask worker resolves relative paths against its own folder
    setup = Setup(tuple(Path(s).absolute() for s in scenes), evaluator_settings(evaluator))
    outcomes = _outcomes(setup, todo, jobs, loaded, scheduler)
    for unit, prepared in zip(todo, outcomes, strict=False):
        store.add_prepared(prepared)
        report.units_done += 1
        report.frames += len(unit.configurations) * len(unit.frames_of(loaded[unit.scene]))
        if progress is not None:
            progress(report.units_done, len(todo), report)
    return report


def run_sweep(
    store: ResultsStore,
    scenes: Sequence[Path],
    loaded: Mapping[int, list[SceneFrame]],
    configurations: Sequence[Configuration],
    evaluator: Evaluator,
    *,
    chunk: int = DEFAULT_CHUNK,
    jobs: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int, SweepReport], None] | None = None,
) -> SweepReport:
    """Score every configuration on every frame of ``scenes`` into ``store`` (done units skipped).

    ``loaded`` holds the scenes as :func:`load_scene` read them (the driver checked them all
    before creating the store); the in-process run reuses them, worker processes (``jobs``
    > 1, or a Dask cluster: ``scheduler`` as ``dispeval bag --scheduler`` takes it) load their
    own.
    """
    sequences = set_sequences(store, scenes, loaded)
    units = plan(sequences, configurations, chunk)
    return run_units(
        store, scenes, loaded, units, evaluator, jobs=jobs, scheduler=scheduler, progress=progress
    )
