"""The results database of a run: per-frame scores, problems and match counts in SQLite.

``dispeval bag`` and the live summarizer write it one *unit* of work at a time (e.g. a time
slice of a bag); the HTML report reads it later. Each unit is one transaction that also marks
the unit done, so a killed run loses at most the unit being written, and a resumed run skips
the done units and ends with exactly the rows of an uninterrupted run. Every frame row keeps
its float64 accumulator row (``sums``), so sequence scores are exact sums of sums
(METHOD.md §4), never averages of per-frame means.
"""

from __future__ import annotations

import csv
import json
import math
import os
import sqlite3
from collections.abc import Collection, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path, PurePath
from types import TracebackType

import numpy as np

from dispeval_ros.core.measures import SUM_FIELDS, Scores, quantile_level
from dispeval_ros.errors import ConfigurationError, InputError, ResultsConflictError

RESULTS_FILE = "results.sqlite"
APPLICATION_ID = 0x44737045
"""``"DspE"`` in the SQLite header: tells a dispeval results database from any other."""
SCHEMA_VERSION = 1
FAILED_MARK = "!failed"
"""Suffix of the record a unit that failed every attempt leaves (see :func:`failure_record`)."""
_BLOB = np.dtype("<f8")  # accumulator rows are stored little-endian whatever the machine
_FIXED_COLUMNS = ("sequence", "stamp", "method", "criterion", "n", "sums", "relative")

_SCHEMA = (
    # the run's configuration, one JSON value per key, in the caller's key order
    "CREATE TABLE run (key TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE, value TEXT NOT NULL)",
    # the scoring layout, fixed by the first frame: measure columns, sums fields, thresholds
    "CREATE TABLE layout (id INTEGER PRIMARY KEY CHECK (id = 1), measures TEXT NOT NULL, "
    "fields TEXT NOT NULL, thresholds BLOB NOT NULL, policy TEXT NOT NULL)",
    "CREATE TABLE sequences (name TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE, "
    "source TEXT, info TEXT)",
    "CREATE TABLE methods (name TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE)",
    "CREATE TABLE criteria (name TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE, "
    "overlapping INTEGER NOT NULL)",
    "CREATE TABLE units (sequence TEXT NOT NULL, unit TEXT NOT NULL, "
    "ordinal INTEGER NOT NULL UNIQUE, PRIMARY KEY (sequence, unit))",
    "CREATE TABLE problems (sequence TEXT NOT NULL, unit TEXT NOT NULL, position INTEGER NOT NULL, "
    "stamp INTEGER, method TEXT, message TEXT NOT NULL, PRIMARY KEY (sequence, unit, position))",
    "CREATE TABLE match_counts (sequence TEXT NOT NULL, method TEXT NOT NULL, "
    "ordinal INTEGER NOT NULL, matched INTEGER NOT NULL, unmatched INTEGER NOT NULL, "
    "dropped INTEGER NOT NULL, failed INTEGER NOT NULL, PRIMARY KEY (sequence, method))",
)


def failure_record(unit: str) -> str:
    """The unit name under which a unit that failed every attempt is recorded.

    The record holds the failure's problem and no frames; the unit itself stays undone, so a
    resumed run tries it again, and writing it (or a newer failure) replaces the record.
    """
    return unit + FAILED_MARK


_ADD_COUNTS = (
    "INSERT INTO match_counts "
    "(sequence, method, ordinal, matched, unmatched, dropped, failed) VALUES (?, ?, "
    "(SELECT COALESCE(MAX(ordinal), -1) + 1 FROM match_counts WHERE sequence = ?), "
    "?, ?, ?, ?) ON CONFLICT (sequence, method) DO UPDATE SET "
    "matched = matched + excluded.matched, unmatched = unmatched + excluded.unmatched, "
    "dropped = dropped + excluded.dropped, failed = failed + excluded.failed"
)
"""Add a unit's match counts to its sequence's (rows: sequence, method, sequence, counts…)."""
_ORDERED_FRAMES = (
    " FROM frames f JOIN sequences s ON s.name = f.sequence JOIN methods m ON m.name = f.method"
    " JOIN criteria c ON c.name = f.criterion"
)
_FRAME_ORDER = " ORDER BY s.ordinal, f.stamp, m.ordinal, c.ordinal"


@dataclass(frozen=True)
class FrameScores:
    """The scores of one method on one frame (``stamp`` in nanoseconds)."""

    sequence: str
    stamp: int
    method: str
    scores: Scores


@dataclass(frozen=True)
class Problem:
    """A per-frame problem worth reporting (decode error, size mismatch…), kept with the unit."""

    sequence: str
    stamp: int | None
    method: str | None
    message: str


@dataclass(frozen=True)
class MatchCounts:
    """How a method's estimates met the ground truth: matched, unmatched, dropped, failed."""

    matched: int
    unmatched: int
    dropped: int
    failed: int


@dataclass(frozen=True)
class _Layout:
    """What every stored frame shares: measure columns, accumulator fields, thresholds, policy."""

    measures: tuple[str, ...]
    fields: tuple[str, ...]
    thresholds: np.ndarray
    policy: str

    @classmethod
    def of(cls, scores: Scores) -> _Layout:
        clash = [name for name in scores.measures if name in _FIXED_COLUMNS]
        if clash:
            raise ConfigurationError(f"measure name '{clash[0]}' is taken by a frames column")
        return cls(
            measures=tuple(scores.measures),
            fields=tuple(SUM_FIELDS),
            thresholds=np.asarray(scores.thresholds, dtype=np.float64),
            policy=scores.policy,
        )

    def difference(self, other: _Layout) -> str | None:
        """The first thing that differs, as 'what these vs those', or None."""
        pairs = (
            ("measures", ", ".join(self.measures), ", ".join(other.measures)),
            ("accumulator fields", ", ".join(self.fields), ", ".join(other.fields)),
            ("thresholds", _floats(self.thresholds), _floats(other.thresholds)),
            ("missing policy", self.policy, other.policy),
        )
        for what, mine, theirs in pairs:
            if mine != theirs:
                return f"{what} {mine} vs {theirs}"
        return None

    def frames_table(self) -> str:
        measures = "".join(f", {_quote(name)} REAL" for name in self.measures)
        return (
            "CREATE TABLE frames (sequence TEXT NOT NULL, stamp INTEGER NOT NULL, "
            f"method TEXT NOT NULL, criterion TEXT NOT NULL, n INTEGER{measures}, "
            "sums BLOB NOT NULL, relative INTEGER NOT NULL, "
            "PRIMARY KEY (sequence, stamp, method, criterion))"
        )

    def insert_frames(self) -> str:
        columns = ", ".join(["sequence", "stamp", "method", "criterion", "n"])
        measures = "".join(f", {_quote(name)}" for name in self.measures)
        marks = ", ".join("?" * (7 + len(self.measures)))
        return f"INSERT INTO frames ({columns}{measures}, sums, relative) VALUES ({marks})"

    def measure_columns(self) -> str:
        return "".join(f", f.{_quote(name)}" for name in self.measures)


@dataclass(frozen=True)
class PreparedUnit:
    """A unit's database rows, made without a database (by a worker) for a writer to add."""

    sequence: str
    unit: str
    layout: _Layout | None
    frame_rows: list[tuple[object, ...]]
    methods: list[str]
    criteria: dict[str, bool]
    problem_rows: list[tuple[object, ...]]
    count_rows: list[tuple[object, ...]]

    @property
    def frames(self) -> int:
        """How many (frame, method) scores the unit holds."""
        return len({(row[1], row[2]) for row in self.frame_rows})


def prepare_unit(
    sequence: str,
    unit: str,
    frames: Sequence[FrameScores],
    problems: Sequence[Problem] = (),
    counts: Mapping[str, MatchCounts] | None = None,
) -> PreparedUnit:
    """The rows :meth:`ResultsStore.add_unit` writes for a unit (checked: one sequence, no twins)."""
    layout = _unit_layout(unit, frames)
    frame_rows, methods, criteria = _frame_rows(sequence, unit, frames, layout)
    problem_rows: list[tuple[object, ...]] = []
    for position, problem in enumerate(problems):
        if problem.sequence != sequence:
            raise ValueError(
                f"unit '{unit}' of {sequence} holds a problem of sequence {problem.sequence}"
            )
        stamp = None if problem.stamp is None else int(problem.stamp)
        problem_rows.append((sequence, unit, position, stamp, problem.method, problem.message))
    count_rows: list[tuple[object, ...]] = [
        (sequence, method, sequence, c.matched, c.unmatched, c.dropped, c.failed)
        for method, c in (counts or {}).items()
    ]
    return PreparedUnit(
        sequence, unit, layout, frame_rows, methods, criteria, problem_rows, count_rows
    )


class ResultsStore:
    """The results database of one run (``results.sqlite`` in the output folder).

    Writers use :meth:`create` (one process, one connection, WAL journal); readers use
    :meth:`open` (read-only). Use it from one thread at a time.
    """

    def __init__(
        self,
        connection: sqlite3.Connection,
        path: Path,
        writable: bool,
        lock: _FolderLock | None = None,
    ) -> None:
        self._db = connection
        self.path = path
        self._writable = writable
        self._lock = lock
        self._layout: _Layout | None = None

    # -- opening -----------------------------------------------------------------------------

    @classmethod
    def create(
        cls, directory: Path, config: Mapping[str, object], resume: bool = False
    ) -> ResultsStore:
        """Create ``directory/results.sqlite`` for a run, or continue it with ``resume``.

        Refuses to mix runs: existing results without ``resume`` and a different ``config``
        with it are configuration errors.
        """
        directory = Path(directory)
        wanted = _config_rows(config)
        try:
            directory.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(
                f"{directory}: cannot create the results folder ({error.strerror or error})"
            ) from None
        path = directory / RESULTS_FILE
        lock = _FolderLock.take(directory)
        try:
            connection = _connect(path, writable=True)
        except BaseException:
            lock.release()
            raise
        try:
            state = _state(connection, path)
            if state == "results" and _holds_nothing(connection):
                _clear(connection)  # a run that stopped before its first unit left no results
                state = "empty"
            if state == "results" and not resume:
                raise ResultsConflictError(f"{directory} already holds results", resumable=True)
            connection.execute("PRAGMA journal_mode = WAL")
            connection.execute("PRAGMA synchronous = NORMAL")
            if state == "empty":
                _initialise(connection, wanted)
            else:
                _check_config(connection, directory, wanted)
        except sqlite3.Error as error:
            connection.close()
            lock.release()
            raise InputError(f"{path}: cannot write the results database ({error})") from None
        except BaseException:
            connection.close()
            lock.release()
            raise
        return cls(connection, path, writable=True, lock=lock)

    @classmethod
    def open(cls, directory_or_file: Path) -> ResultsStore:
        """Open existing results read-only (for summaries and reports)."""
        path = Path(directory_or_file)
        if path.is_dir():
            path = path / RESULTS_FILE
        if not path.is_file():
            raise InputError(
                f"{path}: no such file; expected a results folder or its {RESULTS_FILE} "
                "(written by 'dispeval bag' or the summarizer)"
            )
        connection = _connect(path, writable=False)
        try:
            if _state(connection, path) != "results":
                raise InputError(
                    f"{path} is an empty SQLite database; expected dispeval results "
                    f"({RESULTS_FILE} written by 'dispeval bag' or the summarizer)"
                )
            _check_tables(connection, path)
        except BaseException:
            connection.close()
            raise
        return cls(connection, path, writable=False)

    def close(self) -> None:
        """Close the connection (a writer's WAL is checkpointed into the database file)."""
        self._db.close()
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def __enter__(self) -> ResultsStore:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    # -- writing -----------------------------------------------------------------------------

    def is_done(self, sequence: str, unit: str) -> bool:
        """Whether a unit was completely written (a resumed run skips it)."""
        row = self._db.execute(
            "SELECT 1 FROM units WHERE sequence = ? AND unit = ?", (sequence, unit)
        ).fetchone()
        return row is not None

    def done_units(self, sequence: str) -> set[str]:
        """The units of a sequence that were completely written (failure records aside)."""
        rows = self._db.execute("SELECT unit FROM units WHERE sequence = ?", (sequence,))
        return {unit for (unit,) in rows if not unit.endswith(FAILED_MARK)}

    def failed_units(self, sequence: str) -> set[str]:
        """The units of a sequence whose last run failed every attempt (a resume retries them)."""
        rows = self._db.execute("SELECT unit FROM units WHERE sequence = ?", (sequence,))
        return {unit[: -len(FAILED_MARK)] for (unit,) in rows if unit.endswith(FAILED_MARK)}

    def add_unit(
        self,
        sequence: str,
        unit: str,
        frames: Sequence[FrameScores],
        problems: Sequence[Problem] = (),
        counts: Mapping[str, MatchCounts] | None = None,
    ) -> None:
        """Write one unit of work in one transaction and mark it done; a done unit is a no-op.

        Frames, problems and the added match counts are all-or-nothing, so a kill can never
        leave half a unit, and adding it again after a resume changes nothing.
        """
        self._require_writable()
        if self._written(sequence, unit, unit.endswith(FAILED_MARK)):
            return
        self.add_prepared(prepare_unit(sequence, unit, frames, problems, counts))

    def _written(self, sequence: str, unit: str, failure: bool) -> bool:
        """Whether writing ``unit`` is a no-op: it is done (a failure record: its unit is)."""
        return self.is_done(sequence, unit[: -len(FAILED_MARK)] if failure else unit)

    def add_prepared(self, prepared: PreparedUnit) -> None:
        """:meth:`add_unit` of rows made by :func:`prepare_unit` (e.g. on another machine)."""
        self._require_writable()
        sequence, unit, layout = prepared.sequence, prepared.unit, prepared.layout
        failure = unit.endswith(FAILED_MARK)
        if self._written(sequence, unit, failure):
            return
        frame_rows, methods, criteria = prepared.frame_rows, prepared.methods, prepared.criteria
        problem_rows, count_rows = prepared.problem_rows, prepared.count_rows
        with self._transaction():
            if self._written(sequence, unit, failure):  # again, now under the write lock
                return
            record = unit if failure else failure_record(unit)  # an earlier failure's record
            for table in ("problems", "units"):
                self._db.execute(
                    f"DELETE FROM {table} WHERE sequence = ? AND unit = ?", (sequence, record)
                )
            if layout is not None:
                self._use_layout(layout)
            self._register_sequence(sequence)
            self._db.executemany(
                "INSERT OR IGNORE INTO methods (name, ordinal) "
                "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM methods))",
                [(method,) for method in methods],
            )
            self._db.executemany(
                "INSERT OR IGNORE INTO criteria (name, ordinal, overlapping) "
                "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM criteria), ?)",
                list(criteria.items()),
            )
            if layout is not None:
                try:
                    self._db.executemany(layout.insert_frames(), frame_rows)
                except sqlite3.IntegrityError as error:
                    if "UNIQUE" not in str(error):
                        raise
                    raise ValueError(
                        f"unit '{unit}' of {sequence} holds a frame (stamp, method) that "
                        "another unit already stored"
                    ) from None
            self._db.executemany(
                "INSERT INTO problems (sequence, unit, position, stamp, method, message) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                problem_rows,
            )
            self._db.executemany(_ADD_COUNTS, count_rows)
            self._db.execute(
                "INSERT INTO units (sequence, unit, ordinal) "
                "VALUES (?, ?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM units))",
                (sequence, unit),
            )
        if self._layout is None:
            self._layout = self._read_layout()

    def add_results(self, other: ResultsStore) -> int:
        """Copy every unit of ``other`` (frames, problems, match counts) in one transaction.

        Returns the units added. Refuses (one line) results of another scoring layout, a
        sequence both hold from different bags, and a unit both hold (it would count twice).
        """
        self._require_writable()
        layout = other._current_layout()
        mine = set(self.sequences())
        units = other._db.execute("SELECT sequence, unit FROM units ORDER BY ordinal").fetchall()
        with self._transaction():
            if layout is not None:
                self._use_layout(layout)
            for sequence in other.sequences():
                source, info = other.sequence_info(sequence)
                if sequence in mine and self.sequence_info(sequence) != (source, info):
                    raise ConfigurationError(
                        f"{other.path}: sequence {sequence} comes from {source or 'elsewhere'}"
                        f", in {self.path} from {self.sequence_info(sequence)[0] or 'elsewhere'}"
                    )
                self._register_sequence(sequence)
                self._db.execute(
                    "UPDATE sequences SET source = ?, info = ? WHERE name = ?",
                    (source, _json(info, f"the metadata of sequence {sequence}"), sequence),
                )
            for sequence, unit in units:
                if self.is_done(sequence, unit):
                    raise ConfigurationError(
                        f"{other.path}: unit {unit} of sequence {sequence} is in {self.path} "
                        "already; merging it again would count it twice"
                    )
                self._db.execute(
                    "INSERT INTO units (sequence, unit, ordinal) "
                    "VALUES (?, ?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM units))",
                    (sequence, unit),
                )
            self._db.executemany(
                "INSERT OR IGNORE INTO methods (name, ordinal) "
                "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM methods))",
                [(method,) for method in other.methods()],
            )
            _, overlapping = other._criterion_order()
            self._db.executemany(
                "INSERT OR IGNORE INTO criteria (name, ordinal, overlapping) "
                "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM criteria), ?)",
                [(name, name in overlapping) for name in other.criteria()],
            )
            if layout is not None:
                columns = "sequence, stamp, method, criterion, n" + "".join(
                    f", {_quote(name)}" for name in layout.measures
                )
                try:
                    self._db.executemany(
                        layout.insert_frames(),
                        other._db.execute(f"SELECT {columns}, sums, relative FROM frames"),
                    )
                except sqlite3.IntegrityError:
                    raise ConfigurationError(
                        f"{other.path} holds frames (sequence, stamp, method) that {self.path} "
                        "holds already"
                    ) from None
            self._db.executemany(
                "INSERT INTO problems (sequence, unit, position, stamp, method, message) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                other._db.execute(
                    "SELECT sequence, unit, position, stamp, method, message FROM problems"
                ),
            )
            self._db.executemany(
                _ADD_COUNTS,
                other._db.execute(
                    "SELECT sequence, method, sequence, matched, unmatched, dropped, failed "
                    "FROM match_counts ORDER BY sequence, ordinal"
                ),
            )
        self._layout = self._read_layout()
        return len(units)

    def set_sequence(self, sequence: str, source: str, info: Mapping[str, object]) -> None:
        """Record (or replace) a sequence's metadata: bag path, camera, topics, start/end."""
        self._require_writable()
        text = _json(info, f"the metadata of sequence {sequence}")
        with self._transaction():
            self._register_sequence(sequence)
            self._db.execute(
                "UPDATE sequences SET source = ?, info = ? WHERE name = ?", (source, text, sequence)
            )

    def set_provenance(self, record: Mapping[str, object]) -> None:
        """Record (or replace) how the results were made: version, configuration, input hashes.

        Kept in its own table (created on first use), one JSON value per key, so databases
        written before it existed stay readable.
        """
        self._require_writable()
        rows = _config_rows(record)
        with self._transaction():
            self._db.execute(_PROVENANCE_TABLE)
            self._db.executemany(
                "INSERT INTO provenance (key, value) VALUES (?, ?) "
                "ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                rows,
            )

    def provenance(self) -> dict[str, object]:
        """The record of :meth:`set_provenance` (empty for results written without one)."""
        exists = self._db.execute(
            "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'provenance'"
        ).fetchone()
        if not exists:
            return {}
        rows = self._db.execute("SELECT key, value FROM provenance ORDER BY rowid")
        return {key: json.loads(value) for key, value in rows}

    # -- reading -----------------------------------------------------------------------------

    def sequences(self) -> list[str]:
        """Sequence names in first-seen order."""
        return self._names("sequences")

    def methods(self) -> list[str]:
        """Names of the methods with stored frames, in first-seen order."""
        return self._names("methods")

    def criteria(self) -> list[str]:
        """Criterion names in first-seen order."""
        return self._names("criteria")

    def measures(self) -> list[str]:
        """The measure columns of the frames (empty until the first frame is stored)."""
        layout = self._current_layout()
        return list(layout.measures) if layout else []

    def config(self) -> dict[str, object]:
        """The run's configuration as given to :meth:`create` (after a JSON round trip)."""
        rows = self._db.execute("SELECT key, value FROM run ORDER BY ordinal")
        return {key: json.loads(value) for key, value in rows}

    def sequence_info(self, sequence: str) -> tuple[str, dict[str, object]]:
        """A sequence's source and metadata as given to :meth:`set_sequence` (else '' and {})."""
        row = self._db.execute(
            "SELECT source, info FROM sequences WHERE name = ?", (sequence,)
        ).fetchone()
        if row is None:
            raise KeyError(sequence)
        source, info = row
        return source or "", json.loads(info) if info else {}

    def frame_rows(
        self, sequence: str | None = None, method: str | None = None
    ) -> Iterator[dict[str, object]]:
        """Stored rows (sequence, stamp, method, criterion, n, measures…; NULL read as NaN).

        Ordered by sequence, stamp, method and criterion (first-seen orders).
        """
        layout = self._current_layout()
        if layout is None:
            return
        where, parameters = _where(sequence=sequence, method=method)
        cursor = self._db.execute(
            "SELECT f.sequence, f.stamp, f.method, f.criterion, f.n"
            + layout.measure_columns()
            + _ORDERED_FRAMES
            + where
            + _FRAME_ORDER,
            parameters,
        )
        keys = ("sequence", "stamp", "method", "criterion")
        for row in cursor:
            record: dict[str, object] = dict(zip(keys, row[:4], strict=True))
            for name, value in zip(("n", *layout.measures), row[4:], strict=True):
                record[name] = math.nan if value is None else value
            yield record

    def sequence_scores(
        self, sequence: str | None = None, stamps: Collection[int] | None = None
    ) -> dict[str, Scores]:
        """Per method, the scores summed over a sequence (all if None), optionally some stamps.

        Sums of the stored float64 sums in frame order, bit-identical to :meth:`Scores.combine`
        of the frames (a criterion absent from a frame adds nothing; metric and relative SZE
        do not mix); measures are recomputed from them, so means are never averaged.
        Quantiles are not summable and come out NaN.
        """
        layout = self._current_layout()
        if layout is None:
            return {}
        where, parameters = _where(sequence=sequence)
        cursor = self._db.execute(
            "SELECT f.method, f.criterion, f.stamp, f.relative, f.sums"
            + _ORDERED_FRAMES
            + where
            + _FRAME_ORDER,
            parameters,
        )
        wanted = None if stamps is None else {int(stamp) for stamp in stamps}
        groups: dict[tuple[str, str], int] = {}
        relative: dict[str, bool] = {}
        blobs: list[bytes] = []
        targets: list[int] = []
        for method, criterion, stamp, is_relative, blob in cursor:
            if wanted is not None and stamp not in wanted:
                continue
            targets.append(groups.setdefault((method, criterion), len(groups)))
            blobs.append(blob)
            if relative.setdefault(method, bool(is_relative)) != bool(is_relative):
                raise ConfigurationError(
                    f"{self.path}: cannot sum the scores of {method} over "
                    f"{sequence or 'all sequences'}: metric SZE (with a camera) and relative "
                    "SZE (without) are mixed"
                )
        if not blobs:
            return {}
        rows = self._sums(b"".join(blobs), layout)
        totals = np.zeros((len(groups), len(layout.fields)), dtype=np.float64)
        np.add.at(totals, np.array(targets, dtype=np.intp), rows)  # sequential, in frame order
        order, overlapping = self._criterion_order()
        result: dict[str, Scores] = {}
        for method, any_relative in relative.items():
            criteria = sorted((c for m, c in groups if m == method), key=order.__getitem__)
            result[method] = Scores(
                criteria=tuple(criteria),
                measures=layout.measures,
                sums=totals[[groups[method, c] for c in criteria]],
                thresholds=layout.thresholds.copy(),
                relative=any_relative,
                overlapping=tuple(c for c in criteria if c in overlapping),
                policy=layout.policy,
            )
        return result

    def frame_scores(self, sequence: str, stamp: int) -> dict[str, Scores]:
        """Per method, the scores of one frame as they were stored (quantiles included)."""
        layout = self._current_layout()
        if layout is None:
            return {}
        cursor = self._db.execute(
            "SELECT f.method, f.criterion, f.relative, f.sums"
            + layout.measure_columns()
            + _ORDERED_FRAMES
            + " WHERE f.sequence = ? AND f.stamp = ?"
            + _FRAME_ORDER,
            (sequence, int(stamp)),
        )
        quantiles = [(i, name) for i, name in enumerate(layout.measures) if quantile_level(name)]
        _, overlapping = self._criterion_order()
        criteria: dict[str, list[str]] = {}
        blobs: dict[str, list[bytes]] = {}
        quantile_values: dict[str, dict[str, dict[str, float]]] = {}
        relative: dict[str, bool] = {}
        for method, criterion, is_relative, blob, *values in cursor:
            criteria.setdefault(method, []).append(criterion)
            blobs.setdefault(method, []).append(blob)
            relative[method] = bool(is_relative)
            quantile_values.setdefault(method, {})
            if quantiles:
                quantile_values[method][criterion] = {
                    name: math.nan if values[i] is None else float(values[i])
                    for i, name in quantiles
                }
        return {
            method: Scores(
                criteria=tuple(names),
                measures=layout.measures,
                sums=self._sums(b"".join(blobs[method]), layout),
                thresholds=layout.thresholds.copy(),
                quantiles=quantile_values[method],
                relative=relative[method],
                overlapping=tuple(c for c in names if c in overlapping),
                policy=layout.policy,
            )
            for method, names in criteria.items()
        }

    def stamps(self, sequence: str) -> list[int]:
        """The stamps of a sequence with any stored frame, ascending."""
        if self._current_layout() is None:
            return []
        rows = self._db.execute(
            "SELECT DISTINCT stamp FROM frames WHERE sequence = ? ORDER BY stamp", (sequence,)
        )
        return [stamp for (stamp,) in rows]

    def common_stamps(self, sequence: str) -> list[int]:
        """The stamps where every method stored for the sequence has scores (fair comparison)."""
        if self._current_layout() is None:
            return []
        rows = self._db.execute(
            "SELECT stamp FROM frames WHERE sequence = ? GROUP BY stamp "
            "HAVING COUNT(DISTINCT method) = "
            "(SELECT COUNT(DISTINCT method) FROM frames WHERE sequence = ?) ORDER BY stamp",
            (sequence, sequence),
        )
        return [stamp for (stamp,) in rows]

    def match_counts(self, sequence: str) -> dict[str, MatchCounts]:
        """Per method, the match counts added up over the sequence's units."""
        rows = self._db.execute(
            "SELECT method, matched, unmatched, dropped, failed FROM match_counts "
            "WHERE sequence = ? ORDER BY ordinal",
            (sequence,),
        )
        return {method: MatchCounts(*counts) for method, *counts in rows}

    def problems(self, sequence: str | None = None) -> list[Problem]:
        """Recorded problems of one sequence (or all), in the order they were written."""
        where, parameters = _where(sequence=sequence, table="p")
        rows = self._db.execute(
            "SELECT p.sequence, p.stamp, p.method, p.message FROM problems p "
            "JOIN sequences s ON s.name = p.sequence "
            "JOIN units u ON u.sequence = p.sequence AND u.unit = p.unit"
            + where
            + " ORDER BY s.ordinal, u.ordinal, p.position",
            parameters,
        )
        return [Problem(*row) for row in rows]

    def export_csv(self, path: Path) -> int:
        """Write every frame row to CSV (NaN as an empty cell, floats exact); rows written."""
        path = Path(path)
        layout = self._current_layout()
        measures = layout.measures if layout else ()
        partial = path.with_name(path.name + ".partial")
        written = 0
        try:
            with open(partial, "w", newline="", encoding="utf-8") as handle:
                writer = csv.writer(handle)
                writer.writerow(["sequence", "stamp", "method", "criterion", "n", *measures])
                for row in self.frame_rows():
                    writer.writerow(
                        [row["sequence"], row["stamp"], row["method"], row["criterion"]]
                        + [_cell(row[name]) for name in ("n", *measures)]
                    )
                    written += 1
            os.replace(partial, path)
        except OSError as error:
            partial.unlink(missing_ok=True)
            raise InputError(
                f"{path}: cannot write the CSV file ({error.strerror or error})"
            ) from None
        return written

    # -- internals ---------------------------------------------------------------------------

    @contextmanager
    def _transaction(self) -> Iterator[None]:
        """One write transaction: committed if the block ends, rolled back if it raises.

        A failing write (disk full, I/O error) is one line; what earlier transactions stored
        stays intact, so the run can be resumed once the cause is gone.
        """
        try:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield
            except BaseException:
                if self._db.in_transaction:
                    self._db.execute("ROLLBACK")
                raise
            self._db.execute("COMMIT")
        except sqlite3.OperationalError as error:
            if self._db.in_transaction:
                self._db.execute("ROLLBACK")
            raise InputError(
                f"{self.path}: cannot write the results ({error}); what was stored before is "
                "intact: resume the run once the cause is gone"
            ) from None

    def _require_writable(self) -> None:
        if not self._writable:
            raise ValueError(f"{self.path} was opened read-only")

    def _register_sequence(self, sequence: str) -> None:
        self._db.execute(
            "INSERT OR IGNORE INTO sequences (name, ordinal) "
            "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM sequences))",
            (sequence,),
        )

    def overlapping_criteria(self) -> set[str]:
        """Criteria stored as overlapping (the legacy Middlebury ones), recorded on first write."""
        return self._criterion_order()[1]

    def _names(self, table: str) -> list[str]:
        return [name for (name,) in self._db.execute(f"SELECT name FROM {table} ORDER BY ordinal")]

    def _criterion_order(self) -> tuple[dict[str, int], set[str]]:
        rows = self._db.execute("SELECT name, ordinal, overlapping FROM criteria").fetchall()
        return {name: ordinal for name, ordinal, _ in rows}, {name for name, _, o in rows if o}

    def _read_layout(self) -> _Layout | None:
        row = self._db.execute(
            "SELECT measures, fields, thresholds, policy FROM layout WHERE id = 1"
        ).fetchone()
        if row is None:
            return None
        measures, fields, thresholds, policy = row
        return _Layout(
            measures=tuple(json.loads(measures)),
            fields=tuple(json.loads(fields)),
            thresholds=np.frombuffer(thresholds, dtype=_BLOB).astype(np.float64),
            policy=policy,
        )

    def _current_layout(self) -> _Layout | None:
        """The layout, read again while none is known (a writer may have stored it since)."""
        if self._layout is None:
            self._layout = self._read_layout()
        return self._layout

    def _use_layout(self, layout: _Layout) -> None:
        """Fix the layout with the first frames (creating the frames table), else check it."""
        stored = self._read_layout()
        if stored is None:
            self._db.execute(
                "INSERT INTO layout (id, measures, fields, thresholds, policy) "
                "VALUES (1, ?, ?, ?, ?)",
                (
                    json.dumps(list(layout.measures)),
                    json.dumps(list(layout.fields)),
                    layout.thresholds.astype(_BLOB).tobytes(),
                    layout.policy,
                ),
            )
            self._db.execute(layout.frames_table())
            return
        difference = layout.difference(stored)
        if difference is not None:
            raise ResultsConflictError(
                f"{self.path}: these scores do not fit the stored results ({difference} stored)",
                resumable=False,
            )

    def _sums(self, blob: bytes, layout: _Layout) -> np.ndarray:
        width = len(layout.fields)
        if len(blob) % (width * _BLOB.itemsize):
            raise InputError(
                f"{self.path}: a stored accumulator row is not {width} float64 values; "
                "the database is damaged"
            )
        return np.frombuffer(blob, dtype=_BLOB).astype(np.float64).reshape(-1, width)


# -- helpers -----------------------------------------------------------------------------------


_PROVENANCE_TABLE = (
    "CREATE TABLE IF NOT EXISTS provenance (key TEXT PRIMARY KEY, value TEXT NOT NULL)"
)


def _quote(name: str) -> str:
    """An SQL identifier for a measure name such as ``bad_0.5``."""
    return '"' + name.replace('"', '""') + '"'


def _floats(values: np.ndarray) -> str:
    return ", ".join(repr(float(v)) for v in values)


def _cell(value: object) -> str:
    """A CSV cell: empty for NaN, ``repr`` for numbers so they read back exactly."""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)


def _where(
    sequence: str | None = None, method: str | None = None, table: str = "f"
) -> tuple[str, tuple[str, ...]]:
    clauses, parameters = [], []
    for column, value in (("sequence", sequence), ("method", method)):
        if value is not None:
            clauses.append(f"{table}.{column} = ?")
            parameters.append(value)
    return (" WHERE " + " AND ".join(clauses) if clauses else ""), tuple(parameters)


def _jsonable(value: object) -> object:
    """What JSON cannot hold as such: arrays and numpy numbers, paths, sets."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value, key=repr)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def _json(value: object, what: str) -> str:
    """Canonical JSON (sorted keys, no spaces), so equal configurations compare equal as text."""
    try:
        return json.dumps(value, sort_keys=True, separators=(",", ":"), default=_jsonable)
    except (TypeError, ValueError) as error:
        raise ConfigurationError(f"{what} cannot be stored: {error}") from None


def _config_rows(config: Mapping[str, object]) -> list[tuple[str, str]]:
    return [
        (str(key), _json(value, f"configuration value '{key}'")) for key, value in config.items()
    ]


class _FolderLock:
    """An exclusive lock on a results folder for one writing run (``flock`` on the folder).

    Two runs started at once on one folder would both create the tables (``table run already
    exists``) or meet ``database is locked``; the second is refused with one line instead. The
    lock goes with the process: a killed run leaves nothing to clean up.
    """

    def __init__(self, fd: int | None) -> None:
        self._fd = fd

    @classmethod
    def take(cls, directory: Path) -> _FolderLock:
        try:
            import fcntl
        except ImportError:  # no flock (Windows): SQLite's own locking is all there is
            return cls(None)
        fd = os.open(directory, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise ConfigurationError(
                f"{directory} is in use by another dispeval run; wait for it to end or write "
                "elsewhere"
            ) from None
        return cls(fd)

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing the descriptor releases the lock
            self._fd = None


def _check_tables(connection: sqlite3.Connection, path: Path) -> None:
    """Every table of the schema is there (a damaged or hand-edited database is one line)."""
    present = {
        name for (name,) in connection.execute("SELECT name FROM sqlite_master WHERE type='table'")
    }
    wanted = {statement.split()[2] for statement in _SCHEMA}
    if "layout" in present and connection.execute("SELECT COUNT(*) FROM layout").fetchone()[0]:
        wanted.add("frames")  # made with the first frame
    missing = sorted(wanted - present)
    if missing:
        raise InputError(
            f"{path}: the results database is incomplete (no table {', '.join(missing)}); "
            "it was damaged or not written by dispeval"
        )


def _connect(path: Path, writable: bool) -> sqlite3.Connection:
    try:
        if writable:
            return sqlite3.connect(path, isolation_level=None, check_same_thread=False)
        return sqlite3.connect(
            path.resolve().as_uri() + "?mode=ro",
            uri=True,
            isolation_level=None,
            check_same_thread=False,
        )
    except sqlite3.Error as error:
        raise InputError(f"{path}: cannot open the results database ({error})") from None


def _state(connection: sqlite3.Connection, path: Path) -> str:
    """'results' (ours, this schema), 'empty' (a new file), else a one-line InputError."""
    try:
        application = connection.execute("PRAGMA application_id").fetchone()[0]
        version = connection.execute("PRAGMA user_version").fetchone()[0]
        tables = connection.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()[0]
    except sqlite3.DatabaseError as error:
        raise InputError(
            f"{path} is not a results database ({error}); expected an SQLite file "
            "written by 'dispeval bag' or the summarizer"
        ) from None
    if application == APPLICATION_ID:
        if version != SCHEMA_VERSION:
            raise InputError(
                f"{path} has results schema version {version}; this dispeval reads "
                f"version {SCHEMA_VERSION}"
            )
        return "results"
    if application == 0 and tables == 0:
        return "empty"
    raise InputError(
        f"{path} is an SQLite database but not dispeval results; expected {RESULTS_FILE} "
        "written by 'dispeval bag' or the summarizer"
    )


def _holds_nothing(connection: sqlite3.Connection) -> bool:
    """A results database no unit was ever written to (a run refused or killed at start)."""
    try:
        return connection.execute("SELECT COUNT(*) FROM units").fetchone()[0] == 0
    except sqlite3.DatabaseError:  # no units table: not ours to judge, _state said results
        return False


def _clear(connection: sqlite3.Connection) -> None:
    """Drop every table (and the provenance record), as before the first run."""
    tables = [
        name for (name,) in connection.execute("SELECT name FROM sqlite_master WHERE type='table'")
    ]
    connection.execute("BEGIN IMMEDIATE")
    try:
        for table in tables:
            connection.execute(f'DROP TABLE "{table}"')
        connection.execute("PRAGMA application_id = 0")
        connection.execute("PRAGMA user_version = 0")
    except BaseException:
        connection.execute("ROLLBACK")
        raise
    connection.execute("COMMIT")


def _initialise(connection: sqlite3.Connection, config: list[tuple[str, str]]) -> None:
    """Schema, configuration and header marks in one transaction (a kill leaves it empty)."""
    connection.execute("BEGIN IMMEDIATE")
    try:
        for statement in _SCHEMA:
            connection.execute(statement)
        connection.executemany(
            "INSERT INTO run (key, ordinal, value) VALUES (?, ?, ?)",
            [(key, ordinal, value) for ordinal, (key, value) in enumerate(config)],
        )
        connection.execute(f"PRAGMA application_id = {APPLICATION_ID}")
        connection.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
    except BaseException:
        connection.execute("ROLLBACK")
        raise
    connection.execute("COMMIT")


def _shorten(text: str, limit: int = 100) -> str:
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _check_config(
    connection: sqlite3.Connection, directory: Path, config: list[tuple[str, str]]
) -> None:
    """Resume only the same run: name the first key whose value differs."""
    stored = dict(connection.execute("SELECT key, value FROM run ORDER BY ordinal").fetchall())
    wanted = dict(config)
    for key in [*stored, *(key for key in wanted if key not in stored)]:
        old, new = stored.get(key), wanted.get(key)
        if old != new:
            raise ResultsConflictError(
                f"{directory} holds results of another configuration: '{key}' is "
                f"{_shorten(old or '(absent)')} there but {_shorten(new or '(absent)')} now",
                resumable=False,
            )


def _unit_layout(unit: str, frames: Sequence[FrameScores]) -> _Layout | None:
    """The layout the unit's frames share (None without frames); a mix is an error."""
    if not frames:
        return None
    layout = _Layout.of(frames[0].scores)
    for frame in frames[1:]:
        scores = frame.scores
        if (
            tuple(scores.measures) != layout.measures
            or scores.policy != layout.policy
            or not np.array_equal(scores.thresholds, layout.thresholds)
        ):
            difference = _Layout.of(scores).difference(layout)
            raise ConfigurationError(f"unit '{unit}' mixes scores of different {difference}")
    return layout


def _frame_rows(
    sequence: str, unit: str, frames: Sequence[FrameScores], layout: _Layout | None
) -> tuple[list[tuple[object, ...]], list[str], dict[str, bool]]:
    """The frames table rows of a unit, its methods and its criteria (first-seen order)."""
    rows: list[tuple[object, ...]] = []
    methods: dict[str, None] = {}
    criteria: dict[str, bool] = {}
    seen: set[tuple[int, str]] = set()
    if layout is None:
        return rows, [], criteria
    width, names, isnan = len(layout.fields), layout.measures, math.isnan
    for frame in frames:
        stamp, method, scores = int(frame.stamp), str(frame.method), frame.scores
        if frame.sequence != sequence:
            raise ValueError(f"unit '{unit}' of {sequence} holds a frame of {frame.sequence}")
        if (stamp, method) in seen:
            raise ValueError(f"unit '{unit}' of {sequence} holds {method} at {stamp} twice")
        seen.add((stamp, method))
        sums = np.ascontiguousarray(scores.sums, dtype=_BLOB)
        if sums.shape != (len(scores.criteria), width):
            raise ValueError(
                f"{method} at {stamp}: sums of shape {sums.shape}, expected "
                f"({len(scores.criteria)}, {width})"
            )
        relative = int(bool(scores.relative))
        methods.setdefault(method, None)
        for index, criterion in enumerate(scores.criteria):
            criteria.setdefault(criterion, criterion in scores.overlapping)
            values = scores[criterion]
            # NaN is stored as NULL (SQLite has no NaN) and read back as NaN
            measures = [None if isnan(v) else v for v in map(values.__getitem__, names)]
            rows.append(
                (sequence, stamp, method, criterion, _sql_float(values["n"]), *measures,
                 sums[index].tobytes(), relative)
            )  # fmt: skip
    return rows, list(methods), criteria


def _sql_float(value: float) -> float | None:
    """NaN is stored as NULL (SQLite has no NaN) and read back as NaN."""
    value = float(value)
    return None if math.isnan(value) else value
