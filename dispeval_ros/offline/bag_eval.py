"""Evaluate recorded bags: each bag is a sequence, cut into time slices (units of work).

The driver plans the units (:mod:`dispeval_ros.offline.units`), hands them to an executor
(:mod:`dispeval_ros.offline.executors`: in process, ``--jobs N`` processes or a Dask
cluster) and is the only writer of the results database. Each unit is written in one
transaction with its match counts, in plan order as soon as it and the units before it are
back, so any engine gives the same database, a killed run loses at most the units in flight
and ``--resume`` continues without duplicating anything. A unit that raises or whose worker
dies is retried; after :data:`MAX_ATTEMPTS` its problem is stored as the unit's failure record,
which ``--resume`` replaces by trying the unit again.
"""

from __future__ import annotations

import dataclasses
import threading
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.io.store import RESULTS_FILE, ResultsStore
from dispeval_ros.io.store.naming import bag_location, sequence_names
from dispeval_ros.offline.executors import Executor, make_executor
from dispeval_ros.offline.units import (
    DEFAULT_SLICE_NS,
    Unit,
    UnitResult,
    UnitRows,
    auto_slice_for,
    close_bags,
    evaluate_unit,
    failed_result,
    open_bag,
    plan_bag,
    repeated_elsewhere,
)
from dispeval_ros.stream.core import CoreConfig

__all__ = [
    "DEFAULT_SLICE_NS",
    "MAX_ATTEMPTS",
    "RunReport",
    "Unit",
    "UnitResult",
    "bag_location",
    "evaluate_bags",
    "evaluate_unit",
    "plan_units",
    "recorded_bags",
    "sequence_names",
]

MAX_ATTEMPTS = 3
"""How often a unit is tried before it is stored as a problem (a raise or a dead worker)."""
WINDOW_PER_WORKER = 4
"""Units submitted ahead of the oldest one not yet written, per worker (bounds memory)."""


def recorded_bags(out: Path, bags: Sequence[Path], resume: bool) -> list[str]:
    """The run record's bags: :func:`bag_location` of each, or an older database's spelling.

    Databases written before :func:`bag_location` hold the paths as typed. On ``--resume`` a
    stored path naming the same bag (resolved from the current folder: relative paths were
    typed there) keeps its spelling, so the record still matches; a relative one that names
    another bag from here is refused in one line saying where to resume from.
    """
    locations = [bag_location(path) for path in bags]
    stored = _stored_bags(out) if resume else None
    if stored is None or len(stored) != len(locations):
        return locations
    recorded = []
    for old, new in zip(stored, locations, strict=True):
        if old != new and Path(old).resolve() == Path(new):
            recorded.append(old)  # the same bag, spelled as an older dispeval stored it
            continue
        if not Path(old).is_absolute():
            raise ConfigurationError(
                f"{out} names bag '{old}' as typed (an older dispeval), relative to the folder "
                f"that run started in; from here it is {Path(old).resolve()}, not {new}: run "
                "--resume from that folder"
            )
        recorded.append(new)
    return recorded


def _stored_bags(out: Path) -> list[str] | None:
    """The bags in the run record of ``out``'s results, if it has a readable one."""
    if not (out / RESULTS_FILE).is_file():
        return None
    try:
        with ResultsStore.open(out) as store:
            bags = store.config().get("bags")
    except DispevalError:  # creating the store reports what is wrong with it
        return None
    if isinstance(bags, list) and all(isinstance(bag, str) for bag in bags):
        return bags
    return None


def plan_units(path: Path, sequence: str, config: CoreConfig, slice_ns: int) -> list[Unit]:
    """Cut a bag into slices where its messages are; the plan depends only on the bag and slice."""
    return plan_bag(path, sequence, config, slice_ns).units


@dataclass
class RunReport:
    """What a run did: units written now and before (resume), frames, problems."""

    units_done: int = 0
    units_skipped: int = 0
    frames: int = 0
    problems: int = 0
    messages: int = 0
    retries: int = 0
    failed_before: int = 0
    """Units an earlier run had given up on (failure records), tried again by this one."""


def evaluate_bags(
    bags: Sequence[Path],
    config: CoreConfig,
    store: ResultsStore,
    *,
    jobs: int = 1,
    scheduler: str | None = None,
    executor: Executor | None = None,
    slice_ns: int | None = DEFAULT_SLICE_NS,
    progress: Callable[[int, int, RunReport], None] | None = None,
    alongside: Callable[[], None] | None = None,
    warn: Callable[[str], None] | None = None,
) -> RunReport:
    """Evaluate every bag into ``store`` (units already done there are skipped).

    Units run on ``executor``, else on the one ``jobs`` / ``scheduler`` ask for (see
    :func:`~dispeval_ros.offline.executors.make_executor`). ``slice_ns=None`` sizes each
    bag's units from its length and the number of workers (the choice is stored with the
    sequence, so a resumed run cuts the same units whatever its executor).

    ``alongside`` runs on a thread of this process while the units run (see :class:`_Alongside`);
    what it raises is raised once the units are written. ``warn`` is told, once per bag while
    planning, what a reader should know (header stamps far from the log time).
    """
    own = executor is None
    engine = make_executor(config, jobs, scheduler) if executor is None else executor
    side = _Alongside(alongside)
    try:
        engine.start(bags)
        units, skipped, failed_before = _plan(bags, config, store, slice_ns, engine.workers, warn)
        engine.check(bags)
        report = RunReport(units_skipped=skipped, failed_before=failed_before)
        _run(engine, units, store, report, progress, side.start)
        side.finish()
    finally:
        if own:
            engine.close()
        close_bags()  # the driver's own, opened to plan
    return report


class _Alongside:
    """Work for the driver's spare time, on a thread started once the first units are submitted.

    Not before: the process pool forks its workers at the first submission, and a process
    with threads is not forked (see :class:`~dispeval_ros.offline.executors.PoolExecutor`).
    """

    def __init__(self, work: Callable[[], None] | None) -> None:
        self.work = work
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None

    def start(self) -> None:
        """Start the work (once)."""
        if self.work is not None and self._thread is None:
            self._thread = threading.Thread(target=self._run, name="dispeval-alongside")
            self._thread.daemon = True  # a failed run does not wait for it
            self._thread.start()

    def _run(self) -> None:
        assert self.work is not None
        try:
            self.work()
        except BaseException as error:  # raised in the driver by finish()
            self._error = error

    def finish(self) -> None:
        """Wait for the work (started now if no unit was submitted); raise what it raised."""
        self.start()
        if self._thread is not None:
            self._thread.join()
        if self._error is not None:
            raise self._error


def _plan(
    bags: Sequence[Path],
    config: CoreConfig,
    store: ResultsStore,
    slice_ns: int | None,
    workers: int,
    warn: Callable[[str], None] | None = None,
) -> tuple[list[Unit], int, int]:
    """Every unit not stored yet, in plan order, with two counts.

    How many were stored before, and how many of the planned ones an earlier run gave up on
    (they are tried again).
    """
    units: list[Unit] = []
    skipped = failed_before = 0
    for path, sequence in zip(bags, sequence_names(bags), strict=True):
        chosen = slice_ns
        if chosen is None:
            chosen = _stored_slice(store, sequence)
        if chosen is None:
            source = open_bag(path)
            margin = config.tolerance_ns + config.lateness_ns
            chosen = auto_slice_for(source, workers, margin)
        plan = plan_bag(path, sequence, config, chosen)
        if plan.warning is not None and warn is not None:
            warn(plan.warning)
        info = plan.info if slice_ns is not None else {**plan.info, "slice_ns": chosen}
        store.set_sequence(sequence, bag_location(path), info)
        done = store.done_units(sequence)
        skipped += len(done)
        failed_before += len(store.failed_units(sequence) - done)
        units.extend(unit for unit in plan.units if unit.name not in done)
    return units, skipped, failed_before


def _stored_slice(store: ResultsStore, sequence: str) -> int | None:
    """The slice an earlier (auto-sliced) run of this sequence chose, if any."""
    try:
        _, info = store.sequence_info(sequence)
    except KeyError:
        return None
    value = info.get("slice_ns")
    return int(value) if isinstance(value, int) else None


def _run(
    engine: Executor,
    units: list[Unit],
    store: ResultsStore,
    report: RunReport,
    progress: Callable[[int, int, RunReport], None] | None,
    submitted: Callable[[], None],
) -> None:
    """Submit within a window, retry failures, write each unit in plan order as it can be.

    ``submitted`` is called after each round of submissions.
    """
    window = max(1, engine.workers * WINDOW_PER_WORKER)
    pending = list(range(len(units)))[::-1]  # a stack: lowest index on top
    attempts: Counter[int] = Counter()
    arrived: dict[int, UnitRows] = {}
    in_flight = 0
    alone = False  # a retry runs alone, so a worker that dies is its own unit's fault
    written = 0
    first: dict[str, dict[int, int]] = {}  # per sequence: stamp → arrival of the frames kept
    stored: dict[str, set[int]] = {}  # per sequence: the stamps an earlier run stored
    while written < len(units):
        while not alone and pending and in_flight < window:
            index = pending[-1]
            if attempts[index]:
                if in_flight:
                    break
                alone = True
            elif index >= written + window:
                break
            pending.pop()
            engine.submit(index, units[index])
            in_flight += 1
        submitted()
        for index, outcome in engine.completed():
            in_flight -= 1
            alone = alone and in_flight > 0
            if isinstance(outcome, UnitRows):
                arrived[index] = outcome
                continue
            attempts[index] += 1
            if attempts[index] < MAX_ATTEMPTS:
                report.retries += 1
                pending.append(index)
                pending.sort(reverse=True)
            else:
                arrived[index] = failed_result(outcome, attempts[index])
        while written in arrived:
            result = arrived.pop(written)
            unit = units[written]
            kept = first.setdefault(unit.sequence, {})
            before = stored.setdefault(unit.sequence, set(store.stamps(unit.sequence)))
            again = repeated_elsewhere(result, kept, before)
            if again:  # frames an earlier unit kept, logged again: run it with them as repeats
                units[written] = dataclasses.replace(unit, seen_stamps=unit.seen_stamps | again)
                pending.append(written)
                pending.sort(reverse=True)
                break
            for stamp, arrival in result.kept:
                kept.setdefault(stamp, arrival)
            store.add_prepared(result.rows)
            written += 1
            report.units_done += 1
            report.frames += result.frames
            report.problems += result.problems
            report.messages += result.messages
            if progress is not None:
                progress(report.units_done, len(units), report)
