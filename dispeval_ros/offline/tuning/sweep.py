"""Run a sweep: every configuration's maps of every scene frame, scored into one database.

The scenes, units and sequences are :mod:`dispeval_ros.stream.tuning`'s (shared with ``tune
--node``). A unit
computes the chunk's OpenCV maps on the sequence's frames and scores each one with the
:class:`~dispeval_ros.core.Evaluator` against the frame's reference, exactly as ``dispeval
eval`` scores a map read from a file (the same ground truth, masks and camera of the scene).
Units run here or on ``--jobs`` worker processes and are written in plan order, one
transaction each, so any number of workers gives the same database, a killed run loses at most
the units in flight and a resumed one skips the units that are done.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, CancelledError, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

from dispeval_ros.core import Evaluator
from dispeval_ros.core.records import FrameScores, MatchCounts
from dispeval_ros.errors import DispevalError, InputError
from dispeval_ros.io.store import PreparedUnit, ResultsStore, prepare_unit
from dispeval_ros.offline.executors import end_with_the_parent
from dispeval_ros.stream.tuning import (
    SceneFrame,
    SweepReport,
    TuneUnit,
    check_fits,
    load_scene,
    plan,
    set_sequences,
    units_to_do,
)
from dispeval_ros.testbed.node_parameters import Configuration

__all__ = [
    "DEFAULT_CHUNK",
    "SceneFrame",
    "SweepReport",
    "check_fits",
    "load_scene",
    "plan",
    "run_sweep",
    "run_units",
    "set_sequences",
]

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


def evaluator_settings(evaluator: Evaluator) -> dict[str, Any]:
    """The settings that rebuild ``evaluator`` in a worker (an Evaluator does not pickle)."""
    return {name: getattr(evaluator, name) for name in EVALUATOR_FIELDS}


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


def _start_worker(setup: Setup, jobs: int) -> None:
    import cv2

    end_with_the_parent()
    cv2.setNumThreads(max(1, (os.cpu_count() or 1) // jobs))  # the cores shared, not each taken
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
            index = running.pop(future)
            arrived[index] = _result(future, units[index])
        while written in arrived:
            yield arrived.pop(written)
            written += 1


def _result(future: Any, unit: TuneUnit) -> PreparedUnit:
    """A unit's rows; what went wrong on its worker as one line (a user's error as it is)."""
    try:
        return cast(PreparedUnit, future.result())
    except DispevalError:
        raise
    except Exception as error:  # a worker that died, ran out of memory, was lost...
        what = " ".join(str(error).split()) or "no message"
        raise InputError(
            f"unit {unit.name} of {unit.sequence} failed on its worker ({type(error).__name__}: "
            f"{what}); the units written so far are kept, continue with --resume"
        ) from None


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
    # spawn, never fork: OpenCV's own thread pool (invisible to threading) has run here, and a
    # forked child that touches it can hang for good
    pool = ProcessPoolExecutor(
        jobs,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_start_worker,
        initargs=(setup, jobs),
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
    todo, report = units_to_do(store, units)
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
