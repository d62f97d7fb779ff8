"""Where the units of ``dispeval bag`` run: in process, a process pool, or a Dask cluster.

An executor takes units, runs :func:`~dispeval_ros.offline.units.run_unit` on them wherever
it runs work and hands back each outcome as it completes; it never touches the results
database (the driver in :mod:`dispeval_ros.offline.bag_eval` is its only writer and decides
what to retry). Workers stay alive across units, so each opens a bag once.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Protocol

from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.offline.units import (
    Unit,
    UnitFailure,
    UnitRows,
    close_bags,
    close_scoring_pools,
    forget_bags,
    open_bag,
    run_unit,
    scoring_threads,
)
from dispeval_ros.stream.core import CoreConfig

Outcome = tuple[int, UnitRows | UnitFailure]
"""A submitted unit's index and what came back."""


class Executor(Protocol):
    """Runs units somewhere; outcomes come back as they complete."""

    workers: int
    """How many units run at once (to size the units and the submission window)."""

    def start(self, paths: Sequence[Path]) -> None:
        """Get the workers going before the units are planned (they open the first bag)."""

    def check(self, paths: Sequence[Path]) -> None:
        """Refuse (one line) when a worker cannot run the units: bag paths, version."""

    def submit(self, index: int, unit: Unit) -> None:
        """Start running ``unit`` (``index`` comes back with its outcome)."""

    def completed(self) -> list[Outcome]:
        """Wait for at least one submitted unit; its outcome (and any others ready)."""

    def close(self) -> None:
        """Release the workers."""


class InProcessExecutor:
    """Runs each unit when asked for outcomes, in this process (bags stay open meanwhile).

    Its frames are scored on as many threads as the process has cores, while it reads on.
    """

    workers = 1

    def __init__(self, config: CoreConfig) -> None:
        self.config = config
        self.threads = scoring_threads(1)
        self._queue: deque[tuple[int, Unit]] = deque()

    def start(self, paths: Sequence[Path]) -> None:
        """Nothing to start: the driver opens the bags as it plans them."""

    def check(self, paths: Sequence[Path]) -> None:
        """Nothing to check: the driver reads the bags itself."""

    def submit(self, index: int, unit: Unit) -> None:
        """Queue ``unit``; it runs when an outcome is asked for."""
        self._queue.append((index, unit))

    def completed(self) -> list[Outcome]:
        """Run the oldest queued unit here."""
        index, unit = self._queue.popleft()
        return [(index, run_unit(self.config, unit, self.threads))]

    def close(self) -> None:
        """Close the bags this process opened and stop its scoring threads."""
        close_bags()
        close_scoring_pools()


_worker_config: dict[str, CoreConfig] = {}
"""A pool worker's configuration, set once when it starts (not sent with every unit)."""
_worker_threads: dict[str, int] = {}
"""A pool worker's scoring threads (its share of the cores)."""


def _start_worker(config: CoreConfig, threads: int, first_bag: Path | None) -> None:
    forget_bags()
    _worker_config["config"] = config
    _worker_threads["threads"] = threads
    end_with_the_parent()
    if first_bag is not None:  # while the driver plans: the first units read this bag
        with contextlib.suppress(DispevalError):  # its units report what is wrong
            open_bag(first_bag)


def _ready() -> None:
    """A task that makes the pool start its workers."""


def end_with_the_parent() -> None:
    """A pool worker stops when its driver does, however the driver ends.

    Ctrl-C (sent to the whole process group) is the driver's to handle: it stops taking units
    and shuts the pool down. If the driver is killed outright, Linux sends the worker SIGKILL
    (``PR_SET_PDEATHSIG``), so no worker outlives it or prints tracebacks after the prompt.
    SIGTERM ends a worker at once: the pool terminates its workers with it when one died, and a
    worker that raised the driver's inherited "stop cleanly" instead would retry sending its
    result into a pipe nobody reads any more, and hang the run.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            return
        if os.getppid() == 1:  # the driver died before the request took effect
            os._exit(1)


def _run_in_worker(unit: Unit) -> UnitRows | UnitFailure:
    return run_unit(_worker_config["config"], unit, _worker_threads["threads"])


class PoolExecutor:
    """``--jobs N``: N worker processes that live for the whole run.

    A worker that dies breaks the pool: the units it held come back as failures (the driver
    retries them) and a fresh pool takes over.
    """

    def __init__(self, config: CoreConfig, jobs: int) -> None:
        self.config = config
        self.workers = jobs
        self._pool: ProcessPoolExecutor | None = None
        self._first_bag: Path | None = None
        self._running: dict[Future[UnitRows | UnitFailure], tuple[int, Unit]] = {}
        self._pool_of: dict[Future[UnitRows | UnitFailure], ProcessPoolExecutor] = {}

    def start(self, paths: Sequence[Path]) -> None:
        """Fork the workers now: each opens the first bag while the driver plans the units.

        Opening a bag (parsing its metadata and index) takes tens of milliseconds that would
        otherwise be spent in turn, first by the driver, then by the workers.
        """
        self._first_bag = paths[0] if paths else None
        self._ensure_pool().submit(_ready)

    def check(self, paths: Sequence[Path]) -> None:
        """Nothing to check: the workers share this machine and this installation."""

    def _ensure_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            # fork is fastest, but forking a process with threads can deadlock its children
            method = "spawn" if threading.active_count() > 1 else "fork"
            self._pool = ProcessPoolExecutor(
                self.workers,
                mp_context=multiprocessing.get_context(method),
                initializer=_start_worker,
                initargs=(self.config, scoring_threads(self.workers), self._first_bag),
            )
        return self._pool

    def submit(self, index: int, unit: Unit) -> None:
        """Send ``unit`` to the pool (a fresh one if the last broke)."""
        pool = self._ensure_pool()
        try:
            future = pool.submit(_run_in_worker, unit)
        except BrokenProcessPool:
            self._replace_pool(pool)
            pool = self._ensure_pool()
            future = pool.submit(_run_in_worker, unit)
        self._running[future] = (index, unit)
        self._pool_of[future] = pool

    def completed(self) -> list[Outcome]:
        """The units finished by now (at least one); a broken pool's units as failures."""
        done, _ = wait(list(self._running), return_when=FIRST_COMPLETED)
        outcomes: list[Outcome] = []
        for future in done:
            index, unit = self._running.pop(future)
            pool = self._pool_of.pop(future)
            error = future.exception()
            if error is None:
                outcomes.append((index, future.result()))
                continue
            if isinstance(error, BrokenProcessPool):
                self._replace_pool(pool)
            outcomes.append((index, UnitFailure(unit, _worker_lost(error))))
        return outcomes

    def _replace_pool(self, broken: ProcessPoolExecutor) -> None:
        """Drop a broken pool (once); its other units fail too and are retried."""
        broken.shutdown(wait=False, cancel_futures=True)
        if self._pool is broken:
            self._pool = None

    def close(self) -> None:
        """Stop the worker processes."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def _worker_lost(error: BaseException) -> str:
    if isinstance(error, BrokenProcessPool):
        return "a worker process died while running it"
    return f"{type(error).__name__}: {' '.join(str(error).split())}"


def check_engine(jobs: int, scheduler: str | None) -> None:
    """The engine options are consistent (checked before anything is created)."""
    if jobs < 1:
        raise ConfigurationError(f"--jobs must be at least 1, got {jobs}")
    if scheduler is not None and jobs != 1:
        raise ConfigurationError("give --jobs or --scheduler, not both")
    if scheduler is not None:
        from dispeval_ros.offline.dask_executor import check_scheduler

        check_scheduler(scheduler)


@contextlib.contextmanager
def ready_executor(
    config: CoreConfig, jobs: int, scheduler: str | None, paths: Sequence[Path]
) -> Iterator[Executor]:
    """The executor of :func:`make_executor`, checked against ``paths``, closed on leaving.

    A run builds it before its results store: a scheduler that cannot be reached, or workers
    that cannot read the bags, are refused before any file is created.
    """
    engine = make_executor(config, jobs, scheduler)
    try:
        engine.check(paths)
        yield engine
    finally:
        engine.close()


def make_executor(config: CoreConfig, jobs: int = 1, scheduler: str | None = None) -> Executor:
    """The executor the options ask for: a Dask scheduler, ``jobs`` processes, or in process."""
    check_engine(jobs, scheduler)
    if scheduler is not None:
        from dispeval_ros.offline.dask_executor import DaskExecutor

        return DaskExecutor(config, scheduler)
    if jobs == 1:
        return InProcessExecutor(config)
    return PoolExecutor(config, jobs)
